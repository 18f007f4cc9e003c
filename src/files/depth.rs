//! Distance maps read from files (`--distance`, docs/OUTPUTS.md
//! "Distance"): NumPy `.npy` arrays, TIFF floats, OpenEXR channels and
//! COLMAP's dense depth maps in metres (COLMAP's: in its reconstruction's
//! units), 16-bit PNG and 16-bit TIFF in millimetres. Unknown distance (NaN, infinite, zero,
//! negative, or beyond [`MAX_DISTANCE`]) is NaN in the map; the method
//! treats it as a hole (METHOD §13).

use std::fs::File;
use std::io::{BufRead as _, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::error::{Failure, Kind};

pub use crate::method::distance::MAX_DISTANCE;

/// Longest `.npy` header read (NumPy writes 64 to a few hundred bytes).
const MAX_NPY_HEADER: usize = 1 << 16;

/// A distance map as read: metres, NaN where unknown.
#[derive(Debug, Clone)]
pub struct DistanceMap {
    /// row-major metres, NaN = unknown
    pub data: Vec<f32>,
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// how many values were out of range (unknown from then on)
    pub out_of_range: usize,
}

/// The path of an input's distance map from a `--distance` template:
/// `{stem}` is the input's file name without its extension, `{name}` the
/// whole file name; a template without either names one map for every input.
/// One pass over the template: text put in is not read again for
/// placeholders, and a name's bytes are kept as they are (a name that is
/// not UTF-8 finds its map). Why not, when a folder of the path would be
/// `.`, `..` or empty because of the input's name (`...jpg` has the stem
/// `..`): the name would move the map out of the template's folder.
pub fn expand(template: &str, input: &Path) -> Result<PathBuf, String> {
    let name = input.file_name().unwrap_or_default();
    let stem = input.file_stem().unwrap_or_default();
    let mut out: Vec<u8> = Vec::with_capacity(template.len() + 2 * name.len());
    for (k, part) in template.split('/').enumerate() {
        if k > 0 {
            out.push(b'/');
        }
        let start = out.len();
        let mut rest = part;
        let mut filled = false;
        while let Some(at) = rest.find('{') {
            let (head, tail) = rest.split_at(at);
            out.extend_from_slice(head.as_bytes());
            let value = if tail.starts_with("{stem}") {
                Some(stem)
            } else if tail.starts_with("{name}") {
                Some(name)
            } else {
                None
            };
            match value {
                Some(v) => {
                    out.extend_from_slice(os_bytes(v).as_ref());
                    filled = true;
                }
                None => out.push(b'{'),
            }
            // both placeholders are six bytes; a lone brace is one
            rest = tail.get(if value.is_some() { 6 } else { 1 }..).unwrap_or_default();
        }
        out.extend_from_slice(rest.as_bytes());
        let segment = out.get(start..).unwrap_or_default();
        if filled && matches!(segment, b"" | b"." | b"..") {
            return Err(format!(
                "--distance {template}: the input's name makes a folder of the map's path {:?}, which would leave the template's folder",
                String::from_utf8_lossy(segment)
            ));
        }
    }
    Ok(path_from_bytes(out))
}

#[cfg(unix)]
fn os_bytes(s: &std::ffi::OsStr) -> std::borrow::Cow<'_, [u8]> {
    use std::os::unix::ffi::OsStrExt;
    std::borrow::Cow::Borrowed(s.as_bytes())
}

#[cfg(not(unix))]
fn os_bytes(s: &std::ffi::OsStr) -> std::borrow::Cow<'_, [u8]> {
    std::borrow::Cow::Owned(s.to_string_lossy().into_owned().into_bytes())
}

#[cfg(unix)]
fn path_from_bytes(b: Vec<u8>) -> PathBuf {
    use std::os::unix::ffi::OsStringExt;
    PathBuf::from(std::ffi::OsString::from_vec(b))
}

#[cfg(not(unix))]
fn path_from_bytes(b: Vec<u8>) -> PathBuf {
    PathBuf::from(String::from_utf8_lossy(&b).into_owned())
}

/// Most pixels of a photo's map, as a multiple of the photo's pixels (four
/// times its side: depth maps are exported at the photo's size or
/// smaller), and at least [`MAP_MIN_CAP`]: a small compressed file of
/// 17000 x 17000 pixels for a photo of 256 x 256 would take gigabytes.
pub const MAP_PER_PHOTO_PIXEL: u64 = 16;
/// The cap of [`MAP_PER_PHOTO_PIXEL`] is never below this (4 Mpx).
pub const MAP_MIN_CAP: u64 = 1 << 22;

/// The most pixels a distance map of a photo of `h` x `w` pixels may have
/// ([`MAP_PER_PHOTO_PIXEL`] times the photo's, at least [`MAP_MIN_CAP`]).
pub fn map_cap(h: u64, w: u64) -> u64 {
    h.saturating_mul(w).saturating_mul(MAP_PER_PHOTO_PIXEL).max(MAP_MIN_CAP)
}

/// Reads a distance map (regular files only; the size is checked from the
/// header against `max_pixels` and `max_memory` before anything large is
/// allocated).
pub fn read_distance(path: &Path, max_pixels: u64, max_memory: u64) -> Result<DistanceMap, Failure> {
    read_distance_of(path, max_pixels, max_memory, None)
}

/// [`read_distance`] of the map of a photo of `photo` = (height, width)
/// pixels, when known: a map of more than [`map_cap`] pixels is refused
/// from its header, and `max_memory` is what the budget leaves the map
/// beside that photo.
pub fn read_distance_of(path: &Path, max_pixels: u64, max_memory: u64, photo: Option<(u64, u64)>) -> Result<DistanceMap, Failure> {
    crate::files::jobs::regular_file(path).map_err(|m| Failure::new(Kind::Input, m))?;
    let f = File::open(path).map_err(|e| Failure::new(Kind::Input, format!("cannot open: {e}")))?;
    read_distance_from(BufReader::new(f), max_pixels, max_memory, photo)
}

