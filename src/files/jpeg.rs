//! JPEG files checked before they are decoded: complete by their segments,
//! of a kind the decoder reads, and with scans that hold every block of
//! their frame. The decoder (zune-jpeg through the `image` crate, strict
//! mode off) fills what a damaged stream lacks with gray or with blocks
//! decoded from zero bits and reports success; a restoration of such a
//! photo is a silent wrong result, so these files are refused, named.

use crate::error::{Failure, Kind};
use crate::files::decode::Limits;
use std::io::{BufRead, Seek};

/// A JPEG frame's components as its scans name them, with their sampling
/// factors: (id, H, V).
type Components = Vec<(u8, u8, u8)>;

/// A JPEG frame's height, width and components.
type Frame = (u32, u32, Components);

/// The largest sampling factors (H, V) of a frame's components (at least 1).
fn max_sampling(comps: &[(u8, u8, u8)]) -> (u64, u64) {
    comps.iter().fold((1, 1), |(a, b), &(_, x, y)| (a.max(u64::from(x)), b.max(u64::from(y))))
}

/// The 8 x 8 blocks across and down of a component sampled (H, V) in a
/// frame of `w` x `h` pixels whose largest factors are `max` (A.2.2).
fn component_blocks((hs, vs): (u8, u8), (w, h): (u32, u32), (hmax, vmax): (u64, u64)) -> (u64, u64) {
    let across = (u64::from(w) * u64::from(hs.max(1))).div_ceil(hmax).div_ceil(8);
    let down = (u64::from(h) * u64::from(vs.max(1))).div_ceil(vmax).div_ceil(8);
    (across, down)
}

/// The components of a scan (its SOS segment `header`): (id, table ids).
fn scan_components(header: &[u8]) -> impl Iterator<Item = (u8, u8)> + '_ {
    let n = usize::from(header.first().copied().unwrap_or(0));
    header.get(1..).unwrap_or_default().chunks_exact(2).take(n).filter_map(|c| match c {
        &[id, tables] => Some((id, tables)),
        _ => None,
    })
}

/// What [`jpeg_walk`] finds in a complete JPEG: the frame (SOF: height,
/// width, and each component's id and sampling factors) and the bytes of
/// entropy-coded data over all its scans.
#[derive(Debug, Default)]
struct JpegWalk {
    frame: Option<Frame>,
    /// whether the frame is arithmetic-coded (SOF9 and up: codes may be under one bit)
    arithmetic: bool,
    /// the frame's marker when it is a lossless one (SOF3, 7, B, F) or JPEG-LS (SOF55, F7)
    lossless: Option<u8>,
    scan_bytes: u64,
    /// of a Huffman-coded sequential frame (SOF0, SOF1), the blocks its scans
    /// hold and the blocks they should, when a scan ends short by at least
    /// one row of MCUs ([`scan_blocks`]) or a component has no scan
    short: Option<(u64, u64)>,
}

/// The scans of a sequential Huffman frame as [`jpeg_walk`] counts them.
#[derive(Default)]
struct Counted {
    /// blocks held and blocks needed, over the scans judged
    blocks: (u64, u64),
    /// a scan ended at least a row of MCUs short
    short: bool,
    /// a scan could not be judged (its tables, its codes)
    unjudged: bool,
    /// the components the scans code
    coded: Vec<u8>,
}

/// The segments of a complete JPEG stream; None when it is not complete.
/// Complete: walking its segments from SOI (each marker's length, and past
/// each scan's entropy-coded data, where 0xFF is followed only by 0x00, a
/// restart marker or fill bytes) reaches the end-of-image marker (FF D9)
/// before the data ends. What follows that marker is not looked at: phones
/// append a video or a depth map after it (Motion Photos, MPF), whose bytes
/// hold FF DA and FF D9 at random. The JPEG decoder fills a truncated scan
/// with gray and reports success; a cut-off frame must be an error instead
/// (Pillow refuses it too).
fn jpeg_walk(bytes: &[u8]) -> Option<JpegWalk> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut walk = JpegWalk::default();
    // what the scans of a sequential Huffman frame are counted with
    let mut tables: [[Option<Huffman>; 4]; 2] = Default::default();
    let mut restart = 0u64;
    // a Huffman-coded sequential frame (SOF0, SOF1), whose scans are counted
    let mut sequential = false;
    let mut counted = Counted::default();
    let mut i = 2usize;
    loop {
        // a marker: 0xFF, any fill bytes (0xFF), then its code; stray bytes
        // before it (some cameras pad segments) are passed over, as libjpeg does
        while bytes.get(i).is_some_and(|b| *b != 0xFF) {
            i += 1;
        }
        while bytes.get(i) == Some(&0xFF) {
            i += 1;
        }
        let &code = bytes.get(i)?;
        i += 1;
        match code {
            0xD9 => {
                if let (true, Some(frame)) = (sequential, &walk.frame) {
                    walk.short = counted.verdict(frame);
                }
                return Some(walk);
            }
            0x01 | 0xD0..=0xD7 => continue,
            _ => {}
        }
        let &len = bytes.get(i..).and_then(<[u8]>::first_chunk::<2>)?;
        let len = usize::from(u16::from_be_bytes(len));
        if len < 2 {
            return None;
        }
        if matches!(code, 0xC3 | 0xC7 | 0xCB | 0xCF | 0xF7) {
            walk.lossless.get_or_insert(code);
        }
        let seg = bytes.get(i + 2..i + len)?;
        // SOFn (not DHT C4, JPG C8, DAC CC): precision, height, width, components
        if matches!(code, 0xC0..=0xCF) && !matches!(code, 0xC4 | 0xC8 | 0xCC) && walk.frame.is_none() {
            if let Some(([_, h0, h1, w0, w1, n], rest)) = seg.split_first_chunk::<6>() {
                let comps = rest.chunks_exact(3).take(usize::from(*n)).filter_map(|c| match c {
                    &[id, f, _] => Some((id, f >> 4, f & 15)),
                    _ => None,
                });
                walk.frame = Some((u32::from(u16::from_be_bytes([*h0, *h1])), u32::from(u16::from_be_bytes([*w0, *w1])), comps.collect()));
                walk.arithmetic = code >= 0xC9;
                sequential = matches!(code, 0xC0 | 0xC1);
            }
        }
        match code {
            0xC4 => read_huffman(seg, &mut tables),
            0xDD => restart = seg.first_chunk::<2>().map_or(0, |&r| u64::from(u16::from_be_bytes(r))),
            _ => {}
        }
        i += len;
        if code == 0xDA {
            // the entropy-coded data runs to the next marker that is not a restart
            let begin = i;
            loop {
                match bytes.get(i..i + 2)? {
                    [0xFF, b] if *b == 0x00 || (0xD0..=0xD7).contains(b) => i += 2,
                    [0xFF, 0xFF] => i += 1,
                    [0xFF, _] => break,
                    _ => i += 1,
                }
            }
            walk.scan_bytes += (i - begin) as u64;
            if let (true, Some(frame)) = (sequential, &walk.frame) {
                match bytes.get(begin..i).and_then(|data| scan_blocks(data, seg, frame, &tables, restart)) {
                    Some((held, need, row)) => {
                        counted.blocks = (counted.blocks.0 + held, counted.blocks.1 + need);
                        counted.short |= held + row <= need;
                        counted.coded.extend(scan_components(seg).map(|(id, _)| id));
                    }
                    None => counted.unjudged = true,
                }
            }
        }
    }
}

/// Why a complete JPEG (its [`jpeg_walk`]) is not decoded, if it is not: a lossless or
/// JPEG-LS frame (the decoder has no such mode), or scans too short for
/// the frame's pixels. Every
/// 8 x 8 block of every component takes at least one bit of Huffman-coded
/// data (its DC coefficient's code, one bit or more, in sequential and
/// progressive JPEG alike), so a file whose scans hold fewer bytes than
/// its blocks need is damaged (cut inside a scan with its end marker
/// kept) or made to cost memory: a 632-byte file claiming 6000 x 4000
/// pixels decoded to gray for 2.3 GB. Arithmetic-coded frames are not
/// judged.
fn jpeg_problem(walk: JpegWalk) -> Option<String> {
    if let Some(code) = walk.lossless {
        let what = if code == 0xF7 { "JPEG-LS" } else { "lossless JPEG" };
        return Some(format!("{what} (marker FF {code:02X}) is not read: baseline and progressive JPEG are"));
    }
    let (h, w, comps) = walk.frame?;
    if walk.arithmetic || comps.is_empty() {
        return None;
    }
    let max = max_sampling(&comps);
    let blocks: u64 = comps
        .iter()
        .map(|&(_, x, y)| {
            let (across, down) = component_blocks((x, y), (w, h), max);
            across * down
        })
        .sum();
    let need = blocks.div_ceil(8);
    if walk.scan_bytes < need {
        return Some(format!(
            "a damaged JPEG: its {w}x{h} pixels need at least {need} bytes of scan data, and its scans hold {}",
            walk.scan_bytes
        ));
    }
    walk.short.map(|(held, need)| {
        format!(
            "a damaged JPEG: its scan data ends after {held} of its {need} blocks of 8x8 pixels \
             (cut short with its end marker kept, or overwritten); the decoder would fill the rest with made-up pixels"
        )
    })
}