/// [`read_distance_of`] from a reader: the format is told by the first
/// bytes, whatever the file's name.
fn read_distance_from<R: std::io::BufRead + Seek>(mut r: R, max_pixels: u64, max_memory: u64, photo: Option<(u64, u64)>) -> Result<DistanceMap, Failure> {
    let mut magic = [0u8; 8];
    let got = read_up_to(&mut r, &mut magic)?;
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    let check = |h: u64, w: u64, bytes_per: u64| -> Result<(), Failure> {
        let n = h.saturating_mul(w);
        if h == 0 || w == 0 {
            return Err(Failure::new(Kind::Input, "the distance map has no pixels"));
        }
        if n > max_pixels {
            return Err(Failure::new(Kind::Budget, format!("the distance map is {w}x{h} pixels, over --max-pixels {max_pixels}")));
        }
        if let Some((ph, pw)) = photo {
            if n > map_cap(ph, pw) {
                return Err(Failure::new(
                    Kind::Input,
                    format!("the distance map is {w}x{h} pixels, more than {MAP_PER_PHOTO_PIXEL} times the photo's {pw}x{ph}: not read"),
                ));
            }
        }
        // the decoded samples and the metres, beside what the process holds anyway
        let need = n.saturating_mul(bytes_per.saturating_add(4)).saturating_add(crate::kernels::memory::process_base());
        if need > max_memory {
            let over = if photo.is_some() {
                format!("more than the {max_memory} bytes --max-memory leaves it beside the photo")
            } else {
                format!("over --max-memory {max_memory}")
            };
            return Err(Failure::new(Kind::Budget, format!("the distance map of {w}x{h} pixels needs about {need} bytes, {over}")));
        }
        Ok(())
    };
    let head = magic.get(..got).unwrap_or_default();
    let (values, h, w) = match head {
        [0x93, b'N', b'U', b'M', b'P', b'Y', ..] => read_npy(&mut r, check)?,
        [0x89, b'P', b'N', b'G', ..] => read_png(r, check)?,
        // classic TIFF (42) and BigTIFF (43), either byte order
        [b'I', b'I', 42 | 43, 0, ..] | [b'M', b'M', 0, 42 | 43, ..] => read_tiff(r, check, max_memory)?,
        [0x76, 0x2f, 0x31, 0x01, ..] => read_exr(r, check)?,
        [b'0'..=b'9', ..] if head.contains(&b'&') => read_colmap(r, check)?,
        _ => {
            return Err(Failure::new(
                Kind::Input,
                "not a distance map: expected a .npy array (metres), a 16-bit PNG (millimetres), a TIFF (float metres or 16-bit millimetres), an OpenEXR file (metres) or a COLMAP depth map",
            ))
        }
    };
    let mut out_of_range = 0;
    let data = values
        .into_iter()
        .map(|v| {
            if v.is_finite() && v > MAX_DISTANCE {
                out_of_range += 1;
            }
            if crate::method::distance::known(v) {
                v
            } else {
                f32::NAN
            }
        })
        .collect();
    Ok(DistanceMap { data, height: h, width: w, out_of_range })
}

/// A 16-bit distance in millimetres, in metres; 65535, the no-data value
/// of 16-bit depth exports (the largest code), is unknown (NaN), not
/// 65.5 m.
fn millimetres(v: u16) -> f32 {
    if v == u16::MAX {
        f32::NAN
    } else {
        f32::from(v) / 1000.0
    }
}

/// A float64 distance as float32: a finite value beyond float32's range
/// stays finite (the largest float32), so that it is counted out of range
/// like any other absurd distance instead of becoming inf (unknown).
fn narrow(x: f64) -> f32 {
    if x.is_finite() {
        x.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32
    } else {
        x as f32
    }
}

fn io(e: std::io::Error) -> Failure {
    Failure::new(Kind::Input, format!("cannot read the distance map: {e}"))
}

fn read_up_to<R: Read>(r: &mut R, buf: &mut [u8]) -> Result<usize, Failure> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(buf.get_mut(n..).unwrap_or(&mut [])) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) => return Err(io(e)),
        }
    }
    Ok(n)
}

/// A `.npy` file (format versions 1-3): a 2-D array, or (H, W, 1), of
/// little- or big-endian float32/float64 (metres) or uint16 (millimetres).
fn read_npy<R: Read>(r: &mut R, check: impl Fn(u64, u64, u64) -> Result<(), Failure>) -> Result<(Vec<f32>, usize, usize), Failure> {
    let bad = |m: &str| Failure::new(Kind::Input, format!("a .npy file {m}"));
    let mut pre = [0u8; 8];
    if read_up_to(r, &mut pre)? < 8 {
        return Err(bad("ends inside its header"));
    }
    let len = match pre[6] {
        1 => {
            let mut b = [0u8; 2];
            if read_up_to(r, &mut b)? < 2 {
                return Err(bad("ends inside its header"));
            }
            usize::from(u16::from_le_bytes(b))
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            if read_up_to(r, &mut b)? < 4 {
                return Err(bad("ends inside its header"));
            }
            u32::from_le_bytes(b) as usize
        }
        v => return Err(bad(&format!("of format version {v}: not read (versions 1 to 3 are)"))),
    };
    if len > MAX_NPY_HEADER {
        return Err(bad(&format!("with a header of {len} bytes: over the {MAX_NPY_HEADER} read")));
    }
    let mut head = vec![0u8; len];
    if read_up_to(r, &mut head)? < len {
        return Err(bad("ends inside its header"));
    }
    let text = String::from_utf8_lossy(&head);
    let field = |key: &str| -> Option<String> {
        let at = text.find(&format!("'{key}'"))?;
        let rest = text.get(at + key.len() + 2..)?;
        let rest = rest.trim_start().strip_prefix(':')?.trim_start();
        if let Some(inner) = rest.strip_prefix('(') {
            return inner.find(')').and_then(|e| inner.get(..e)).map(str::to_string);
        }
        if let Some(inner) = rest.strip_prefix('\'') {
            return inner.find('\'').and_then(|e| inner.get(..e)).map(str::to_string);
        }
        let end = rest.find([',', '}']).unwrap_or(rest.len());
        rest.get(..end).map(|s| s.trim().to_string())
    };
    // NumPy's reader takes the last of a repeated key, a first-match reader
    // the first: a header that says two things is not read either way
    for key in ["descr", "fortran_order", "shape"] {
        if text.matches(&format!("'{key}'")).count() > 1 {
            return Err(bad(&format!("with '{key}' twice in its header")));
        }
    }
    let descr = field("descr").ok_or_else(|| bad("without a 'descr' in its header"))?;
    match field("fortran_order").as_deref() {
        Some("False") => {}
        Some("True") => return Err(bad("in Fortran order: not read (save it with numpy.ascontiguousarray)")),
        other => {
            let said = other.map_or("nothing".to_string(), crate::files::nav::shown);
            return Err(bad(&format!("whose header's 'fortran_order' is {said}, not True or False")));
        }
    }
    let shape: Vec<u64> = field("shape")
        .ok_or_else(|| bad("without a 'shape' in its header"))?
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<u64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad("with an unreadable 'shape'"))?;
    let (h, w) = match shape.as_slice() {
        [h, w] | [h, w, 1] => (*h, *w),
        other => return Err(bad(&format!("of shape {other:?}: a distance map is 2-D (H, W)"))),
    };
    let (size, mm) = match descr.get(1..) {
        Some("f4") => (4, false),
        Some("f8") => (8, false),
        Some("u2") => (2, true),
        _ => return Err(bad(&format!("of dtype '{descr}': float32 or float64 metres, or uint16 millimetres, are read"))),
    };
    let big = descr.starts_with('>');
    if !(descr.starts_with('<') || big || descr.starts_with('|') || descr.starts_with('=')) {
        return Err(bad(&format!("of dtype '{descr}'")));
    }
    check(h, w, size as u64)?;
    let n = (h * w) as usize;
    let mut raw = vec![0u8; n * size];
    if read_up_to(r, &mut raw)? < raw.len() {
        return Err(bad(&format!("ends before its {w}x{h} values do")));
    }
    let vals: Vec<f32> = match size {
        4 => raw
            .as_chunks::<4>()
            .0
            .iter()
            .map(|&b| {
                if big { f32::from_be_bytes(b) } else { f32::from_le_bytes(b) }
            })
            .collect(),
        8 => raw
            .as_chunks::<8>()
            .0
            .iter()
            .map(|&b| {
                narrow(if big { f64::from_be_bytes(b) } else { f64::from_le_bytes(b) })
            })
            .collect(),
        _ => raw
            .as_chunks::<2>()
            .0
            .iter()
            .map(|&b| {
                let v = if big { u16::from_be_bytes(b) } else { u16::from_le_bytes(b) };
                if mm { millimetres(v) } else { f32::from(v) }
            })
            .collect(),
    };
    Ok((vals, h as usize, w as usize))
}