/// Reads a whole JPEG file (bounded by the memory budget) and checks that it
/// is complete; the JPEG decoder holds the whole file in memory anyway.
pub(crate) fn read_jpeg<R: BufRead + Seek>(mut reader: R, limits: &Limits) -> Result<Vec<u8>, Failure> {
    let io = |e: std::io::Error| Failure::new(Kind::Input, format!("cannot read: {e}"));
    let len = reader.seek(std::io::SeekFrom::End(0)).map_err(io)?;
    if len > limits.max_memory {
        return Err(Failure::new(
            Kind::Budget,
            format!("JPEG file of {len} bytes is over --max-memory {}", limits.max_memory),
        ));
    }
    reader.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(usize::try_from(len).unwrap_or(usize::MAX))
        .map_err(|e| Failure::new(Kind::Budget, format!("cannot hold the file: {e}")))?;
    reader.read_to_end(&mut bytes).map_err(io)?;
    let Some(walk) = jpeg_walk(&bytes) else {
        return Err(Failure::new(
            Kind::Input,
            "cannot decode: truncated JPEG (no end-of-image marker after the last scan)",
        ));
    };
    if let Some(why) = jpeg_problem(walk) {
        return Err(Failure::new(Kind::Input, why));
    }
    Ok(bytes)
}


/// A Huffman table of a DHT segment (JPEG, ITU T.81 Annex C and F.2.2.3):
/// per code length 1-16 the largest code (-1: none), the first code and
/// the index of its first value; and a lookup of codes of up to 8 bits.
struct Huffman {
    maxcode: [i32; 17],
    mincode: [i32; 17],
    first: [usize; 17],
    values: Vec<u8>,
    /// by the next 8 bits: (code length, value); length 0: longer code
    fast: Vec<(u8, u8)>,
}

impl Huffman {
    /// The table of `counts` codes of each length 1-16 and their `values`;
    /// None when the counts do not make a prefix code.
    fn new(counts: &[u8; 16], values: &[u8]) -> Option<Huffman> {
        let (mut maxcode, mut mincode, mut first) = ([-1i32; 17], [0i32; 17], [0usize; 17]);
        let mut fast = vec![(0u8, 0u8); 256];
        let (mut code, mut k) = (0i32, 0usize);
        for (len, &n) in (1..=16usize).zip(counts) {
            let n = i32::from(n);
            *first.get_mut(len)? = k;
            *mincode.get_mut(len)? = code;
            if n > 0 {
                *maxcode.get_mut(len)? = code + n - 1;
            }
            if code + n > 1 << len {
                return None;
            }
            if len <= 8 {
                for c in code..code + n {
                    let value = *values.get(k + (c - code) as usize)?;
                    let from = (c as usize) << (8 - len);
                    fast.get_mut(from..from + (1 << (8 - len)))?.fill((len as u8, value));
                }
            }
            k += n as usize;
            code = (code + n) << 1;
        }
        (k <= values.len()).then(|| Huffman { maxcode, mincode, first, values: values.to_vec(), fast })
    }
}

/// Reads the tables of a DHT segment into `tables` (class 0 DC, 1 AC; ids
/// 0-3). A table that does not make a prefix code is stored as None: the
/// scans that use it are not judged.
fn read_huffman(mut seg: &[u8], tables: &mut [[Option<Huffman>; 4]; 2]) {
    while let Some((&[tc_th], rest)) = seg.split_first_chunk::<1>() {
        let Some((counts, rest)) = rest.split_first_chunk::<16>() else { return };
        let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
        let Some(values) = rest.get(..n) else { return };
        if let Some(slot) = tables.get_mut(usize::from(tc_th >> 4)).and_then(|t| t.get_mut(usize::from(tc_th & 15))) {
            *slot = Huffman::new(counts, values);
        }
        seg = rest.get(n..).unwrap_or_default();
    }
}

/// Why a bit reader stopped: the data ended, or a code no table holds
/// (then the scan is not judged: the decoder's own error handling applies).
enum Stop {
    End,
    Bad,
}

/// The bits of one stretch of entropy-coded data (between restart markers),
/// with 0xFF 0x00 read as 0xFF.
struct Bits<'a> {
    data: &'a [u8],
    acc: u64,
    n: u32,
}

impl Bits<'_> {
    fn fill(&mut self) {
        while self.n <= 56 {
            let byte = match self.data {
                [0xFF, 0x00, rest @ ..] => {
                    self.data = rest;
                    0xFF
                }
                [b, rest @ ..] if *b != 0xFF => {
                    self.data = rest;
                    *b
                }
                _ => return,
            };
            self.acc |= u64::from(byte) << (56 - self.n);
            self.n += 8;
        }
    }

    fn skip(&mut self, k: u32) -> Result<(), Stop> {
        if k == 0 {
            return Ok(());
        }
        self.fill();
        if self.n < k {
            return Err(Stop::End);
        }
        self.acc <<= k;
        self.n -= k;
        Ok(())
    }

    /// The next value of `table`.
    fn decode(&mut self, table: &Huffman) -> Result<u8, Stop> {
        self.fill();
        if self.n >= 8 {
            if let Some(&(len, value)) = table.fast.get((self.acc >> 56) as usize) {
                if len > 0 {
                    self.skip(u32::from(len))?;
                    return Ok(value);
                }
            }
        }
        for len in 1..=16u32 {
            if self.n < len {
                return Err(Stop::End);
            }
            let code = (self.acc >> (64 - len)) as i32;
            let l = len as usize;
            if code <= table.maxcode.get(l).copied().unwrap_or(-1) {
                let at = table.first.get(l).copied().unwrap_or(0) + (code - table.mincode.get(l).copied().unwrap_or(0)) as usize;
                self.skip(len)?;
                return table.values.get(at).copied().ok_or(Stop::Bad);
            }
        }
        Err(Stop::Bad)
    }

    /// Passes over one 8 x 8 block of a sequential scan (F.2.2.1, F.2.2.2).
    fn block(&mut self, dc: &Huffman, ac: &Huffman) -> Result<(), Stop> {
        let size = self.decode(dc)?;
        if size > 16 {
            return Err(Stop::Bad);
        }
        self.skip(u32::from(size))?;
        let mut k = 1u32;
        while k < 64 {
            let rs = self.decode(ac)?;
            let (run, size) = (u32::from(rs >> 4), u32::from(rs & 15));
            if size == 0 {
                if run != 15 {
                    return Ok(());
                }
                k += 16;
            } else {
                k += run + 1;
                self.skip(size)?;
            }
        }
        Ok(())
    }
}

impl Counted {
    /// (blocks held, blocks needed) when the frame's scans are short: one by
    /// a row of MCUs or more, or a component without a scan (a file cut
    /// between the scans of a frame coded one component a scan). None when
    /// whole, or when a scan could not be judged.
    fn verdict(&self, (h, w, comps): &Frame) -> Option<(u64, u64)> {
        if self.unjudged || self.coded.is_empty() {
            return None;
        }
        let max = max_sampling(comps);
        let missing: u64 = comps
            .iter()
            .filter(|(id, _, _)| !self.coded.contains(id))
            .map(|&(_, x, y)| {
                let (across, down) = component_blocks((x, y), (*w, *h), max);
                across * down
            })
            .sum();
        let (held, need) = self.blocks;
        (self.short || missing > 0).then_some((held, need + missing))
    }
}