/// A 16-bit grayscale PNG in millimetres (0 = unknown).
fn read_png<R: std::io::BufRead + Seek>(r: R, check: impl Fn(u64, u64, u64) -> Result<(), Failure>) -> Result<(Vec<f32>, usize, usize), Failure> {
    // a map's chunks besides its pixels are not read: a compressed 300 MB
    // iCCP or a 50 MB eXIf took 70-110 MB past --max-memory 30M
    let mut dec = png::Decoder::new_with_limits(r, png::Limits { bytes: 16 << 20 });
    dec.set_ignore_text_chunk(true);
    dec.set_ignore_iccp_chunk(true);
    let bad = |m: String| Failure::new(Kind::Input, format!("a PNG distance map {m}"));
    let mut reader = dec.read_info().map_err(|e| bad(format!("cannot be read: {e}")))?;
    let info = reader.info();
    let (w, h) = (u64::from(info.width), u64::from(info.height));
    if info.color_type != png::ColorType::Grayscale {
        let kind = match info.color_type {
            png::ColorType::Rgb => "RGB",
            png::ColorType::Rgba => "RGBA",
            png::ColorType::GrayscaleAlpha => "grayscale with alpha",
            png::ColorType::Indexed => "a palette image",
            png::ColorType::Grayscale => "grayscale",
        };
        return Err(bad(format!("is {kind}: a distance map is one channel, 16-bit grayscale in millimetres")));
    }
    if info.bit_depth != png::BitDepth::Sixteen {
        return Err(bad(format!(
            "is {}-bit grayscale: write 16-bit grayscale in millimetres ({} bits cannot hold a distance)",
            info.bit_depth as u8, info.bit_depth as u8
        )));
    }
    check(h, w, 2)?;
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap_or(0)];
    let frame = reader.next_frame(&mut buf).map_err(|e| bad(format!("cannot be decoded: {e}")))?;
    let bytes = buf.get(..frame.buffer_size()).unwrap_or(&[]);
    let vals = bytes.as_chunks::<2>().0.iter().map(|&c| millimetres(u16::from_be_bytes(c))).collect();
    Ok((vals, h as usize, w as usize))
}

/// A single-channel TIFF: float32/float64 metres, or 16-bit millimetres.
fn read_tiff<R: Read + Seek>(mut r: R, check: impl Fn(u64, u64, u64) -> Result<(), Failure>, max_memory: u64) -> Result<(Vec<f32>, usize, usize), Failure> {
    use tiff::decoder::{Decoder, DecodingResult, Limits};
    let bad = |m: String| Failure::new(Kind::Input, format!("a TIFF distance map {m}"));
    crate::files::exif::tiff_structure(&mut r).map_err(|why| bad(format!("is damaged: {why}")))?;
    r.seek(std::io::SeekFrom::Start(0)).map_err(|e| bad(format!("cannot be read: {e}")))?;
    let mut limits = Limits::default();
    limits.decoding_buffer_size = usize::try_from(max_memory).unwrap_or(usize::MAX);
    let mut d = Decoder::new(r).map_err(|e| bad(format!("cannot be read: {e}")))?.with_limits(limits);
    let (w, h) = d.dimensions().map_err(|e| bad(format!("cannot be read: {e}")))?;
    let ct = d.colortype().map_err(|e| bad(format!("cannot be read: {e}")))?;
    let bits = match ct {
        tiff::ColorType::Gray(b) => b,
        tiff::ColorType::Multiband { num_samples, .. } => {
            return Err(bad(format!("has {num_samples} channels: a distance map has one")));
        }
        tiff::ColorType::RGB(_) | tiff::ColorType::RGBA(_) | tiff::ColorType::YCbCr(_) | tiff::ColorType::CMYK(_) => {
            return Err(bad("is a colour image: a distance map has one channel".into()));
        }
        _ => return Err(bad("is not a one-channel image: a distance map has one channel".into())),
    };
    // WhiteIsZero: the decoder turns the codes over (65535 - v), so a map
    // written so reads as other distances with no word
    if d.get_tag_u32(tiff::tags::Tag::PhotometricInterpretation).ok() == Some(0) {
        return Err(bad("has PhotometricInterpretation WhiteIsZero: a distance map's values are read as written, with BlackIsZero (1)".into()));
    }
    check(u64::from(h), u64::from(w), u64::from(bits.max(8)) / 8)?;
    let data = d.read_image().map_err(|e| bad(format!("cannot be decoded: {e}")))?;
    let vals: Vec<f32> = match data {
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(narrow).collect(),
        DecodingResult::U16(v) => v.into_iter().map(millimetres).collect(),
        DecodingResult::I16(_) => return Err(bad("of signed 16-bit samples: float32/float64 metres or unsigned 16-bit millimetres are read".into())),
        DecodingResult::F16(_) => return Err(bad("of 16-bit float samples: float32/float64 metres or unsigned 16-bit millimetres are read".into())),
        _ => return Err(bad(format!("of {bits}-bit samples: float32/float64 metres or unsigned 16-bit millimetres are read"))),
    };
    if vals.len() != (h as usize).saturating_mul(w as usize) {
        return Err(bad("holds fewer values than its size says".into()));
    }
    Ok((vals, h as usize, w as usize))
}

/// A COLMAP dense depth map (`*.geometric.bin`, `*.photometric.bin`): the
/// ASCII header `WIDTH&HEIGHT&CHANNELS&`, then WIDTH x HEIGHT x CHANNELS
/// little-endian float32 with the column index fastest (COLMAP's
/// `Mat<float>` in Fortran order over (width, height, channels), so one
/// channel is row-major); one channel, 0 = unknown. The values are in the
/// reconstruction's units: metres when it was scaled, else some other unit,
/// which scales the fitted attenuation but not the transmission (beta z).
fn read_colmap<R: Read>(mut r: R, check: impl Fn(u64, u64, u64) -> Result<(), Failure>) -> Result<(Vec<f32>, usize, usize), Failure> {
    let bad = |m: String| Failure::new(Kind::Input, format!("a COLMAP depth map {m}"));
    let mut fields = [0u64; 3];
    for f in fields.iter_mut() {
        let mut digits = 0;
        loop {
            let mut b = [0u8; 1];
            if read_up_to(&mut r, &mut b)? == 0 {
                return Err(bad("ends inside its header".into()));
            }
            match b[0] {
                b'0'..=b'9' if digits < 10 => {
                    *f = *f * 10 + u64::from(b[0] - b'0');
                    digits += 1;
                }
                b'&' if digits > 0 => break,
                _ => return Err(bad("has a header that is not WIDTH&HEIGHT&CHANNELS&".into())),
            }
        }
    }
    let [w, h, c] = fields;
    if c != 1 {
        return Err(bad(format!("has {c} channels: a depth map has one (a normal map has three)")));
    }
    check(h, w, 4)?;
    let (h, w) = (h as usize, w as usize);
    let mut bytes = vec![0u8; h.saturating_mul(w).saturating_mul(4)];
    if read_up_to(&mut r, &mut bytes)? < bytes.len() {
        return Err(bad("ends before its values do".into()));
    }
    let vals = bytes.as_chunks::<4>().0.iter().map(|&b| f32::from_le_bytes(b)).collect();
    Ok((vals, h, w))
}

/// The channel of an OpenEXR part that holds the distance: `Z` (or a
/// layered `<layer>.Z`, as renderers name their depth pass), else `depth`
/// (or `<layer>.depth`), else the part's only channel. Two channels of one
/// of those names (a stereo pair's `left.Z` and `right.Z`, or `Z` and `z`)
/// are an error naming both: which one is this photo's is not known.
fn exr_depth_channel(names: &[String]) -> Result<Option<usize>, String> {
    let last = |n: &str| n.rsplit('.').next().unwrap_or(n).to_ascii_lowercase();
    for want in ["z", "depth"] {
        let mut found = names.iter().enumerate().filter(|(_, n)| last(n) == want);
        if let Some((i, first)) = found.next() {
            if let Some((_, second)) = found.next() {
                return Err(format!("has two depth channels, {} and {}: write the photo's own in a file of its own", crate::files::nav::shown(first), crate::files::nav::shown(second)));
            }
            return Ok(Some(i));
        }
    }
    Ok((names.len() == 1).then_some(0))
}

/// Largest OpenEXR header (all parts' attributes) read for a distance map,
/// and most attributes in it. Headers are parsed whole before any size is
/// known: a 20 MB file of a million small attributes took 2.4 GB, one
/// attribute of 100 MB took 300 MB. A renderer's header, preview image
/// included, is far below both.
const MAX_EXR_HEADER_BYTES: u64 = 16 << 20;
const MAX_EXR_ATTRIBUTES: usize = 16_384;

/// Walks an OpenEXR file's headers (attribute names, types and sizes,
/// values passed over) within [`MAX_EXR_HEADER_BYTES`] and
/// [`MAX_EXR_ATTRIBUTES`], before the decoder parses them. Returns to the
/// start of the file.
fn exr_header_bounded<R: std::io::BufRead + Seek>(r: &mut R) -> Result<(), String> {
    let mut head = [0u8; 8];
    r.read_exact(&mut head).map_err(|e| format!("cannot be read: {e}"))?;
    let multipart = head.get(5).is_some_and(|f| f & 0x10 != 0);
    let mut at = 8u64;
    let mut attributes = 0usize;
    // one null-terminated name of at most 255 bytes; empty at the end of a header
    let name = |r: &mut R, at: &mut u64| -> Result<bool, String> {
        let mut buf = Vec::new();
        let n = r.by_ref().take(256).read_until(0, &mut buf).map_err(|e| format!("cannot be read: {e}"))?;
        *at += n as u64;
        match buf.last() {
            Some(0) => Ok(buf.len() > 1),
            _ => Err("cannot be read: an attribute name of more than 255 bytes, or the file ends inside its header".into()),
        }
    };
    loop {
        // one header: attributes until an empty name
        let mut any = false;
        while name(r, &mut at)? {
            any = true;
            attributes += 1;
            name(r, &mut at)?;
            let mut size = [0u8; 4];
            r.read_exact(&mut size).map_err(|_| "cannot be read: the file ends inside its header".to_string())?;
            let size = u64::try_from(i32::from_le_bytes(size)).map_err(|_| "cannot be read: an attribute of negative size".to_string())?;
            at = at.saturating_add(4).saturating_add(size);
            if at > MAX_EXR_HEADER_BYTES || attributes > MAX_EXR_ATTRIBUTES {
                return Err(format!(
                    "has a header of more than {MAX_EXR_HEADER_BYTES} bytes or {MAX_EXR_ATTRIBUTES} attributes: not a distance map's"
                ));
            }
            r.seek_relative(i64::try_from(size).unwrap_or(i64::MAX)).map_err(|e| format!("cannot be read: {e}"))?;
        }
        // a multipart file's list of headers ends with an empty one
        if !multipart || !any {
            break;
        }
    }
    r.seek(SeekFrom::Start(0)).map_err(|e| format!("cannot be read: {e}"))?;
    Ok(())
}

/// The most samples an OpenEXR distance map's parts may hold together for
/// each pixel of its depth channel (every channel of every part is
/// decoded): a renderer's multilayer file of every pass and three
/// Cryptomatte layers (some 70 channels) fits; 40,000 parts beside a
/// small depth part do not.
const MAX_EXR_SAMPLES_PER_PIXEL: u64 = 128;