/// The blocks a scan of a sequential Huffman frame holds, the blocks it
/// should and the blocks of one row of its MCUs; None when it is not judged
/// (a table missing or not a prefix code, a code no table holds, a frame of
/// unknown height, a component not in the frame).
/// `data`: its entropy-coded bytes; `header`: its SOS segment. A scan's stretches between restart markers each hold at
/// most `restart` MCUs (all of them when 0); every MCU of a sequential
/// scan takes at least one bit per block, so this reads each bit at most
/// once and stops where the data does. A cut stream whose end marker was
/// kept decodes without an error: the decoder reads zero bits past the cut.
fn scan_blocks(data: &[u8], header: &[u8], (h, w, comps): &Frame, tables: &[[Option<Huffman>; 4]; 2], restart: u64) -> Option<(u64, u64, u64)> {
    let mut scan = Vec::new();
    for (id, t) in scan_components(header) {
        let &(_, hs, vs) = comps.iter().find(|(cid, _, _)| *cid == id)?;
        let dc = tables.first()?.get(usize::from(t >> 4))?.as_ref()?;
        let ac = tables.get(1)?.get(usize::from(t & 15))?.as_ref()?;
        scan.push((hs, vs, dc, ac));
    }
    if scan.is_empty() || *h == 0 {
        return None;
    }
    let max = max_sampling(comps);
    // MCUs and blocks: one block an MCU for a single component (A.2.2), else
    // each component's H x V blocks in an MCU of 8 Hmax x 8 Vmax pixels (A.2.3)
    let (per_row, rows, units): (u64, u64, Vec<(u64, &Huffman, &Huffman)>) = match scan.as_slice() {
        [(hs, vs, dc, ac)] => {
            let (across, down) = component_blocks((*hs, *vs), (*w, *h), max);
            (across, down, vec![(1, *dc, *ac)])
        }
        many => (
            u64::from(*w).div_ceil(8 * max.0),
            u64::from(*h).div_ceil(8 * max.1),
            many.iter().map(|(hs, vs, dc, ac)| (u64::from(hs.max(&1) * vs.max(&1)), *dc, *ac)).collect(),
        ),
    };
    let blocks_per_mcu: u64 = units.iter().map(|(n, _, _)| n).sum();
    let need = per_row * rows;
    let stretch = if restart == 0 { need } else { restart };
    let mut held = 0u64;
    // the stretches between restart markers
    let mut rest = data;
    while held < need && !rest.is_empty() {
        let end = rest.windows(2).position(|p| matches!(p, [0xFF, 0xD0..=0xD7])).unwrap_or(rest.len());
        let mut bits = Bits { data: rest.get(..end)?, acc: 0, n: 0 };
        let mut got = 0u64;
        'mcus: while got < stretch && held + got < need {
            for &(n, dc, ac) in &units {
                for _ in 0..n {
                    match bits.block(dc, ac) {
                        Ok(()) => {}
                        Err(Stop::End) => break 'mcus,
                        Err(Stop::Bad) => return None,
                    }
                }
            }
            got += 1;
        }
        held += got;
        rest = rest.get(end + 2..).unwrap_or_default();
    }
    Some((held * blocks_per_mcu, need * blocks_per_mcu, per_row * blocks_per_mcu))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::decode::decode;
    use std::io::Cursor;

    const NO_LIMIT: Limits = Limits {
        max_pixels: 1 << 40,
        max_memory: 1 << 40,
    };

    /// A 16x16 baseline JPEG of a fixed pattern.
    fn small_jpeg() -> Vec<u8> {
        use image::ImageEncoder;
        let px: Vec<u8> = (0..16 * 16 * 3).map(|i| (i * 7 % 251) as u8).collect();
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 90)
            .write_image(&px, 16, 16, image::ExtendedColorType::Rgb8)
            .unwrap();
        jpg
    }

    /// A 96 x 160 baseline JPEG of noise (every block coded), 4:2:0, with a
    /// restart marker every `restart` MCUs (0: none) and, when asked,
    /// optimised Huffman tables.
    fn noisy_jpeg(restart: u16, optimized: bool) -> Vec<u8> {
        let mut state = 12345u32;
        let px: Vec<u8> = (0..96 * 160 * 3)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (state >> 24) as u8
            })
            .collect();
        let mut out = Vec::new();
        let mut enc = jpeg_encoder::Encoder::new(&mut out, 90);
        enc.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
        enc.set_restart_interval(restart);
        enc.set_optimized_huffman_tables(optimized);
        enc.encode(&px, 96, 160, jpeg_encoder::ColorType::Rgb).unwrap();
        out
    }

    #[test]
    fn a_scan_cut_short_with_its_end_marker_kept_is_refused() {
        for (restart, optimized) in [(0, false), (0, true), (3, false), (1, true)] {
            let jpg = noisy_jpeg(restart, optimized);
            let walk = jpeg_walk(&jpg).unwrap();
            assert_eq!(walk.short, None, "restart {restart}: a whole file");
            assert!(decode(Cursor::new(jpg.clone()), &NO_LIMIT, true, |_| Ok(())).is_ok());
            let sos = jpg.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
            let scan = jpg.len() - 2 - sos;
            // 4:2:0 at 96 x 160: 6 x 10 MCUs of 16 x 16 pixels, 6 blocks each
            for keep in [0.3, 0.6, 0.85] {
                let mut cut = jpg[..sos + (scan as f64 * keep) as usize].to_vec();
                // a cut that leaves a lone 0xFF would end in a marker of its own
                while cut.last() == Some(&0xFF) {
                    cut.pop();
                }
                cut.extend_from_slice(&[0xFF, 0xD9]);
                let walk = jpeg_walk(&cut).unwrap();
                let (held, need) = walk.short.unwrap_or_else(|| panic!("restart {restart}, kept {keep}: not found"));
                assert_eq!(need, 360, "restart {restart}, optimized {optimized}, kept {keep}");
                // noise codes about evenly: the blocks held follow the bytes kept, to within two rows of MCUs
                let expect = 360.0 * keep;
                assert!((held as f64 - expect).abs() <= 72.0, "restart {restart}, kept {keep}: {held} of {need}");
                let e = decode(Cursor::new(cut), &NO_LIMIT, true, |_| Ok(())).unwrap_err();
                assert_eq!(e.kind, Kind::Input);
                assert!(e.message.contains(&format!("ends after {held} of its 360 blocks")), "{e}");
            }
        }
    }

    #[test]
    fn truncated_jpeg_is_an_input_error() {
        let jpg = small_jpeg();
        assert!(jpeg_walk(&jpg).is_some());
        let d = decode(Cursor::new(jpg.clone()), &NO_LIMIT, true, |_| Ok(())).unwrap();
        assert_eq!((d.format, d.height, d.width), ("JPEG", 16, 16));
        let cut = &jpg[..jpg.len() - 10];
        assert!(jpeg_walk(cut).is_none());
        let e = decode(Cursor::new(cut), &NO_LIMIT, true, |_| Ok(())).unwrap_err();
        assert_eq!(e.kind, Kind::Input);
        assert!(e.message.contains("truncated"), "{e}");
    }

    #[test]
    fn a_lossless_frame_and_scans_too_short_for_the_frame_are_named() {
        let problem = |b: &[u8]| jpeg_walk(b).and_then(jpeg_problem);
        let jpg = small_jpeg();
        assert_eq!(problem(&jpg), None);
        let sof = jpg.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
        // the same stream marked lossless (SOF3): the decoder has no such mode
        let mut lossless = jpg.clone();
        lossless[sof + 1] = 0xC3;
        assert_eq!(problem(&lossless).unwrap(), "lossless JPEG (marker FF C3) is not read: baseline and progressive JPEG are");
        // its frame claimed 6000 x 4000: the encoder writes 4:4:4, so 3 x 750 x 500 blocks, one bit each at least
        let mut big = jpg.clone();
        big[sof + 5..sof + 9].copy_from_slice(&[0x0F, 0xA0, 0x17, 0x70]);
        let why = problem(&big).unwrap();
        assert!(why.starts_with("a damaged JPEG: its 6000x4000 pixels need at least 140625 bytes of scan data"), "{why}");
        let e = decode(Cursor::new(big), &NO_LIMIT, true, |_| Ok(())).unwrap_err();
        assert_eq!((e.kind, e.message), (Kind::Input, why));
    }

    #[test]
    fn a_jpeg_is_complete_by_its_segments_whatever_follows_its_end() {
        let jpg = small_jpeg();
        // a video appended after the end (a Motion Photo) holding a start-of-scan and no end marker
        let mut motion = jpg.clone();
        motion.extend_from_slice(b"\0\0\0\x18ftypmp42\xff\xda\x00\x08junk");
        assert!(jpeg_walk(&motion).is_some());
        let d = decode(Cursor::new(motion), &NO_LIMIT, true, |_| Ok(())).unwrap();
        assert_eq!((d.height, d.width), (16, 16));
        // stray bytes between two segments
        let mut padded = jpg[..2].to_vec();
        padded.extend_from_slice(&[0, 0]);
        padded.extend_from_slice(&jpg[2..]);
        assert!(jpeg_walk(&padded).is_some());
        // cut inside the scan, or right after its header
        let sos = jpg.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
        assert!(jpeg_walk(&jpg[..sos + 20]).is_none());
        assert!(jpeg_walk(&jpg[..sos + 1]).is_none());
        assert!(jpeg_walk(b"\xff\xd8").is_none());
        assert!(jpeg_walk(b"not a jpeg").is_none());
    }

}