/// An OpenEXR distance map in metres: the depth channel
/// ([`exr_depth_channel`]) of the first part that has one, flat (not deep),
/// every channel sampled at full resolution. The header is read and the size
/// checked (all channels of all parts are decoded) before the pixels.
fn read_exr<R: std::io::BufRead + Seek>(mut r: R, check: impl Fn(u64, u64, u64) -> Result<(), Failure>) -> Result<(Vec<f32>, usize, usize), Failure> {
    use exr::image::read::image::ReadLayers as _;
    use exr::image::read::layers::ReadChannels as _;
    use exr::prelude::{read, FlatSamples};
    let bad = |m: String| Failure::new(Kind::Input, format!("an OpenEXR distance map {m}"));
    exr_header_bounded(&mut r).map_err(bad)?;
    let meta = exr::meta::MetaData::read_from_buffered(&mut r, false).map_err(|e| bad(format!("cannot be read: {e}")))?;
    let names = |h: &exr::meta::header::Header| -> Vec<String> { h.channels.list.iter().map(|c| c.name.to_string()).collect() };
    let mut with_depth = Vec::new();
    for (i, h) in meta.headers.iter().enumerate() {
        if exr_depth_channel(&names(h)).map_err(bad)?.is_some() {
            with_depth.push(i);
        }
    }
    if let [first, second, ..] = with_depth.as_slice() {
        return Err(bad(format!("has depth channels in two parts, {} and {}: write the photo's own in a file of its own", first + 1, second + 1)));
    }
    let Some((part, header)) = with_depth.first().and_then(|&i| meta.headers.get(i).map(|h| (i, h))) else {
        let first = meta.headers.first().map(names).unwrap_or_default();
        let first = match first.len() {
            n if n > 8 => format!("{}, ... ({n} in all)", first.get(..8).unwrap_or(&[]).join(", ")),
            _ => first.join(", "),
        };
        return Err(bad(format!("has no depth channel (channels: {first}): name it Z or write one channel")));
    };
    if header.deep {
        return Err(bad("holds deep data: a distance map is one flat channel".into()));
    }
    if header.channels.list.iter().any(|c| c.sampling.x() != 1 || c.sampling.y() != 1) {
        return Err(bad("has subsampled channels: a distance map is sampled at every pixel".into()));
    }
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    // the data window is where the pixels are; the display window is the
    // frame they belong in (the photo's). A map cropped to its content, or
    // rendered with overscan, would be stretched over the photo.
    let display = &header.shared_attributes.display_window;
    if header.own_attributes.layer_position != display.position || header.layer_size != display.size {
        let corners = |p: exr::math::Vec2<i32>, s: exr::math::Vec2<usize>| {
            let end = |a: i32, n: usize| i64::from(a) + i64::try_from(n).unwrap_or(i64::MAX) - 1;
            format!("({}, {})-({}, {})", p.x(), p.y(), end(p.x(), s.width()), end(p.y(), s.height()))
        };
        return Err(bad(format!(
            "has its data window {} apart from its display window {}: a cropped or overscanned map is not placed; \
             write it over the whole frame",
            corners(header.own_attributes.layer_position, header.layer_size),
            corners(display.position, display.size)
        )));
    }
    // every channel of every part is decoded, at most 4 bytes a sample
    let samples: u64 = meta.headers.iter().map(|hd| (hd.channels.list.len() as u64).saturating_mul(hd.layer_size.area() as u64)).sum();
    let area = (w as u64).saturating_mul(h as u64).max(1);
    if samples > MAX_EXR_SAMPLES_PER_PIXEL.saturating_mul(area) {
        // the pixel cap holds the depth part only: thousands of parts beside it
        // would decode gigabytes from a small file
        return Err(bad(format!(
            "holds {samples} samples in {} part{}, more than {MAX_EXR_SAMPLES_PER_PIXEL} for each of the {w}x{h} pixels \
             of its depth channel: write the depth in a file of its own",
            meta.headers.len(),
            if meta.headers.len() == 1 { "" } else { "s" }
        )));
    }
    let per_pixel = samples.saturating_mul(4) / area;
    check(h as u64, w as u64, per_pixel.max(4))?;
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .from_buffered(r)
        .map_err(|e| bad(format!("cannot be decoded: {e}")))?;
    let layer = image.layer_data.get(part).ok_or_else(|| bad("has fewer parts than its header lists".into()))?;
    let list = &layer.channel_data.list;
    let chosen: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
    let ch = exr_depth_channel(&chosen).ok().flatten().and_then(|i| list.get(i)).ok_or_else(|| bad("lost its depth channel while decoding".into()))?;
    let vals: Vec<f32> = match &ch.sample_data {
        FlatSamples::F16(_) | FlatSamples::F32(_) => ch.sample_data.values_as_f32().collect(),
        FlatSamples::U32(_) => return Err(bad(format!("has an integer channel {}: metres are read from float channels", ch.name))),
    };
    if vals.len() != w.saturating_mul(h) {
        return Err(bad("holds fewer values than its size says".into()));
    }
    Ok((vals, h, w))
}

/// Entry points for `fuzz/` (cargo-fuzz) and the mutation test below:
/// not part of the API.
#[doc(hidden)]
pub mod fuzzing {
    use super::*;

    /// Any bytes as a distance map of a 64 x 64 photo, with the caps a
    /// batch gives one (4 Mpx, 512 MiB): an error is fine, a panic, a hang
    /// or an allocation past the caps is a bug.
    pub fn depth(data: &[u8]) {
        let _ = read_distance_from(std::io::Cursor::new(data), 1 << 22, 512 << 20, Some((64, 64)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn tmp(name: &str, bytes: &[u8]) -> PathBuf {
        let d = std::env::temp_dir().join(format!("uwhl-depth-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        File::create(&p).unwrap().write_all(bytes).unwrap();
        p
    }

    fn npy(descr: &str, shape: &str, body: &[u8]) -> Vec<u8> {
        let mut head = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + head.len() + 1) % 64 != 0 {
            head.push(' ');
        }
        head.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(head.len() as u16).to_le_bytes());
        out.extend_from_slice(head.as_bytes());
        out.extend_from_slice(body);
        out
    }

    #[test]
    fn npy_float32_metres_with_unknowns() {
        let vals = [1.5f32, f32::NAN, -2.0, 0.0, 2500.0, 7.25];
        let body: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let p = tmp("a.npy", &npy("<f4", "(2, 3)", &body));
        let m = read_distance(&p, 1 << 20, 1 << 30).unwrap();
        assert_eq!((m.height, m.width, m.out_of_range), (2, 3, 1));
        assert_eq!(m.data[0], 1.5);
        assert_eq!(m.data[5], 7.25);
        assert!(m.data[1..5].iter().all(|v| v.is_nan()));
    }

    #[test]
    fn npy_uint16_is_millimetres_and_big_endian_float64_is_read() {
        let body: Vec<u8> = [1500u16, 0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let m = read_distance(&tmp("mm.npy", &npy("<u2", "(1, 2, 1)", &body)), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data[0], 1.5);
        assert!(m.data[1].is_nan());
        let body: Vec<u8> = [3.0f64, 4.0].iter().flat_map(|v| v.to_be_bytes()).collect();
        let m = read_distance(&tmp("be.npy", &npy(">f8", "(2, 1)", &body)), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data, vec![3.0, 4.0]);
    }

    #[test]
    fn hostile_npy_files_get_clear_errors() {
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("short.npy", npy("<f4", "(100, 100)", &[0; 12]), "ends before"),
            ("rgb.npy", npy("<f4", "(2, 2, 3)", &[0; 48]), "2-D"),
            ("int.npy", npy("<i8", "(1, 1)", &[0; 8]), "dtype"),
            ("huge.npy", npy("<f4", "(100000, 100000)", &[]), "max-pixels"),
            ("cut.npy", b"\x93NUMPY\x01\x00\xff\xff{'descr'".to_vec(), "ends inside"),
            ("v9.npy", b"\x93NUMPY\x09\x00\x00\x00".to_vec(), "version 9"),
            ("text.npy", b"hello world".to_vec(), "not a distance map"),
        ];
        for (name, bytes, want) in cases {
            let e = read_distance(&tmp(name, &bytes), 1 << 20, 1 << 30).unwrap_err();
            assert!(e.message.contains(want), "{name}: {}", e.message);
        }
        let mut fortran = npy("<f4", "(1, 1)", &[0; 4]);
        let at = fortran.windows(5).position(|w| w == b"False").unwrap();
        fortran[at..at + 5].copy_from_slice(b"True ");
        let e = read_distance(&tmp("f.npy", &fortran), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("Fortran"), "{}", e.message);
        let mut zero = npy("<f4", "(1, 1)", &[0; 4]);
        let at = zero.windows(5).position(|w| w == b"False").unwrap();
        zero[at..at + 5].copy_from_slice(b"0    ");
        let e = read_distance(&tmp("z.npy", &zero), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("'fortran_order' is \"0\", not True or False"), "{}", e.message);
        // a key twice: NumPy would take the last shape, a first-match reader the first
        let mut two = npy("<f4", "(1, 1)", &[0; 4]);
        let at = two.windows(7).position(|w| w == b"'shape'").unwrap();
        two.splice(at..at, b"'shape': (2, 2), ".iter().copied());
        let e = read_distance(&tmp("two.npy", &two), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("'shape' twice"), "{}", e.message);
    }

    #[test]
    fn float64_distances_beyond_float32_are_counted_out_of_range() {
        // 1e39 m is finite in float64 and inf in float32: counted with the
        // other absurd distances (over 1000 m), not lost as unknown
        let body: Vec<u8> = [1e39f64, 5.0, f64::INFINITY].iter().flat_map(|v| v.to_le_bytes()).collect();
        let m = read_distance(&tmp("big.npy", &npy("<f8", "(1, 3)", &body)), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.out_of_range, 1);
        assert!(m.data[0].is_nan() && m.data[1] == 5.0 && m.data[2].is_nan());
    }

    /// A one-channel PNG of `w` x `h` samples of `depth` bits, written by the png crate.
    fn gray_png(w: u32, h: u32, depth: png::BitDepth, data: &[u8]) -> Vec<u8> {
        let mut buf = Vec::new();
        let mut e = png::Encoder::new(&mut buf, w, h);
        e.set_color(png::ColorType::Grayscale);
        e.set_depth(depth);
        e.write_header().unwrap().write_image_data(data).unwrap();
        buf
    }

    #[test]
    fn sixteen_bit_png_is_millimetres_and_eight_bit_is_refused() {
        let buf = gray_png(2, 1, png::BitDepth::Sixteen, &[0x0b, 0xb8, 0, 0]);
        let m = read_distance(&tmp("d.png", &buf), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data[0], 3.0);
        assert!(m.data[1].is_nan());
        // 65535, the no-data code, and 5 mm (below 1 cm) are unknown; 65534 and 10 mm are distances
        let codes: [u16; 4] = [65535, 5, 65534, 10];
        let buf = gray_png(4, 1, png::BitDepth::Sixteen, &codes.iter().flat_map(|c| c.to_be_bytes()).collect::<Vec<u8>>());
        let m = read_distance(&tmp("nodata.png", &buf), 1 << 20, 1 << 30).unwrap();
        assert!(m.data[0].is_nan() && m.data[1].is_nan(), "{:?}", m.data);
        assert_eq!((m.data[2], m.data[3]), (65.534, 0.01));
        let buf = gray_png(1, 1, png::BitDepth::Eight, &[7]);
        let e = read_distance(&tmp("d8.png", &buf), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("16-bit"), "{}", e.message);
    }

    #[test]
    fn the_template_names_each_inputs_map() {
        let p = expand("depth/{stem}_d.tif", Path::new("/x/dive 01.JPG")).unwrap();
        assert_eq!(p, PathBuf::from("depth/dive 01_d.tif"));
        assert_eq!(expand("maps/{name}.npy", Path::new("a.b.png")).unwrap(), PathBuf::from("maps/a.b.png.npy"));
        assert_eq!(expand("one.npy", Path::new("a.png")).unwrap(), PathBuf::from("one.npy"));
        assert_eq!(expand("{x}/{stem}.{npy", Path::new("a.png")).unwrap(), PathBuf::from("{x}/a.{npy"));
    }

    #[test]
    fn a_map_far_larger_than_its_photo_is_refused_from_its_header() {
        // a 16-bit PNG of 4096 x 2048 (8 Mpx, 16 MB of samples) for a photo of 100 x 200
        let p = tmp("big.png", &gray_png(4096, 2048, png::BitDepth::Sixteen, &vec![0u8; 4096 * 2048 * 2]));
        let e = read_distance_of(&p, 1 << 30, 1 << 34, Some((100, 200))).unwrap_err();
        assert!(e.message.contains("more than 16 times the photo's 200x100"), "{}", e.message);
        // the same map for a photo of 1024 x 512 (16 x 0.5 Mpx = 8 Mpx) is read
        assert_eq!(read_distance_of(&p, 1 << 30, 1 << 34, Some((512, 1024))).unwrap().width, 4096);
    }

    #[test]
    fn a_name_cannot_steer_the_template() {
        // text put in is not expanded again
        assert_eq!(expand("d/{stem}.npy", Path::new("in/{name}.jpg")).unwrap(), PathBuf::from("d/{name}.npy"));
        // a stem of ".." or "." (or "." twice) would leave the folder
        for (t, input) in [("maps/{stem}/depth.npy", "...jpg"), ("maps/{stem}/d.npy", "..jpg"), ("m/{stem}{stem}/d", "..jpg")] {
            let e = expand(t, Path::new(input)).unwrap_err();
            assert!(e.contains("leave the template's folder"), "{e}");
        }
        // ".." inside a longer name is a name, not a folder
        assert_eq!(expand("m/{stem}_d.npy", Path::new("...jpg")).unwrap(), PathBuf::from("m/.._d.npy"));
        // the user's own ".." is theirs
        assert_eq!(expand("../m/{stem}.npy", Path::new("a.jpg")).unwrap(), PathBuf::from("../m/a.npy"));
    }

    #[cfg(unix)]
    #[test]
    fn a_name_that_is_not_utf8_finds_its_map() {
        use std::os::unix::ffi::OsStrExt;
        let input = Path::new(std::ffi::OsStr::from_bytes(b"in/q\xff.jpg"));
        let p = expand("d/{stem}.npy", input).unwrap();
        assert_eq!(p.as_os_str().as_bytes(), b"d/q\xff.npy");
    }

    /// An OpenEXR file of one part with the given channels, written by the
    /// exr crate (the reader under test uses the same crate's decoder; the
    /// values are the ones put in, not read back from our own output).
    fn exr_file(name: &str, w: usize, h: usize, channels: Vec<(&str, exr::prelude::FlatSamples)>) -> PathBuf {
        use exr::prelude::*;
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels.into_iter().map(|(n, v)| AnyChannel::new(n, v)).collect();
        let layer = Layer::new((w, h), LayerAttributes::named("depth"), Encoding::FAST_LOSSLESS, AnyChannels::sort(list));
        let d = std::env::temp_dir().join(format!("uwhl-depth-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        Image::from_layer(layer).write().to_file(&p).unwrap();
        p
    }

    #[test]
    fn exr_depth_channel_in_metres_with_unknowns() {
        use exr::prelude::{f16, FlatSamples};
        // 3 x 2, row-major: a NaN, a zero and a value beyond 1000 m are unknown
        let z = vec![1.5f32, 2.0, f32::NAN, 0.0, 2000.0, 7.25];
        let m = read_distance(&exr_file("z.exr", 3, 2, vec![("Z", FlatSamples::F32(z))]), 1 << 20, 1 << 30).unwrap();
        assert_eq!((m.height, m.width, m.out_of_range), (2, 3, 1));
        assert_eq!((m.data[0], m.data[1], m.data[5]), (1.5, 2.0, 7.25));
        assert!(m.data[2].is_nan() && m.data[3].is_nan() && m.data[4].is_nan());
        // a half-float single channel of any name
        let y: Vec<f16> = [3.0f32, 0.5].iter().map(|&v| f16::from_f32(v)).collect();
        let m = read_distance(&exr_file("y.exr", 2, 1, vec![("Y", FlatSamples::F16(y))]), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data, vec![3.0, 0.5]);
    }

    #[test]
    fn exr_depth_pass_is_found_beside_colour_channels() {
        use exr::prelude::FlatSamples;
        let n = 4;
        let col = || FlatSamples::F32(vec![0.5; n]);
        let chans = vec![("R", col()), ("G", col()), ("B", col()), ("A", col()), ("ViewLayer.Depth.Z", FlatSamples::F32(vec![1.0, 2.0, 3.0, 4.0]))];
        let m = read_distance(&exr_file("pass.exr", 2, 2, chans), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data, vec![1.0, 2.0, 3.0, 4.0]);
        let chans = vec![("R", col()), ("G", col()), ("depth", FlatSamples::F32(vec![9.0; n]))];
        assert_eq!(read_distance(&exr_file("named.exr", 2, 2, chans), 1 << 20, 1 << 30).unwrap().data, vec![9.0; n]);
    }

    #[test]
    fn hostile_exr_files_get_clear_errors() {
        use exr::prelude::FlatSamples;
        let col = || FlatSamples::F32(vec![0.5; 6]);
        // colour without a depth channel: the channels are named
        let p = exr_file("rgb.exr", 3, 2, vec![("R", col()), ("G", col()), ("B", col())]);
        let e = read_distance(&p, 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("no depth channel") && e.message.contains("B, G, R"), "{}", e.message);
        // integers are not metres
        let p = exr_file("u32.exr", 3, 2, vec![("Z", FlatSamples::U32(vec![1; 6]))]);
        let e = read_distance(&p, 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("integer channel Z"), "{}", e.message);
        // over the pixel budget: refused from the header
        let p = exr_file("big.exr", 3, 2, vec![("Z", col())]);
        let e = read_distance(&p, 5, 1 << 30).unwrap_err();
        assert!(e.message.contains("over --max-pixels 5"), "{}", e.message);
        // a depth channel among more samples than a renderer's passes: refused from the
        // header (thousands of parts of a small file once decoded to gigabytes)
        let names: Vec<String> = (0..140).map(|i| format!("P{i:03}")).collect();
        let mut many: Vec<(&str, FlatSamples)> = names.iter().map(|n| (n.as_str(), col())).collect();
        many.push(("Z", col()));
        let e = read_distance(&exr_file("passes.exr", 3, 2, many), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("846 samples in 1 part, more than 128 for each of the 3x2 pixels"), "{}", e.message);
        // a renderer's 70 channels (every pass, Cryptomatte) are read
        let mut fits: Vec<(&str, FlatSamples)> = names.iter().take(69).map(|n| (n.as_str(), col())).collect();
        fits.push(("Z", col()));
        assert_eq!(read_distance(&exr_file("fits.exr", 3, 2, fits), 1 << 20, 1 << 30).unwrap().data, vec![0.5; 6]);
        // cut short, or its magic number followed by noise
        let whole = std::fs::read(&p).unwrap();
        for (name, bytes) in [("cut.exr", whole[..whole.len() * 2 / 3].to_vec()), ("noise.exr", [&whole[..4], &[0xAB; 64][..]].concat())] {
            let e = read_distance(&tmp(name, &bytes), 1 << 20, 1 << 30).unwrap_err();
            assert!(e.message.starts_with("an OpenEXR distance map cannot be"), "{name}: {}", e.message);
        }
    }

    /// An OpenEXR file of one `Z` channel (3 x 2 values of 2 m) whose data
    /// window starts at `at` inside a display window of `display` pixels,
    /// with `extra` attributes of 4 bytes each.
    fn exr_placed(name: &str, at: (i32, i32), display: (usize, usize), extra: usize) -> PathBuf {
        use exr::prelude::*;
        let mut attrs = LayerAttributes::named("depth");
        attrs.layer_position = Vec2(at.0, at.1);
        for i in 0..extra {
            attrs.other.insert(Text::from(format!("a{i}").as_str()), AttributeValue::I32(0));
        }
        let z: SmallVec<[AnyChannel<FlatSamples>; 4]> = [AnyChannel::new("Z", FlatSamples::F32(vec![2.0; 6]))].into_iter().collect();
        let z = AnyChannels::sort(z);
        let layer = Layer::new((3, 2), attrs, Encoding::UNCOMPRESSED, z);
        let mut image = Image::from_layer(layer);
        image.attributes.display_window = IntegerBounds::new(Vec2(0, 0), Vec2(display.0, display.1));
        let d = std::env::temp_dir().join(format!("uwhl-depth-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        image.write().to_file(&p).unwrap();
        p
    }

    #[test]
    fn exr_maps_that_cannot_be_placed_or_chosen_are_refused_by_name() {
        use exr::prelude::FlatSamples;
        // placed over its whole frame: read
        assert_eq!(read_distance(&exr_placed("whole.exr", (0, 0), (3, 2), 0), 1 << 20, 1 << 30).unwrap().data, vec![2.0; 6]);
        // cropped inside a 5 x 4 frame, or shifted out of it
        for (name, at, display, corners) in [
            ("crop.exr", (1, 1), (5, 4), "data window (1, 1)-(3, 2) apart from its display window (0, 0)-(4, 3)"),
            ("shifted.exr", (40, 0), (3, 2), "data window (40, 0)-(42, 1) apart from its display window (0, 0)-(2, 1)"),
        ] {
            let e = read_distance(&exr_placed(name, at, display, 0), 1 << 20, 1 << 30).unwrap_err();
            assert!(e.message.contains(corners), "{name}: {}", e.message);
        }
        // a stereo pair's two depth passes, or Z beside z
        fn two<'a>(a: &'a str, b: &'a str) -> Vec<(&'a str, FlatSamples)> {
            vec![(a, FlatSamples::F32(vec![1.0; 6])), (b, FlatSamples::F32(vec![3.0; 6]))]
        }
        for (name, chans) in [("stereo.exr", two("left.Z", "right.Z")), ("zz.exr", two("Z", "z")), ("dd.exr", two("a.depth", "b.depth"))] {
            let e = read_distance(&exr_file(name, 3, 2, chans), 1 << 20, 1 << 30).unwrap_err();
            assert!(e.message.contains("has two depth channels"), "{name}: {}", e.message);
        }
        // Z beside a depth pass: Z is the distance, as before
        let m = read_distance(&exr_file("zd.exr", 3, 2, two("depth", "Z")), 1 << 20, 1 << 30).unwrap();
        assert_eq!(m.data, vec![3.0; 6]);
        // a header of 20,000 small attributes is refused before it is parsed
        let e = read_distance(&exr_placed("attrs.exr", (0, 0), (3, 2), 20_000), 1 << 20, 1 << 30).unwrap_err();
        assert!(e.message.contains("16384 attributes"), "{}", e.message);
        assert_eq!(read_distance(&exr_placed("some.exr", (0, 0), (3, 2), 500), 1 << 20, 1 << 30).unwrap().data.len(), 6);
    }

    /// COLMAP's layout: the header, then float32 with the column index fastest.
    fn colmap(w: usize, h: usize, c: usize, vals: &[f32]) -> Vec<u8> {
        let mut out = format!("{w}&{h}&{c}&").into_bytes();
        for v in vals {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    #[test]
    fn colmap_depth_maps_are_read_row_major_with_zero_unknown() {
        // 3 wide, 2 high: (x, y) = (0, 0), (1, 0), (2, 0), (0, 1), ...
        let m = read_distance(&tmp("d.geometric.bin", &colmap(3, 2, 1, &[1.0, 2.0, 0.0, 4.0, 5.0, 6.5])), 1 << 20, 1 << 30).unwrap();
        assert_eq!((m.height, m.width), (2, 3));
        assert_eq!((m.data[1], m.data[3], m.data[5]), (2.0, 4.0, 6.5));
        assert!(m.data[2].is_nan());
        for (name, bytes, want) in [
            ("normals.bin", colmap(2, 2, 3, &[0.0; 12]), "3 channels"),
            ("cut.bin", colmap(4, 4, 1, &[1.0; 15]), "ends before its values"),
            ("head.bin", b"12&34".to_vec(), "ends inside its header"),
            ("junk.bin", b"12&x4&1&".to_vec(), "not WIDTH&HEIGHT&CHANNELS&"),
            ("long.bin", b"123456789012&1&1&".to_vec(), "not a distance map"),
            ("wide.bin", b"12345678901&1&1&".to_vec(), "not a distance map"),
            ("eleven.bin", b"1234&12345678901&1&".to_vec(), "not WIDTH&HEIGHT&CHANNELS&"),
            ("big.bin", b"100000&100000&1&".to_vec(), "over --max-pixels"),
        ] {
            let e = read_distance(&tmp(name, &bytes), 1 << 20, 1 << 30).unwrap_err();
            assert!(e.message.contains(want), "{name}: {}", e.message);
        }
    }

    /// Valid maps of every format read here, small: the seeds of the
    /// mutation test and of `fuzz/meta_seeds/depth`.
    fn seeds() -> Vec<(&'static str, Vec<u8>)> {
        let vals: Vec<f32> = (0..6 * 5).map(|i| 0.5 + i as f32 * 0.25).collect();
        let npy_f4 = npy("<f4", "(5, 6)", &vals.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());
        let png16 = gray_png(6, 5, png::BitDepth::Sixteen, &vals.iter().flat_map(|v| ((v * 1000.0) as u16).to_be_bytes()).collect::<Vec<u8>>());
        let tif = |big: bool| {
            let mut f = std::io::Cursor::new(Vec::new());
            if big {
                tiff::encoder::TiffEncoder::new_big(&mut f).unwrap().write_image::<tiff::encoder::colortype::Gray32Float>(6, 5, &vals).unwrap();
            } else {
                tiff::encoder::TiffEncoder::new(&mut f).unwrap().write_image::<tiff::encoder::colortype::Gray32Float>(6, 5, &vals).unwrap();
            }
            f.into_inner()
        };
        let exr = std::fs::read(exr_file("seed.exr", 6, 5, vec![("Z", exr::prelude::FlatSamples::F32(vals.clone()))])).unwrap();
        vec![("npy", npy_f4), ("png16", png16), ("tiff", tif(false)), ("bigtiff", tif(true)), ("exr", exr), ("colmap", colmap(6, 5, 1, &vals))]
    }

    #[test]
    fn mutated_maps_of_every_format_fail_cleanly() {
        // A deterministic fuzz pass that runs with the tests (fuzz/run goes
        // further): each valid seed read once, then 2000 mutants of it (bytes
        // overwritten with random, extreme or boundary values, cut short, a
        // run duplicated), each read as a 64 x 64 photo's map. Any panic
        // fails the test; the seeds must read as themselves.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for (name, seed) in seeds() {
            let m = read_distance_from(std::io::Cursor::new(&seed), 1 << 22, 512 << 20, Some((64, 64)))
                .unwrap_or_else(|e| panic!("{name}: {}", e.message));
            assert_eq!((m.height, m.width), (5, 6), "{name}");
            assert!((m.data[7] - 2.25).abs() < 1e-3, "{name}: {}", m.data[7]);
            for _ in 0..2000 {
                let mut b = seed.clone();
                for _ in 0..1 + next() % 4 {
                    let at = (next() % b.len() as u64) as usize;
                    match next() % 5 {
                        0 => b[at] = next() as u8,
                        1 => b[at] = [0x00, 0xFF, 0x7F, 0x80][(next() % 4) as usize],
                        2 => {
                            let end = (at + 4).min(b.len());
                            b[at..end].fill(0xFF);
                        }
                        3 => b.truncate(at.max(1)),
                        _ => {
                            let end = (at + 1 + (next() % 16) as usize).min(b.len());
                            let run = b[at..end].to_vec();
                            b.splice(at..at, run);
                        }
                    }
                }
                fuzzing::depth(&b);
            }
        }
    }
}
