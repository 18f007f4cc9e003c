//! Bounded readers of the metadata inside a JPEG, PNG or TIFF file, one
//! implementation for both commands (docs/OUTPUTS.md "Metadata"): the JPEG
//! segments and PNG chunks that hold EXIF, XMP and the ICC profile, a
//! validator of TIFF-structured EXIF, and the one reading of orientation.
//!
//! Metadata is as hostile as pixels: the EXIF parser of `little_exif`
//! follows IFD links without looking for loops and allocates what a count
//! says, and PNG chunks inflate without bound. Everything here works on
//! offsets checked against the data, inflates with a cap, and stops at
//! [`MAX_IFDS`], [`MAX_ENTRIES`] and [`MAX_VALUE_BYTES`]; a block that
//! breaks a limit is refused whole, with the reason, and the photo is read
//! without it.

use std::collections::HashSet;
use std::io::{Read, Seek, SeekFrom};

/// Most IFDs (IFD0, IFD1, ..., the Exif, GPS and Interop sub-IFDs) walked
/// in one EXIF block or TIFF file.
pub const MAX_IFDS: usize = 64;
/// Most entries over all the IFDs of one block.
pub const MAX_ENTRIES: usize = 8192;
/// Most bytes of values stored outside their entries (text, arrays,
/// rationals) in one block, not counting image strips and the thumbnail,
/// which must lie inside the block and not add up to more than it.
pub const MAX_VALUE_BYTES: u64 = 16 << 20;
/// The same three limits for a whole TIFF file ([`tiff_structure`]): a
/// multi-page file or a pyramid has many IFDs (every page and its
/// SubIFDs), each with its tables, and a decoder reads them lazily, where
/// an EXIF block is parsed whole.
pub const MAX_FILE_IFDS: usize = 4096;
/// See [`MAX_FILE_IFDS`].
pub const MAX_FILE_ENTRIES: usize = 1 << 18;
/// See [`MAX_FILE_IFDS`].
pub const MAX_FILE_VALUE_BYTES: u64 = 1 << 30;
/// The largest EXIF block, XMP packet or ICC profile read (after
/// inflating): real ones are well under a few MB.
pub const MAX_BLOCK: u64 = 16 << 20;

/// A TIFF-structured block (an EXIF block or a whole TIFF file) read by
/// offset: a byte slice, or a file read through seeks.
pub trait Source {
    /// its length in bytes
    fn size(&self) -> u64;
    /// fills `buf` from offset `at`; false when that is past the end or unreadable
    fn read_at(&mut self, at: u64, buf: &mut [u8]) -> bool;
}

impl Source for &[u8] {
    fn size(&self) -> u64 {
        self.len() as u64
    }
    fn read_at(&mut self, at: u64, buf: &mut [u8]) -> bool {
        let Ok(at) = usize::try_from(at) else { return false };
        match at.checked_add(buf.len()).and_then(|end| self.get(at..end)) {
            Some(s) => {
                buf.copy_from_slice(s);
                true
            }
            None => false,
        }
    }
}

/// A [`Source`] over a reader (a TIFF file, not held in memory).
pub struct ReaderSource<'a, R> {
    inner: &'a mut R,
    len: u64,
}

impl<'a, R: Read + Seek> ReaderSource<'a, R> {
    /// The reader's whole length is the block.
    pub fn new(inner: &'a mut R) -> std::io::Result<Self> {
        let len = inner.seek(SeekFrom::End(0))?;
        Ok(Self { inner, len })
    }
}

impl<R: Read + Seek> Source for ReaderSource<'_, R> {
    fn size(&self) -> u64 {
        self.len
    }
    fn read_at(&mut self, at: u64, buf: &mut [u8]) -> bool {
        at.checked_add(buf.len() as u64).is_some_and(|end| end <= self.len)
            && self.inner.seek(SeekFrom::Start(at)).is_ok()
            && self.inner.read_exact(buf).is_ok()
    }
}

/// One IFD entry: tag, type, count and the value-or-offset bytes (four
/// in classic TIFF, eight in BigTIFF; the rest zero).
#[derive(Debug, Clone, Copy)]
struct Entry {
    tag: u16,
    kind: u16,
    count: u64,
    raw: [u8; 8],
}

/// The byte order of a TIFF header, and whether it is a BigTIFF (magic 43:
/// counts, offsets and the value field of an entry are eight bytes).
#[derive(Debug, Clone, Copy)]
struct Order {
    le: bool,
    big: bool,
}

impl Order {
    fn u16(self, b: [u8; 2]) -> u16 {
        if self.le { u16::from_le_bytes(b) } else { u16::from_be_bytes(b) }
    }
    fn u32(self, b: [u8; 4]) -> u32 {
        if self.le { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) }
    }
    fn u64(self, b: [u8; 8]) -> u64 {
        if self.le { u64::from_le_bytes(b) } else { u64::from_be_bytes(b) }
    }
    /// Bytes of an entry's value field: values this size or smaller are
    /// stored in it, larger ones at the offset it holds.
    fn inline(self) -> u64 {
        if self.big { 8 } else { 4 }
    }
    /// The offset an entry's value field holds.
    fn offset(self, raw: [u8; 8]) -> u64 {
        if self.big { self.u64(raw) } else { u64::from(self.u32([raw[0], raw[1], raw[2], raw[3]])) }
    }
}

/// Bytes per value of a TIFF type (6.0, the IFD type 13 and BigTIFF's
/// LONG8, SLONG8 and IFD8); None if unknown.
fn type_size(kind: u16) -> Option<u64> {
    match kind {
        1 | 2 | 6 | 7 => Some(1),
        3 | 8 => Some(2),
        4 | 9 | 11 | 13 => Some(4),
        5 | 10 | 12 | 16 | 17 | 18 => Some(8),
        _ => None,
    }
}

/// The byte order and the offset of IFD0: a classic TIFF header (magic
/// 42), or a BigTIFF's (magic 43, offset size 8, then the 8-byte offset).
fn header(src: &mut dyn Source) -> Result<(Order, u64), String> {
    let mut h = [0u8; 8];
    if !src.read_at(0, &mut h) {
        return Err("the EXIF block is shorter than a TIFF header".into());
    }
    let le = match &h[..2] {
        b"II" => true,
        b"MM" => false,
        _ => return Err("the EXIF block does not start with a TIFF header".into()),
    };
    let classic = Order { le, big: false };
    match classic.u16([h[2], h[3]]) {
        42 => Ok((classic, u64::from(classic.u32([h[4], h[5], h[6], h[7]])))),
        43 => {
            let big = Order { le, big: true };
            let mut off = [0u8; 8];
            if big.u16([h[4], h[5]]) != 8 || big.u16([h[6], h[7]]) != 0 || !src.read_at(8, &mut off) {
                return Err("the EXIF block's BigTIFF header is not offset size 8 followed by an offset".into());
            }
            Ok((big, big.u64(off)))
        }
        _ => Err("the EXIF block does not start with a TIFF header".into()),
    }
}

/// The entries of the IFD at `at` and its link to the next IFD (at most
/// [`MAX_ENTRIES`] entries: a BigTIFF's count is eight bytes).
fn ifd(src: &mut dyn Source, o: Order, at: u64) -> Result<(Vec<Entry>, u64), String> {
    let (count_size, entry_size, link_size) = if o.big { (8, 20, 8) } else { (2, 12, 4) };
    let mut c = [0u8; 8];
    if !c.get_mut(..count_size).is_some_and(|head| src.read_at(at, head)) {
        return Err(format!("an EXIF IFD offset ({at}) is outside the block"));
    }
    let n = if o.big { o.u64(c) } else { u64::from(o.u16([c[0], c[1]])) };
    if n > MAX_ENTRIES as u64 {
        return Err(format!("the EXIF IFD at {at} has {n} entries, over {MAX_ENTRIES}"));
    }
    let n = n as usize;
    let mut raw = vec![0u8; n * entry_size + link_size];
    if !src.read_at(at + count_size as u64, &mut raw) {
        return Err(format!("the EXIF IFD at {at} ({n} entries) runs past the block"));
    }
    let entries = raw
        .chunks_exact(entry_size)
        .take(n)
        .filter_map(|e| {
            // tag and type, then the count and value fields: 4 + 4 bytes in
            // classic TIFF, 8 + 8 in BigTIFF (every chunk has entry_size bytes)
            let ([t0, t1, k0, k1], fields) = e.split_first_chunk::<4>()?;
            let (count, value) = fields.split_at_checked((entry_size - 4) / 2)?;
            let mut v = [0u8; 8];
            v.iter_mut().zip(value).for_each(|(d, &b)| *d = b);
            let mut k = [0u8; 8];
            k.iter_mut().zip(count).for_each(|(d, &b)| *d = b);
            let [c0, c1, c2, c3, ..] = k;
            Some(Entry {
                tag: o.u16([*t0, *t1]),
                kind: o.u16([*k0, *k1]),
                count: if o.big { o.u64(k) } else { u64::from(o.u32([c0, c1, c2, c3])) },
                raw: v,
            })
        })
        .collect();
    let mut l = [0u8; 8];
    if let (Some(dst), Some(src)) = (l.get_mut(..link_size), raw.get(n * entry_size..)) {
        dst.copy_from_slice(src);
    }
    Ok((entries, o.offset(l)))
}

/// The first `n` bytes of an entry's values, `size` bytes each: in its
/// value field when all of them fit there, else at the offset it holds.
/// None when they lie outside the block.
fn value_bytes(src: &mut dyn Source, o: Order, e: &Entry, size: u64, n: usize) -> Option<Vec<u8>> {
    let mut v = vec![0u8; n];
    if size.saturating_mul(e.count) <= o.inline() {
        v.copy_from_slice(e.raw.get(..n)?);
    } else if !src.read_at(o.offset(e.raw), &mut v) {
        return None;
    }
    Some(v)
}

/// The integer values of the entry tagged `tag` in `list`, at most `max`
/// of them; None when there is none or its values cannot be read.
fn tag_integers(src: &mut dyn Source, o: Order, list: &[Entry], tag: u16, max: u64) -> Option<Vec<u64>> {
    list.iter().find(|e| e.tag == tag).and_then(|e| integers(src, o, e, max).ok())
}

/// The first integer value of the entry tagged `tag` in `list` ([`tag_integers`]).
fn tag_integer(src: &mut dyn Source, o: Order, list: &[Entry], tag: u16) -> Option<u64> {
    tag_integers(src, o, list, tag, 1).and_then(|v| v.first().copied())
}

/// The integer values (BYTE, SHORT, LONG) of an entry, at most `max` of them.
fn integers(src: &mut dyn Source, o: Order, e: &Entry, max: u64) -> Result<Vec<u64>, String> {
    let size = match e.kind {
        1 => 1,
        3 => 2,
        4 | 13 => 4,
        16 | 18 => 8,
        k => return Err(format!("EXIF tag 0x{:04X} has type {k}, not an integer", e.tag)),
    };
    if e.count > max {
        return Err(format!("EXIF tag 0x{:04X} has {} values, over {max}", e.tag, e.count));
    }
    let data = value_bytes(src, o, e, size as u64, size * e.count as usize)
        .ok_or_else(|| format!("the values of EXIF tag 0x{:04X} are outside the block", e.tag))?;
    Ok(data
        .chunks_exact(size)
        .map(|c| match size {
            1 => c.first().map_or(0, |&b| u64::from(b)),
            2 => c.try_into().map_or(0, |b| u64::from(o.u16(b))),
            4 => c.try_into().map_or(0, |b| u64::from(o.u32(b))),
            _ => c.try_into().map_or(0, |b| o.u64(b)),
        })
        .collect())
}

/// The tags whose value is the offset of a sub-IFD (Exif, GPS, Interop).
const SUB_IFDS: [u16; 3] = [0x8769, 0x8825, 0xA005];

/// What a valid block holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Walked {
    /// IFDs walked
    pub ifds: usize,
    /// entries over all of them
    pub entries: usize,
}

/// Checks a TIFF-structured block (an EXIF block, or a TIFF file) before
/// a parser that trusts it is let near it: every IFD inside the block and
/// reached once (a link back to an IFD already walked is a loop), at most
/// [`MAX_IFDS`] IFDs and [`MAX_ENTRIES`] entries, every type known, every
/// value inside the block, out-of-line values under [`MAX_VALUE_BYTES`] in
/// all, image strips and the thumbnail inside the block and no larger than
/// it. The reason is returned when one fails.
pub fn check(src: &mut dyn Source) -> Result<Walked, String> {
    // an EXIF block is classic TIFF (EXIF 2.3, 4.6.2); its readers know no other
    if header(src)?.0.big {
        return Err("the EXIF block is a BigTIFF, which EXIF does not allow".into());
    }
    walk(src, true, false)
}

/// [`check`] of classic TIFF or BigTIFF, with the image strips and
/// thumbnail checked only when `check_data` (a whole TIFF file cut short
/// is the decoder's to name: "the file ends before its image data does").
/// With `image` (a TIFF file or a raw file built on TIFF, not an EXIF
/// block) the SubIFDs (0x014A, where a DNG keeps its raw image) are walked
/// too, and every IFD with a size and a strip or tile table must list as
/// many strips or tiles as its size needs ([`covered`]).
fn walk(src: &mut dyn Source, check_data: bool, image: bool) -> Result<Walked, String> {
    walk_as(src, check_data, image, false)
}

/// [`walk`]; when `lenient` (a raw file, whose own decoder judges its
/// structure), only a strip or tile table that does not cover its image
/// fails: an entry that cannot be read is skipped, an IFD that cannot be
/// read or is reached twice is left, and the walk ends at the limits.
fn walk_as(src: &mut dyn Source, check_data: bool, image: bool, lenient: bool) -> Result<Walked, String> {
    // a problem of the structure: skipped (`$skip`) when lenient, else the error
    macro_rules! or_skip {
        ($r:expr, $skip:tt) => {
            match $r {
                Ok(v) => v,
                Err(_) if lenient => $skip,
                Err(m) => return Err(m),
            }
        };
    }
    let (max_ifds, max_entries, max_values) =
        if image { (MAX_FILE_IFDS, MAX_FILE_ENTRIES, MAX_FILE_VALUE_BYTES) } else { (MAX_IFDS, MAX_ENTRIES, MAX_VALUE_BYTES) };
    let (o, ifd0) = or_skip!(header(src), { return Ok(Walked { ifds: 0, entries: 0 }) });
    // IFD0 cannot overlap the header (an offset of 0 would read the header as an IFD)
    if ifd0 < 8 && !lenient {
        return Err(format!("the EXIF block's header gives IFD0 at offset {ifd0}, inside the header: no image directory"));
    }
    let len = src.size();
    // an IFD counts against the limit when it is queued: the walked and the
    // queued ones never exceed it (8192 SubIFDs entries of 4096 offsets each
    // were 268M queued before one was taken)
    let room = |walked: usize, queued: usize, more: usize| {
        if walked + queued + more > max_ifds { Err(format!("the EXIF block has more than {max_ifds} IFDs")) } else { Ok(()) }
    };
    let mut seen = HashSet::new();
    let mut todo = vec![(ifd0, true)];
    let (mut ifds, mut entries, mut values) = (0usize, 0usize, 0u64);
    while let Some((at, chained)) = todo.pop() {
        if !seen.insert(at) {
            or_skip!(Err(format!("the EXIF IFDs form a loop (the IFD at offset {at} is reached twice)")), continue);
        }
        ifds += 1;
        let (list, next) = or_skip!(ifd(src, o, at), continue);
        entries += list.len();
        if entries > max_entries {
            or_skip!(Err(format!("the EXIF block has more than {max_entries} entries")), break);
        }
        let (mut strips, mut counts, mut thumb, mut thumb_len) = (None, None, None, None);
        let mut layout = Layout::default();
        for e in &list {
            let size = or_skip!(type_size(e.kind).ok_or_else(|| format!("EXIF tag 0x{:04X} has an unknown type {}", e.tag, e.kind)), continue);
            let bytes = size.saturating_mul(e.count);
            if bytes > o.inline() {
                let off = o.offset(e.raw);
                if off.checked_add(bytes).is_none_or(|end| end > len) {
                    or_skip!(Err(format!("the value of EXIF tag 0x{:04X} ({bytes} bytes at {off}) is outside the block", e.tag)), continue);
                }
                values += bytes;
                if values > max_values {
                    or_skip!(Err(format!("the EXIF values add up to more than {max_values} bytes")), break);
                }
            }
            match e.tag {
                t if SUB_IFDS.contains(&t) => {
                    let first = or_skip!(integers(src, o, e, 1 << 16), continue);
                    match first.first() {
                        Some(&sub) if matches!(e.kind, 4 | 13 | 16 | 18) => {
                            or_skip!(room(ifds, todo.len(), 1), break);
                            todo.push((sub, false))
                        }
                        _ => or_skip!(Err(format!("EXIF sub-IFD tag 0x{t:04X} is not a LONG offset")), continue),
                    }
                }
                0x014A if image => {
                    if !matches!(e.kind, 4 | 13 | 16 | 18) {
                        or_skip!(Err("EXIF SubIFDs tag 0x014A is not a list of LONG offsets".to_string()), continue);
                    }
                    let subs = or_skip!(integers(src, o, e, max_ifds as u64), continue);
                    or_skip!(room(ifds, todo.len(), subs.len()), break);
                    todo.extend(subs.into_iter().map(|sub| (sub, false)));
                }
                0x0100 | 0x0101 | 0x0115 | 0x0116 | 0x011C | 0x0142 | 0x0143 if image => {
                    let v = or_skip!(integers(src, o, e, 1 << 16), continue).first().copied();
                    match e.tag {
                        0x0100 => layout.width = v,
                        0x0101 => layout.height = v,
                        0x0115 => layout.samples = v,
                        0x0116 => layout.rows_per_strip = v,
                        0x011C => layout.planar = v,
                        0x0142 => layout.tile_width = v,
                        _ => layout.tile_height = v,
                    }
                }
                0x0111 | 0x0144 => strips = Some(or_skip!(integers(src, o, e, 1 << 20), continue)),
                0x0117 | 0x0145 => counts = Some(or_skip!(integers(src, o, e, 1 << 20), continue)),
                0x0201 => thumb = Some(or_skip!(integers(src, o, e, 1 << 20), continue)),
                0x0202 => thumb_len = Some(or_skip!(integers(src, o, e, 1 << 20), continue)),
                _ => {}
            }
        }
        if image {
            if let Some(listed) = strips.as_ref().map(Vec::len).into_iter().chain(counts.as_ref().map(Vec::len)).min() {
                covered(&layout, listed as u64)?;
            }
        }
        for (offsets, sizes) in [(strips, counts), (thumb, thumb_len)] {
            let (Some(offsets), Some(sizes), true) = (offsets, sizes, check_data) else { continue };
            let mut total = 0u64;
            for (off, n) in offsets.iter().zip(&sizes) {
                total += n;
                if off.checked_add(*n).is_none_or(|end| end > len) || total > len {
                    or_skip!(Err(format!("the EXIF image data ({n} bytes at {off}) is outside the block")), break);
                }
            }
        }
        if chained && next != 0 {
            or_skip!(room(ifds, todo.len(), 1), break);
            todo.push((next, true));
        }
    }
    Ok(Walked { ifds, entries })
}

/// The layout tags of one IFD ([`covered`]); None when not given.
#[derive(Debug, Default)]
struct Layout {
    width: Option<u64>,
    height: Option<u64>,
    samples: Option<u64>,
    rows_per_strip: Option<u64>,
    planar: Option<u64>,
    tile_width: Option<u64>,
    tile_height: Option<u64>,
}

/// Whether an IFD's strip or tile table (`listed` entries, the shorter
/// of its offsets and byte counts) covers its image: ceil(W / TileWidth) x
/// ceil(H / TileLength) tiles, or ceil(H / RowsPerStrip) strips (one
/// without RowsPerStrip), each once per sample when the samples are
/// planar. A decoder reads the missing ones from past the table (LibRaw
/// restored a DNG patched to 8000 x 4000 over a table of 4 tiles, from
/// whatever bytes followed, in 3.4 GB). An IFD without a size is not
/// judged.
fn covered(l: &Layout, listed: u64) -> Result<(), String> {
    let (Some(w), Some(h)) = (l.width, l.height) else { return Ok(()) };
    if w == 0 || h == 0 {
        return Ok(());
    }
    let (what, each) = match (l.tile_width, l.tile_height) {
        (Some(tw), Some(th)) if tw > 0 && th > 0 => ("tiles", w.div_ceil(tw).saturating_mul(h.div_ceil(th))),
        _ => ("strips", h.div_ceil(l.rows_per_strip.filter(|&r| r > 0).unwrap_or(h).min(h))),
    };
    let planes = if l.planar == Some(2) { l.samples.unwrap_or(1).max(1) } else { 1 };
    let needed = each.saturating_mul(planes);
    if listed < needed {
        return Err(format!("the EXIF image of {w} x {h} pixels needs {needed} {what}, and its table lists {listed}"));
    }
    Ok(())
}

/// Whether `src` starts as a classic TIFF or a BigTIFF, either byte order.
fn is_tiff(src: &mut dyn Source) -> bool {
    let mut magic = [0u8; 4];
    src.read_at(0, &mut magic) && matches!(&magic, b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+")
}

/// A whole TIFF file's structure checked by [`check`] before a decoder
/// reads it: Err with the reason when it fails. The `tiff` crate trusts
/// a tag's count (an ASCII ImageWidth of 4 GiB went to a `dbg!` on stderr,
/// which deadlocked a binary that held stderr), in classic TIFF and in
/// BigTIFF alike (magic 42 or 43); a file that is neither is the
/// decoder's to name.
pub fn tiff_structure<R: Read + Seek>(r: &mut R) -> Result<(), String> {
    let mut src = ReaderSource::new(r).map_err(|e| e.to_string())?;
    if !is_tiff(&mut src) {
        return Ok(());
    }
    // the walk's words are an EXIF block's; here the block is the file
    walk(&mut src, false, true)
        .map(|_| ())
        .map_err(|m| m.replace("the EXIF block", "the file").replace("the block", "the file").replace("an EXIF ", "a TIFF ").replace("EXIF ", "TIFF "))
}

/// The image of a TIFF file that is decoded: the first IFD of the
/// top-level chain that is not a reduced-resolution image (NewSubfileType
/// bit 0, or the old SubfileType 2), so that a thumbnail stored first is
/// not taken for the photo.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TiffPick {
    /// the picked IFD's offset
    pub offset: u64,
    /// IFD0's offset
    pub first: u64,
    /// its place in the chain (0 = IFD0)
    pub index: usize,
    /// how many full-resolution images the chain holds (pages)
    pub pages: usize,
    /// the file's byte order (little-endian)
    pub little_endian: bool,
}

/// Picks the image of a classic TIFF to decode ([`TiffPick`]), after
/// [`tiff_structure`] accepted the file. Err names what is not read: a
/// file whose every image is reduced (a raw camera file keeps its sensor
/// mosaic in a SubIFD behind a preview: named as raw), and 32-bit samples
/// that are not floats (the decoder would take their bits for floats).
/// Ok(None) for a BigTIFF or what is not a TIFF (the decoder's to name).
pub fn tiff_pick(src: &mut dyn Source) -> Result<Option<TiffPick>, String> {
    let (o, first) = header(src)?;
    if o.big {
        return Ok(None);
    }
    let (mut at, mut index, mut pages) = (first, 0usize, 0usize);
    let mut pick: Option<(u64, usize, Vec<Entry>)> = None;
    let mut seen = std::collections::HashSet::new();
    while at != 0 && index < MAX_FILE_IFDS && seen.insert(at) {
        let (list, next) = ifd(src, o, at)?;
        // a reduced-resolution image (bit 0) or a transparency mask (bit 2) is no photo
        let reduced = tag_integer(src, o, &list, 0x00FE).is_some_and(|v| v & 0b101 != 0)
            || tag_integer(src, o, &list, 0x00FF) == Some(2);
        if !reduced {
            pages += 1;
            if pick.is_none() {
                pick = Some((at, index, list));
            }
        }
        index += 1;
        at = next;
    }
    let Some((offset, index, list)) = pick else {
        // only previews: a raw camera file (DNG, NEF, ...) keeps its full
        // image in a SubIFD of IFD0, in the camera's own colours
        let (ifd0, _) = ifd(src, o, first)?;
        let subs = tag_integers(src, o, &ifd0, 0x014A, 64).unwrap_or_default();
        let raw = subs
            .iter()
            .any(|&sub| ifd(src, o, sub).ok().is_some_and(|(l, _)| tag_integer(src, o, &l, 0x00FE).unwrap_or(0) & 1 == 0));
        return Err(if raw {
            "a raw camera file (its full-resolution image is in a SubIFD, behind the preview a TIFF reader \
             sees): give it its raw extension (.nef, .dng, ...); the Python command reads raw files"
                .into()
        } else {
            "the file holds only reduced-resolution images (thumbnails: NewSubfileType 1)".into()
        });
    };
    // a sensor mosaic (CFA) or DNG's LinearRaw as the main image: a raw file
    if tag_integer(src, o, &list, 0x0106).is_some_and(|p| p == 32803 || p == 34892) {
        return Err("a raw camera file (its image is a sensor mosaic): give it its raw extension (.dng, .nef, ...); \
                    the Python command reads raw files"
            .into());
    }
    let bits = tag_integers(src, o, &list, 0x0102, 64).unwrap_or_default();
    let format = tag_integers(src, o, &list, 0x0153, 64).unwrap_or_default();
    if bits.contains(&32) && format.first().copied().unwrap_or(1) != 3 {
        let kind = if format.first() == Some(&2) { "signed" } else { "unsigned" };
        return Err(format!(
            "32-bit {kind} integer samples are not read: 8/16-bit integer and 32-bit float images are"
        ));
    }
    Ok(Some(TiffPick { offset, first, index, pages, little_endian: o.le }))
}

/// The IFD of an EXIF block an entry is in: IFD0's chain, or the Exif,
/// GPS or Interop sub-IFD.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    /// IFD0, IFD1 (the thumbnail's)
    Ifd0,
    /// the Exif sub-IFD (0x8769)
    Exif,
    /// the GPS sub-IFD (0x8825)
    Gps,
    /// the Interop sub-IFD (0xA005)
    Interop,
}

/// One entry as [`without_entries`] shows it to its rule.
#[derive(Debug)]
pub struct EntryView<'a> {
    /// the IFD it is in
    pub group: Group,
    /// its tag and TIFF type
    pub tag: u16,
    /// its TIFF type
    pub kind: u16,
    /// its first values, at most 64: integers of BYTE, SHORT and LONG,
    /// the bytes of ASCII and UNDEFINED; empty otherwise
    pub values: &'a [u64],
}

/// A copy of the classic-TIFF EXIF block `b` (one [`check`] accepts)
/// without the entries `drop` names, and their tags: each IFD's kept
/// entries moved up, its count and link after them, the bytes freed zeroed
/// (values stay where they are). A sub-IFD pointer typed IFD (13) is
/// written as LONG (4), the same four bytes, which some readers require.
/// None when nothing is to change (the block is not copied: it is a whole
/// TIFF file when the photo is one) or the block cannot be walked so. For a parser that refuses a
/// whole block for one entry of a type it does not expect (an Orientation
/// written as text cost a photo its time and position).
pub fn without_entries(b: &[u8], drop: &dyn Fn(&EntryView) -> bool) -> Option<(Vec<u8>, Vec<u16>)> {
    let mut src = b;
    let (o, ifd0) = header(&mut src).ok()?;
    if o.big {
        return None;
    }
    let mut out: Option<Vec<u8>> = None;
    let mut dropped = Vec::new();
    let mut seen = HashSet::new();
    let mut todo = vec![(ifd0, Group::Ifd0, true)];
    while let Some((at, group, chained)) = todo.pop() {
        if !seen.insert(at) || seen.len() > MAX_IFDS {
            return None;
        }
        let mut src = b;
        let (list, next) = ifd(&mut src, o, at).ok()?;
        let start = usize::try_from(at).ok()?;
        let mut kept = Vec::with_capacity(list.len() * 12);
        let mut retyped = false;
        for (k, e) in list.iter().enumerate() {
            let values = match e.kind {
                1 | 3 | 4 => integers(&mut src, o, e, 64).unwrap_or_default(),
                2 | 7 => value_bytes(&mut src, o, e, 1, e.count.min(64) as usize).unwrap_or_default().into_iter().map(u64::from).collect(),
                _ => Vec::new(),
            };
            if drop(&EntryView { group, tag: e.tag, kind: e.kind, values: &values }) {
                dropped.push(e.tag);
                continue;
            }
            let sub = match e.tag {
                0x8769 => Some(Group::Exif),
                0x8825 => Some(Group::Gps),
                0xA005 => Some(Group::Interop),
                _ => None,
            };
            if let (Some(g), true) = (sub, matches!(e.kind, 4 | 13)) {
                todo.push((o.offset(e.raw), g, false));
            }
            let at = kept.len();
            kept.extend_from_slice(b.get(start + 2 + 12 * k..start + 14 + 12 * k)?);
            if sub.is_some() && e.kind == 13 {
                let four = if o.le { 4u16.to_le_bytes() } else { 4u16.to_be_bytes() };
                kept.get_mut(at + 2..at + 4)?.copy_from_slice(&four);
                retyped = true;
            }
        }
        if chained && next != 0 {
            todo.push((next, group, true));
        }
        if kept.len() == 12 * list.len() && !retyped {
            continue;
        }
        let n = u16::try_from(kept.len() / 12).ok()?;
        let link = b.get(start + 2 + 12 * list.len()..start + 6 + 12 * list.len())?.to_vec();
        let dst = out.get_or_insert_with(|| b.to_vec()).get_mut(start..start + 6 + 12 * list.len())?;
        dst.fill(0);
        let count = if o.le { n.to_le_bytes() } else { n.to_be_bytes() };
        for (d, v) in dst.iter_mut().zip(count.iter().chain(&kept).chain(&link)) {
            *d = *v;
        }
    }
    out.map(|out| (out, dropped))
}

/// Whether every strip or tile table of a TIFF-based raw file (DNG, NEF,
/// CR2, ARW, ...) covers its image ([`covered`]; IFD0's chain and the
/// SubIFDs where a DNG keeps its raw image): Err with the reason when one
/// does not. Nothing else of the structure is judged: LibRaw reads raws
/// with a parser of its own, and a camera's odd tag must not cost the
/// photo. A file that is no TIFF is Ok.
pub fn raw_tables<R: Read + Seek>(r: &mut R) -> Result<(), String> {
    let mut src = ReaderSource::new(r).map_err(|e| e.to_string())?;
    if !is_tiff(&mut src) {
        return Ok(());
    }
    walk_as(&mut src, false, true, true).map(|_| ()).map_err(|m| m.replace("the EXIF image", "the raw image"))
}

/// How the pixels of a TIFF file's first image are laid out, from its
/// IFD0, in words (`2 samples per pixel (gray + alpha), 8 bits each`): what
/// a decoder that cannot read them names. None when IFD0 cannot be read.
pub fn tiff_layout(src: &mut dyn Source) -> Option<String> {
    let (o, ifd0) = header(src).ok()?;
    let (list, _) = ifd(src, o, ifd0).ok()?;
    let mut get = |tag: u16| tag_integers(src, o, &list, tag, 64);
    let samples = get(0x0115).and_then(|v| v.first().copied()).unwrap_or(1);
    let bits = get(0x0102).unwrap_or_else(|| vec![1]);
    let photometric = get(0x0106).and_then(|v| v.first().copied());
    let extra = get(0x0152).map_or(0, |v| v.len() as u64);
    let format = get(0x0153).and_then(|v| v.first().copied()).unwrap_or(1);
    let colour = match (photometric, samples.saturating_sub(extra)) {
        (Some(0 | 1), 1) => "gray",
        (Some(2), 3) => "RGB",
        (Some(3), 1) => "palette",
        (Some(5), 4) => "CMYK",
        (Some(6), 3) => "YCbCr",
        _ => "",
    };
    let what = match (colour, extra) {
        ("", _) => String::new(),
        (c, 0) => format!(" ({c})"),
        (c, 1) => format!(" ({c} + alpha)"),
        (c, n) => format!(" ({c} + {n} extra samples)"),
    };
    // a BitsPerSample of count 0 is an empty list (found by fuzz/decode_restore)
    let bits = match bits.first() {
        Some(first) if bits.iter().all(|b| b == first) => format!("{first} bits each"),
        _ => format!("{bits:?} bits"),
    };
    let kind = match format {
        2 => ", signed integers",
        3 => ", floating point",
        _ => "",
    };
    Some(format!("{samples} sample{} per pixel{what}, {bits}{kind}", if samples == 1 { "" } else { "s" }))
}

/// The Orientation of IFD0 (tag 0x0112), read by the rule of
/// [`orientation_of`]: Ok(None) without the tag, Err with the reason when
/// it is there but unusable.
pub fn exif_orientation(src: &mut dyn Source) -> Result<Option<u8>, String> {
    let (o, ifd0) = header(src)?;
    let (list, _) = ifd(src, o, ifd0)?;
    let Some(e) = list.iter().find(|e| e.tag == 0x0112) else { return Ok(None) };
    if !matches!(e.kind, 3 | 4) {
        return Err(format!("the EXIF Orientation has type {}, not SHORT or LONG", e.kind));
    }
    if e.count == 0 {
        return Err("the EXIF Orientation has no value".into());
    }
    // the first value only
    let size: u64 = if e.kind == 3 { 2 } else { 4 };
    let b = value_bytes(src, o, e, size, size as usize).ok_or("the EXIF Orientation's value is outside the block")?;
    let v = match b[..] {
        [b0, b1] => u32::from(o.u16([b0, b1])),
        [b0, b1, b2, b3] => o.u32([b0, b1, b2, b3]),
        _ => 0,
    };
    if (1..=8).contains(&v) {
        Ok(Some(v as u8))
    } else {
        Err(format!("the EXIF Orientation is {v}, not 1-8"))
    }
}

/// `tiff:Orientation` of an XMP packet, as an attribute (`tiff:Orientation="6"`)
/// or an element (`<tiff:Orientation>6</tiff:Orientation>`), the first one
/// written: Ok(None) without one, Err when its value is not one digit 1-8
/// or it is not closed.
pub fn xmp_orientation(xmp: &str) -> Result<Option<u8>, String> {
    let Some(at) = xmp.find("tiff:Orientation") else { return Ok(None) };
    let rest = &xmp[at + "tiff:Orientation".len()..];
    let value = if let Some(r) = rest.strip_prefix("=\"") {
        r.find('"').map(|e| &r[..e])
    } else if let Some(r) = rest.strip_prefix("='") {
        r.find('\'').map(|e| &r[..e])
    } else if let Some(r) = rest.strip_prefix('>') {
        r.find("</tiff:Orientation>").map(|e| &r[..e])
    } else {
        None
    };
    let Some(value) = value else { return Err("the XMP tiff:Orientation is malformed".into()) };
    match value.trim().parse::<u8>() {
        Ok(v) if (1..=8).contains(&v) => Ok(Some(v)),
        _ => Err(format!("the XMP tiff:Orientation {:?} is not 1-8", value.chars().take(20).collect::<String>())),
    }
}

/// What a container holds besides its pixels, each read with the limits
/// above (None: absent; Err: present but refused, with the reason).
#[derive(Debug, Default, Clone)]
pub struct Found {
    /// the first EXIF block, TIFF-structured (without `Exif\0\0`), unchecked
    pub exif: Option<Result<Vec<u8>, String>>,
    /// how many EXIF blocks the file has (JPEG APP1 `Exif`, PNG eXIf)
    pub exif_blocks: usize,
    /// the first XMP packet
    pub xmp: Option<Result<String, String>>,
    /// the ICC profile (JPEG: its APP2 chunks joined; PNG: iCCP inflated)
    pub icc: Option<Result<Vec<u8>, String>>,
    /// PNG: the gAMA chunk's value (gamma x 100000), whether an sRGB chunk
    /// is there, and the cICP chunk (primaries, transfer, matrix, full range)
    pub gamma: Option<u32>,
    /// see [`Found::gamma`]
    pub srgb: bool,
    /// see [`Found::gamma`]
    pub cicp: Option<[u8; 4]>,
    /// PNG: an animation control chunk (acTL): an APNG, of which the first frame is read
    pub animated: bool,
}

/// The header of an EXIF APP1 segment and, optionally, of a PNG eXIf chunk.
const EXIF_HEADER: &[u8] = b"Exif\0\0";
const XMP_JPEG_HEADER: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";
const ICC_JPEG_HEADER: &[u8] = b"ICC_PROFILE\0";

/// `data` inflated (zlib), refused past `cap` bytes.
pub fn inflate(data: &[u8], cap: u64, what: &str) -> Result<Vec<u8>, String> {
    let cap = usize::try_from(cap).unwrap_or(usize::MAX);
    match fdeflate::decompress_to_vec_bounded(data, cap) {
        Ok(v) => Ok(v),
        Err(fdeflate::BoundedDecompressionError::OutputTooLarge { .. }) => {
            Err(format!("the {what} inflates to more than {cap} bytes"))
        }
        Err(fdeflate::BoundedDecompressionError::DecompressionError { inner }) => {
            Err(format!("the {what} cannot be inflated ({inner:?})"))
        }
    }
}

/// Reads exactly `n` bytes at the reader's position, refusing more than `cap`.
fn take<R: Read>(r: &mut R, n: u64, cap: u64, what: &str) -> Result<Vec<u8>, String> {
    if n > cap {
        return Err(format!("the {what} is {n} bytes, over {cap}"));
    }
    let mut v = vec![0u8; n as usize];
    r.read_exact(&mut v).map_err(|e| format!("the {what} cannot be read ({e})"))?;
    Ok(v)
}

/// The segments of a JPEG (read through `r`) before its first scan: the
/// first EXIF and XMP APP1 segments, the ICC profile of the APP2 segments
/// (at most `icc_cap` bytes, chunks joined in their order numbers). Other
/// segments are skipped by seeking.
pub fn jpeg<R: Read + Seek>(r: &mut R, icc_cap: u64) -> Found {
    let mut f = Found::default();
    let mut icc: Vec<(u8, Vec<u8>)> = Vec::new();
    let mut icc_bytes = 0u64;
    let mut at = 2u64;
    let byte = |r: &mut R| -> Option<u8> {
        let mut b = [0u8; 1];
        r.read_exact(&mut b).ok().map(|_| b[0])
    };
    if r.seek(SeekFrom::Start(at)).is_err() {
        return f;
    }
    loop {
        if byte(r) != Some(0xFF) {
            break;
        }
        let mut marker = 0xFF;
        while marker == 0xFF {
            match byte(r) {
                Some(m) => marker = m,
                None => return finish(f, icc, icc_bytes, icc_cap),
            }
        }
        if marker == 0xD8 || marker == 0x01 || (0xD0..=0xD7).contains(&marker) {
            continue;
        }
        if marker == 0xDA || marker == 0xD9 {
            break;
        }
        let (Some(hi), Some(lo)) = (byte(r), byte(r)) else { break };
        let len = u64::from(u16::from_be_bytes([hi, lo]));
        if len < 2 {
            break;
        }
        at = match r.stream_position() {
            Ok(p) => p + len - 2,
            Err(_) => break,
        };
        if marker == 0xE1 || (marker == 0xE2 && icc_cap > 0) {
            let Ok(seg) = take(r, len - 2, 1 << 16, "segment") else { break };
            if marker == 0xE1 {
                if let Some(tiff) = seg.strip_prefix(EXIF_HEADER) {
                    f.exif_blocks += 1;
                    if f.exif.is_none() {
                        f.exif = Some(Ok(tiff.to_vec()));
                    }
                } else if let Some(x) = seg.strip_prefix(XMP_JPEG_HEADER) {
                    f.xmp.get_or_insert_with(|| Ok(String::from_utf8_lossy(x).into_owned()));
                }
            } else if let Some([seq, _, body @ ..]) = seg.strip_prefix(ICC_JPEG_HEADER) {
                // the chunk's sequence number and count, then its part of the profile
                icc_bytes += body.len() as u64;
                if icc_bytes <= icc_cap {
                    icc.push((*seq, body.to_vec()));
                }
            }
        }
        if r.seek(SeekFrom::Start(at)).is_err() {
            break;
        }
    }
    finish(f, icc, icc_bytes, icc_cap)
}

fn finish(mut f: Found, mut icc: Vec<(u8, Vec<u8>)>, icc_bytes: u64, icc_cap: u64) -> Found {
    if icc_bytes > 0 {
        f.icc = Some(if icc_bytes > icc_cap {
            Err(format!("the ICC profile is {icc_bytes} bytes, over {icc_cap}"))
        } else {
            icc.sort_by_key(|c| c.0);
            Ok(icc.into_iter().flat_map(|c| c.1).collect())
        });
    }
    f
}

/// The keyword of the text chunk that holds XMP in PNG.
const XMP_PNG_KEYWORD: &[u8] = b"XML:com.adobe.xmp";

/// The text of an iTXt chunk's data (keyword already removed), inflated
/// within `cap` when compressed.
fn itxt_text(rest: &[u8], cap: u64) -> Result<String, String> {
    let (compressed, text) = itxt_payload(rest).ok_or_else(|| "the XMP iTXt chunk is malformed".to_string())?;
    if compressed {
        Ok(String::from_utf8_lossy(&inflate(text, cap, "XMP iTXt chunk")?).into_owned())
    } else {
        Ok(String::from_utf8_lossy(text).into_owned())
    }
}

/// An iTXt chunk's data after its keyword's NUL: whether the text is
/// compressed, and the text's bytes (after the compression method, the
/// language tag and the translated keyword); None when a field is missing.
fn itxt_payload(rest: &[u8]) -> Option<(bool, &[u8])> {
    let (&compressed, rest) = rest.split_first()?;
    let rest = rest.get(1..)?;
    let lang = rest.iter().position(|&b| b == 0)?;
    let rest = rest.get(lang + 1..)?;
    let tr = rest.iter().position(|&b| b == 0)?;
    Some((compressed != 0, rest.get(tr + 1..)?))
}

/// The keyword of the text chunks in which ImageMagick (and others) keep
/// EXIF in PNG, as hexadecimal digits.
const RAW_EXIF_KEYWORD: &[u8] = b"Raw profile type exif";

/// The EXIF block of a "Raw profile type exif" text chunk (`data` after
/// the keyword's NUL): the text (inflated within [`MAX_BLOCK`] if
/// compressed) is a line naming the profile, a line with its length, and
/// hexadecimal digits; the block is returned without `Exif\0\0`.
fn raw_profile(kind: &[u8; 4], data: &[u8]) -> Result<Vec<u8>, String> {
    let bad = || "the raw EXIF text chunk is malformed".to_string();
    let text = match kind {
        b"tEXt" => data.to_vec(),
        b"zTXt" => inflate(data.get(1..).ok_or_else(bad)?, MAX_BLOCK * 2, "raw EXIF text chunk")?,
        _ => match itxt_payload(data).ok_or_else(bad)? {
            (true, t) => inflate(t, MAX_BLOCK * 2, "raw EXIF text chunk")?,
            (false, t) => t.to_vec(),
        },
    };
    // "\nexif\n   1234\n" then the digits
    let mut lines = 0;
    let start = text.iter().position(|&b| {
        lines += usize::from(b == b'\n');
        lines == 3
    });
    let digits = text.get(start.ok_or_else(bad)? + 1..).ok_or_else(bad)?;
    let hex = |b: u8| (b as char).to_digit(16).map(|d| d as u8);
    let nibbles: Vec<u8> = digits.iter().filter(|b| !b.is_ascii_whitespace()).map(|&b| hex(b).ok_or_else(bad)).collect::<Result<_, _>>()?;
    let mut block: Vec<u8> = nibbles.as_chunks::<2>().0.iter().map(|&[hi, lo]| hi << 4 | lo).collect();
    if block.starts_with(EXIF_HEADER) {
        block.drain(..EXIF_HEADER.len());
    }
    Ok(block)
}

/// The chunks of a PNG read through `r` (positioned anywhere; the
/// signature is checked): the first eXIf, the first XMP iTXt, and iCCP
/// inflated within `icc_cap`. Chunks are skipped by seeking, never read
/// whole unless they are one of these and under [`MAX_BLOCK`]. Also
/// returns where the metadata chunks (iCCP, eXIf, tEXt, zTXt, iTXt) lie in
/// the file (offset and length of each whole chunk, in order) so that the
/// pixel decoder can be kept from inflating or holding them.
pub fn png<R: Read + Seek>(r: &mut R, icc_cap: u64) -> (Found, Vec<(u64, u64)>) {
    let mut f = Found::default();
    let mut holes = Vec::new();
    let mut sig = [0u8; 8];
    if r.seek(SeekFrom::Start(0)).is_err() || r.read_exact(&mut sig).is_err() || &sig != b"\x89PNG\r\n\x1a\n" {
        return (f, holes);
    }
    let mut at = 8u64;
    let mut raw_exif = None;
    let mut pixels = false;
    loop {
        let mut h = [0u8; 8];
        if r.seek(SeekFrom::Start(at)).is_err() || r.read_exact(&mut h).is_err() {
            break;
        }
        let len = u64::from(u32::from_be_bytes([h[0], h[1], h[2], h[3]]));
        let kind = [h[4], h[5], h[6], h[7]];
        if matches!(&kind, b"iCCP" | b"eXIf" | b"tEXt" | b"zTXt" | b"iTXt") {
            holes.push((at, len.saturating_add(12)));
        }
        match &kind {
            b"IEND" => break,
            b"IDAT" => pixels = true,
            // the reader stands at the chunk's data; colour chunks count before the pixel data only (the PNG rule)
            b"gAMA" if len == 4 && f.gamma.is_none() && !pixels => {
                let mut g = [0u8; 4];
                f.gamma = r.read_exact(&mut g).ok().map(|()| u32::from_be_bytes(g));
            }
            b"cICP" if len == 4 && f.cicp.is_none() && !pixels => {
                let mut c = [0u8; 4];
                f.cicp = r.read_exact(&mut c).ok().map(|()| c);
            }
            b"sRGB" if !pixels => f.srgb = true,
            b"acTL" if !pixels => f.animated = true,
            b"eXIf" => {
                f.exif_blocks += 1;
                if f.exif.is_none() {
                    f.exif = Some(take(r, len, MAX_BLOCK, "EXIF chunk").map(|mut v| {
                        if v.starts_with(EXIF_HEADER) {
                            v.drain(..EXIF_HEADER.len());
                        }
                        v
                    }));
                }
            }
            b"iCCP" if f.icc.is_none() => {
                // the compressed profile is smaller than the inflated cap (deflate cannot beat 1032:1)
                f.icc = Some(take(r, len, icc_cap.max(1 << 16), "ICC chunk").and_then(|d| {
                    let name = d.iter().position(|&b| b == 0).filter(|&n| (1..80).contains(&n));
                    // the name's NUL, then the compression method (0: deflate) and the profile
                    match name.and_then(|n| d.get(n + 1..)).and_then(|rest| rest.split_first()) {
                        Some((0, profile)) => inflate(profile, icc_cap, "ICC profile"),
                        _ => Err("the iCCP chunk is malformed".into()),
                    }
                }));
            }
            b"tEXt" | b"zTXt" | b"iTXt" => {
                let mut key = vec![0u8; len.min(80) as usize];
                let Some(end) = r.read_exact(&mut key).ok().and_then(|_| key.iter().position(|&b| b == 0)) else {
                    at = at.saturating_add(len).saturating_add(12);
                    continue;
                };
                let keyword = key.get(..end).unwrap_or_default();
                let mut rest = || -> Result<Vec<u8>, String> {
                    let _ = r.seek(SeekFrom::Start(at + 8 + end as u64 + 1));
                    take(r, len - end as u64 - 1, MAX_BLOCK, "text chunk")
                };
                if keyword == XMP_PNG_KEYWORD && &kind == b"iTXt" && f.xmp.is_none() {
                    f.xmp = Some(rest().and_then(|d| itxt_text(&d, MAX_BLOCK)));
                } else if keyword == RAW_EXIF_KEYWORD && raw_exif.is_none() {
                    raw_exif = Some(rest().and_then(|d| raw_profile(&kind, &d)));
                }
            }
            _ => {}
        }
        at = at.saturating_add(len).saturating_add(12);
    }
    if f.exif.is_none() && raw_exif.is_some() {
        f.exif = raw_exif;
        f.exif_blocks += 1;
    }
    (f, holes)
}

/// The container's metadata blocks read from `r` (by its first bytes):
/// JPEG segments, PNG chunks; for a TIFF file the file is its own EXIF
/// block and is not copied (`exif` stays None, `exif_blocks` is 1).
pub fn scan<R: Read + Seek>(r: &mut R, icc_cap: u64) -> Found {
    let mut sig = [0u8; 8];
    let n = r.seek(SeekFrom::Start(0)).and_then(|_| r.read(&mut sig)).unwrap_or(0);
    let sig = sig.get(..n).unwrap_or_default();
    if sig.starts_with(&[0xFF, 0xD8]) {
        jpeg(r, icc_cap)
    } else if sig.starts_with(b"\x89PNG") {
        png(r, icc_cap).0
    } else if sig.starts_with(b"II*\0") || sig.starts_with(b"MM\0*") {
        Found { exif_blocks: 1, ..Found::default() }
    } else {
        Found::default()
    }
}

/// The XMP packet of a TIFF file (tag 700 of IFD0), within [`MAX_BLOCK`].
fn tiff_xmp(src: &mut dyn Source) -> Result<Option<String>, String> {
    let (o, ifd0) = header(src)?;
    let (list, _) = ifd(src, o, ifd0)?;
    let Some(e) = list.iter().find(|e| e.tag == 700) else { return Ok(None) };
    let size = type_size(e.kind).unwrap_or(1);
    let n = e.count.saturating_mul(size);
    if n > MAX_BLOCK {
        return Err(format!("the XMP packet is {n} bytes, over {MAX_BLOCK}"));
    }
    let v = value_bytes(src, o, e, size, n as usize).ok_or("the XMP packet is outside the file")?;
    Ok(Some(String::from_utf8_lossy(&v).into_owned()))
}

/// The orientation of a photo (1-8, EXIF's codes) and a note when
/// something was ignored, the one rule for both commands:
///
/// 1. the first EXIF block (JPEG: the first APP1 `Exif` segment; PNG: the
///    first eXIf chunk; TIFF: the file's IFD0): its IFD0 Orientation tag,
///    of type SHORT or LONG, count 1 or more, first value 1-8;
/// 2. else the XMP packet's `tiff:Orientation`, if well-formed (one value
///    1-8, attribute or element);
/// 3. else 1 (upright).
///
/// An Orientation present but unusable in either place, or a second EXIF
/// block, is named in the note.
pub fn orientation_from<R: Read + Seek>(r: &mut R) -> (u8, Option<String>) {
    let mut notes = Vec::new();
    let mut sig = [0u8; 4];
    let n = r.seek(SeekFrom::Start(0)).and_then(|_| r.read(&mut sig)).unwrap_or(0);
    let is_tiff = n == 4 && (&sig == b"II*\0" || &sig == b"MM\0*");
    let (exif, xmp) = if is_tiff {
        match ReaderSource::new(r) {
            Ok(mut src) => (Some(exif_orientation(&mut src)), tiff_xmp(&mut src).transpose()),
            Err(e) => (Some(Err(format!("the file cannot be read ({e})"))), None),
        }
    } else {
        let found = scan(r, 0);
        if found.exif_blocks > 1 {
            notes.push(format!("{} EXIF blocks; the first one is read", found.exif_blocks));
        }
        let exif = found.exif.map(|b| b.and_then(|b| exif_orientation(&mut b.as_slice())));
        (exif, found.xmp)
    };
    let _ = r.seek(SeekFrom::Start(0));
    let mut pick = |v: Option<Result<Option<u8>, String>>| match v {
        Some(Ok(Some(o))) => Some(o),
        Some(Err(e)) => {
            notes.push(e);
            None
        }
        _ => None,
    };
    let code = pick(exif)
        .or_else(|| pick(xmp.map(|x| x.and_then(|x| xmp_orientation(&x)))))
        .unwrap_or(1);
    let note = (!notes.is_empty()).then(|| format!("orientation: {} (read as {code})", notes.join("; ")));
    (code, note)
}

/// [`orientation_from`] over a whole file held in memory.
pub fn orientation_of(bytes: &[u8]) -> (u8, Option<String>) {
    orientation_from(&mut std::io::Cursor::new(bytes))
}

/// The bodies of the metadata fuzz targets (`fuzz/fuzz_targets/meta_*.rs`)
/// and of their replay in `tests/fuzz_regressions.rs`: each reader is
/// given arbitrary bytes and must return, never panic, hang or allocate
/// past its limits (libFuzzer's `-rss_limit_mb` and `-timeout` catch those).
#[cfg(any(test, feature = "internals"))]
pub mod fuzzing {
    use super::*;

    /// An EXIF block: the validator and the orientation reader.
    pub fn exif(data: &[u8]) {
        let _ = check(&mut &data[..]);
        let _ = exif_orientation(&mut &data[..]);
        let _ = tiff_xmp(&mut &data[..]);
    }

    /// An XMP packet: its orientation, and the output packet made from it.
    pub fn xmp(data: &[u8]) {
        let text = String::from_utf8_lossy(data).into_owned();
        let _ = xmp_orientation(&text);
        let c = crate::files::metadata::Carried { xmp: Some(text), ..Default::default() };
        let _ = crate::files::metadata::output_xmp(&c, &vec![("WaterType", "3C".into())]);
    }

    /// An ICC profile: classified, and applied to a few pixels when it is
    /// one the decoder would apply.
    pub fn icc(data: &[u8]) {
        if let crate::files::icc::Profile::Other(_) = crate::files::icc::classify(data) {
            let mut v = vec![0.0, 0.5, 1.0, 0.25, 0.75, 0.1];
            let _ = crate::files::icc::convert(data, &mut v, true);
        }
    }

    /// A whole file: its JPEG segments or PNG chunks, and the orientation rule.
    pub fn container(data: &[u8]) {
        let _ = scan(&mut std::io::Cursor::new(data), MAX_BLOCK);
        let _ = png(&mut std::io::Cursor::new(data), 1 << 20);
        let _ = orientation_of(data);
    }

    /// A whole file's metadata carried into a small encoded photo.
    pub fn carry(data: &[u8]) {
        let side = serde_json::json!({"water_type": "3C", "parameters": {}});
        let _ = crate::files::metadata::carry(data.to_vec(), tiny_png(), &side, "x.json", 1, 1);
    }

    /// A 1 x 1 RGB PNG, framed by hand (the output side of [`carry`]).
    fn tiny_png() -> Vec<u8> {
        let chunk = |out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]| {
            out.extend((data.len() as u32).to_be_bytes());
            let mut kd = kind.to_vec();
            kd.extend(data);
            let mut c = !0u32;
            for &b in &kd {
                c ^= u32::from(b);
                for _ in 0..8 {
                    c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
                }
            }
            out.extend(&kd);
            out.extend((!c).to_be_bytes());
        };
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        chunk(&mut out, b"IHDR", &[0, 0, 0, 1, 0, 0, 0, 1, 8, 2, 0, 0, 0]);
        chunk(&mut out, b"IDAT", &fdeflate::compress_to_vec(&[0, 10, 20, 30]));
        chunk(&mut out, b"IEND", &[]);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A little- or big-endian TIFF block with one IFD0 of `entries`
    /// (tag, type, count, 4 value bytes), its link `next`, then `tail`.
    pub(crate) fn tiff(le: bool, entries: &[(u16, u16, u32, [u8; 4])], next: u32, tail: &[u8]) -> Vec<u8> {
        let wide: Vec<_> = entries.iter().map(|&(t, k, c, v)| (t, k, u64::from(c), v)).collect();
        ifd_file(le, &wide, u64::from(next), tail)
    }

    /// One IFD after a classic TIFF header (value fields of 4 bytes: counts
    /// and links of 4) or a BigTIFF one (of 8: counts and links of 8).
    fn ifd_file<const N: usize>(le: bool, entries: &[(u16, u16, u64, [u8; N])], next: u64, tail: &[u8]) -> Vec<u8> {
        let u16b = |v: u16| if le { v.to_le_bytes() } else { v.to_be_bytes() };
        // a count or link: 4 bytes in classic TIFF, 8 in BigTIFF
        let word = |v: u64| {
            let b = if le { v.to_le_bytes() } else { v.to_be_bytes() };
            if N == 8 { b.to_vec() } else if le { b[..4].to_vec() } else { b[4..].to_vec() }
        };
        let mut b = if le { b"II".to_vec() } else { b"MM".to_vec() };
        if N == 8 {
            b.extend(u16b(43));
            b.extend(u16b(8));
            b.extend(u16b(0));
            b.extend(word(16));
            b.extend(word(entries.len() as u64));
        } else {
            b.extend(u16b(42));
            b.extend(word(8));
            b.extend(u16b(entries.len() as u16));
        }
        for &(t, k, c, v) in entries {
            b.extend(u16b(t));
            b.extend(u16b(k));
            b.extend(word(c));
            b.extend(v);
        }
        b.extend(word(next));
        b.extend(tail);
        b
    }

    fn short(v: u16, le: bool) -> [u8; 4] {
        let b = if le { v.to_le_bytes() } else { v.to_be_bytes() };
        [b[0], b[1], 0, 0]
    }

    #[test]
    fn a_tiff_file_whose_tag_counts_pass_its_end_is_refused_before_a_decoder() {
        // ImageWidth typed ASCII with a count of nearly 4 GiB: the `tiff` crate's dbg! case
        let b = tiff(true, &[(0x0100, 2, 0xFFFF_FF00, [0; 4])], 0, &[]);
        let why = tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err();
        assert!(why.contains("TIFF tag 0x0100") && why.contains("outside the file") && !why.contains("EXIF"), "{why}");
        let ok = tiff(false, &[(0x0100, 3, 1, short(6, false))], 0, &[]);
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(ok)), Ok(()));
        // neither TIFF nor BigTIFF: the decoder's to name
        let mut other = tiff(true, &[(0x0100, 2, 0xFFFF_FF00, [0; 4])], 0, &[]);
        other[2] = 44;
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(other)), Ok(()));
    }

    /// A BigTIFF (magic 43, offset size 8) with one IFD at 16 of 20-byte
    /// entries `(tag, type, count, value field)`, its next-IFD link, then `tail`.
    fn bigtiff(le: bool, entries: &[(u16, u16, u64, [u8; 8])], next: u64, tail: &[u8]) -> Vec<u8> {
        ifd_file(le, entries, next, tail)
    }

    #[test]
    fn a_bigtiff_is_walked_with_eight_byte_counts_and_offsets() {
        let le8 = |v: u64| v.to_le_bytes();
        let be8 = |v: u64| v.to_be_bytes();
        // the dbg! case in BigTIFF: an ASCII count far past the file
        let b = bigtiff(true, &[(0x0100, 2, 0xFFFF_FFFF_FF00, [0; 8])], 0, &[]);
        let why = tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err();
        assert!(why.contains("TIFF tag 0x0100") && why.contains("outside the file"), "{why}");
        // a count whose size overflows 64 bits is outside too, not a wrap to a small number
        let b = bigtiff(false, &[(0x0100, 16, u64::MAX / 4, [0; 8])], 0, &[]);
        assert!(tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err().contains("outside the file"));
        // a value of 8 bytes stays in the entry; 9 bytes go to the offset, which must be inside
        let inline = bigtiff(true, &[(0x010E, 2, 8, *b"abcdefg\0")], 0, &[]);
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(inline)), Ok(()));
        let outside = bigtiff(true, &[(0x010E, 2, 9, le8(4000))], 0, &[]);
        assert!(tiff_structure(&mut std::io::Cursor::new(outside)).unwrap_err().contains("outside the file"));
        // the next-IFD link (8 bytes) back to IFD0, big-endian: a loop
        let b = bigtiff(false, &[(0x0100, 3, 1, [0, 6, 0, 0, 0, 0, 0, 0])], 16, &[]);
        assert!(tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err().contains("loop"));
        // an IFD8 sub-IFD pointing back at IFD0
        let b = bigtiff(false, &[(0x8769, 18, 1, be8(16))], 0, &[]);
        assert!(tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err().contains("loop"));
        // an entry count of 2^40 is refused before anything that size is allocated
        let mut b = bigtiff(true, &[], 0, &[]);
        b[16..24].copy_from_slice(&le8(1 << 40));
        assert!(tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err().contains("over 8192"));
        // a header that says offset size 4 is not BigTIFF
        let mut b = bigtiff(true, &[], 0, &[]);
        b[4] = 4;
        assert!(tiff_structure(&mut std::io::Cursor::new(b)).unwrap_err().contains("BigTIFF header"));
        // an EXIF block must be classic TIFF, whatever it holds
        let b = bigtiff(true, &[(0x0112, 3, 1, [1, 0, 0, 0, 0, 0, 0, 0])], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("BigTIFF"));
    }

    #[test]
    fn a_bigtiff_written_by_the_tiff_crate_passes_and_keeps_its_values() {
        let mut f = std::io::Cursor::new(Vec::new());
        let data: Vec<f32> = (0..40 * 30).map(|i| i as f32 * 0.01).collect();
        tiff::encoder::TiffEncoder::new_big(&mut f)
            .unwrap()
            .write_image::<tiff::encoder::colortype::Gray32Float>(40, 30, &data)
            .unwrap();
        let bytes = f.into_inner();
        assert_eq!(&bytes[..4], b"II+\0");
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(&bytes)), Ok(()));
        // IFD0's ImageWidth, read through the 8-byte layout
        let mut src = bytes.as_slice();
        let (o, at) = header(&mut src).unwrap();
        let (list, next) = ifd(&mut src, o, at).unwrap();
        let width = list.iter().find(|e| e.tag == 0x0100).unwrap();
        assert_eq!(integers(&mut src, o, width, 1).unwrap(), vec![40]);
        assert_eq!(next, 0);
        // cut short by 8 bytes (its IFD or its strips), the walk with the data checked fails
        assert!(walk(&mut &bytes[..bytes.len() - 8], true, true).is_err());
    }

    #[test]
    fn a_strip_or_tile_table_must_cover_its_image() {
        let long = |v: u32| v.to_le_bytes();
        // 64 x 64 in tiles of 32 x 32: four tiles; the table (inline: 2 LONGs do not fit, so at 200) lists two
        let tiles = |n: u32| {
            let e = [(0x0100, 4, 1, long(64)), (0x0101, 4, 1, long(64)), (0x0142, 4, 1, long(32)), (0x0143, 4, 1, long(32)),
                (0x0144, 4, n, long(if n == 1 { 8 } else { 120 })), (0x0145, 4, n, long(if n == 1 { 8 } else { 120 }))];
            let mut b = tiff(true, &e, 0, &[]);
            b.resize(200, 0);
            b
        };
        let why = tiff_structure(&mut std::io::Cursor::new(tiles(2))).unwrap_err();
        assert_eq!(why, "the TIFF image of 64 x 64 pixels needs 4 tiles, and its table lists 2");
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(tiles(4))), Ok(()));
        // strips: RowsPerStrip 16 of 64 rows needs 4, one without RowsPerStrip; planar RGB needs 3 x as many
        let strips = |rows: Option<u32>, planar: bool, n: u32| {
            let mut e = vec![(0x0100, 4, 1, long(8)), (0x0101, 4, 1, long(64)), (0x0115, 3, 1, short(3, true)),
                (0x0111, 4, n, long(120)), (0x0117, 4, n, long(120))];
            if let Some(r) = rows {
                e.push((0x0116, 4, 1, long(r)));
            }
            if planar {
                e.push((0x011C, 3, 1, short(2, true)));
            }
            let mut b = tiff(true, &e, 0, &[]);
            b.resize(200, 0);
            tiff_structure(&mut std::io::Cursor::new(b))
        };
        assert_eq!(strips(Some(16), false, 4), Ok(()));
        assert!(strips(Some(16), false, 3).unwrap_err().ends_with("needs 4 strips, and its table lists 3"));
        assert_eq!(strips(None, false, 1), Ok(()));
        assert_eq!(strips(Some(1000), false, 1), Ok(()));
        assert!(strips(Some(16), true, 4).unwrap_err().ends_with("needs 12 strips, and its table lists 4"));
        // an EXIF block is not judged so (its IFD1 describes a thumbnail, not this block's image)
        let mut b = tiff(true, &[(0x0100, 4, 1, long(64)), (0x0101, 4, 1, long(64)), (0x0116, 4, 1, long(1)),
            (0x0111, 4, 1, long(8)), (0x0117, 4, 1, long(8))], 0, &[]);
        b.resize(200, 0);
        assert!(check(&mut b.as_slice()).is_ok());
    }

    #[test]
    fn entries_are_dropped_from_a_copy_and_the_rest_kept() {
        // IFD0: Orientation as text, Make; its Exif sub-IFD: DateTimeOriginal
        for le in [true, false] {
            let u32b = |v: u32| if le { v.to_le_bytes() } else { v.to_be_bytes() };
            let n = 8 + 2 + 12 * 3 + 4;
            let u16b = |v: u16| if le { v.to_le_bytes() } else { v.to_be_bytes() };
            // the Exif sub-IFD at n: one entry (DateTimeOriginal, 20 bytes at n + 18), its link, the text
            let mut tail = u16b(1).to_vec();
            tail.extend(u16b(0x9003));
            tail.extend(u16b(2));
            tail.extend(u32b(20));
            tail.extend(u32b(n as u32 + 18));
            tail.extend(u32b(0));
            tail.extend(b"2026:01:02 03:04:05\0");
            let b = tiff(le, &[(0x010F, 2, 4, *b"Can\0"), (0x0112, 2, 2, *b"6\0\0\0"), (0x8769, 4, 1, u32b(n as u32))], 0, &tail);
            assert!(check(&mut b.as_slice()).is_ok());
            let (c, gone) = without_entries(&b, &|e| e.group == Group::Ifd0 && e.tag == 0x0112 && e.kind != 3).unwrap();
            assert_eq!(gone, vec![0x0112]);
            assert_eq!(c.len(), b.len());
            let walked = check(&mut c.as_slice()).unwrap();
            assert_eq!(walked, Walked { ifds: 2, entries: 3 });
            let mut src = c.as_slice();
            let (o, at) = header(&mut src).unwrap();
            let (list, _) = ifd(&mut src, o, at).unwrap();
            assert_eq!(list.iter().map(|e| e.tag).collect::<Vec<_>>(), vec![0x010F, 0x8769]);
            // nothing named: nothing to change, and no copy
            assert_eq!(without_entries(&b, &|_| false), None);
            // the rule sees the values: the text "6" of the Orientation
            let (_, gone) = without_entries(&b, &|e| e.tag == 0x0112 && e.values == [u64::from(b'6'), 0]).unwrap();
            assert_eq!(gone, vec![0x0112]);
            // an Exif pointer typed IFD (13) is written as LONG, its sub-IFD kept
            let mut t13 = b.clone();
            let at = 8 + 2 + 2 * 12 + 2;
            t13[at..at + 2].copy_from_slice(&if le { 13u16.to_le_bytes() } else { 13u16.to_be_bytes() });
            let (c, gone) = without_entries(&t13, &|_| false).unwrap();
            assert!(gone.is_empty());
            assert_eq!(c, b, "the pointer retyped");
        }
    }

    #[test]
    fn sub_ifd_offsets_count_against_the_limit_as_they_are_queued() {
        // 8 entries of 0x014A, each listing 4096 offsets to one IFD: 32768
        // queued before one is taken, unless they count when queued
        let n = 8 + 2 + 8 * 12 + 4;
        let list: Vec<u8> = (0..4096u32).flat_map(|_| (n as u32 + 4096 * 4).to_le_bytes()).collect();
        let entries: Vec<_> = (0..8).map(|_| (0x014A, 4, 4096, (n as u32).to_le_bytes())).collect();
        let mut tail = list;
        tail.extend([0u8; 6]);
        let b = tiff(true, &entries, 0, &tail);
        let why = tiff_structure(&mut std::io::Cursor::new(&b)).unwrap_err();
        assert!(why.contains("more than 4096 IFDs"), "{why}");
        // the lenient walk of a raw stops at the limit too, without an error
        assert_eq!(raw_tables(&mut std::io::Cursor::new(&b)), Ok(()));
    }

    #[test]
    fn a_raw_is_judged_by_its_tables_only() {
        let long = |v: u32| v.to_le_bytes();
        // a camera's tag of an unknown type and a value past the end: a strict walk refuses, a raw's does not
        let odd = |strips: u32| {
            let mut b = tiff(true, &[(0x0100, 4, 1, long(8)), (0x0101, 4, 1, long(64)), (0x0116, 4, 1, long(16)),
                (0x0111, 4, strips, long(120)), (0x0117, 4, strips, long(120)), (0xC000, 99, 1, long(0)),
                (0xC001, 7, 5000, long(100))], 0, &[]);
            b.resize(200, 0);
            b
        };
        assert!(tiff_structure(&mut std::io::Cursor::new(odd(4))).is_err());
        assert_eq!(raw_tables(&mut std::io::Cursor::new(odd(4))), Ok(()));
        // its table short of its size is refused all the same
        let why = raw_tables(&mut std::io::Cursor::new(odd(3))).unwrap_err();
        assert_eq!(why, "the raw image of 8 x 64 pixels needs 4 strips, and its table lists 3");
        // a loop, an IFD past the end, a header cut short: nothing to judge
        let b = tiff(true, &[(0x0112, 3, 1, short(1, true))], 8, &[]);
        assert_eq!(raw_tables(&mut std::io::Cursor::new(b)), Ok(()));
        let b = tiff(true, &[(0x8769, 4, 1, long(90_000))], 0, &[]);
        assert_eq!(raw_tables(&mut std::io::Cursor::new(b)), Ok(()));
        assert_eq!(raw_tables(&mut std::io::Cursor::new(b"II+\0\x04\0".to_vec())), Ok(()));
        assert_eq!(raw_tables(&mut std::io::Cursor::new(b"not a tiff".to_vec())), Ok(()));
    }

    #[test]
    fn a_layout_without_bits_per_sample_values_is_said_not_a_panic() {
        // BitsPerSample (0x0102) typed SHORT with a count of 0
        let b = tiff(true, &[(0x0102, 3, 0, [0; 4]), (0x0115, 3, 1, short(3, true))], 0, &[]);
        assert_eq!(tiff_layout(&mut b.as_slice()).as_deref(), Some("3 samples per pixel, [] bits"));
    }

    #[test]
    fn a_valid_block_is_walked() {
        let b = tiff(true, &[(0x0112, 3, 1, short(6, true))], 0, &[]);
        assert_eq!(check(&mut b.as_slice()), Ok(Walked { ifds: 1, entries: 1 }));
    }

    #[test]
    fn loops_are_found_in_the_chain_and_through_sub_ifds() {
        // next-IFD link to itself
        let b = tiff(true, &[(0x0112, 3, 1, short(1, true))], 8, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("loop"));
        // the Exif sub-IFD pointing back at IFD0, big-endian
        let b = tiff(false, &[(0x8769, 4, 1, 8u32.to_be_bytes())], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("loop"));
        // two IFDs linking to each other: 8 -> 26 -> 8
        let mut b = tiff(true, &[(0x0100, 3, 1, short(1, true))], 26, &[]);
        b.extend(1u16.to_le_bytes());
        b.extend([0x01, 0x01, 3, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
        b.extend(8u32.to_le_bytes());
        assert_eq!(b.len(), 26 + 18);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("loop"));
    }

    #[test]
    fn counts_sizes_and_offsets_are_bounded() {
        // a value of 4 G bytes
        let b = tiff(true, &[(0x010F, 2, u32::MAX, 100u32.to_le_bytes())], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("outside"));
        // an IFD offset past the end
        let mut b = tiff(true, &[], 0, &[]);
        b[4..8].copy_from_slice(&1000u32.to_le_bytes());
        assert!(check(&mut b.as_slice()).unwrap_err().contains("outside"));
        // an unknown type
        let b = tiff(true, &[(0x010F, 99, 1, [0; 4])], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("unknown type"));
        // strips larger than the block, and a thumbnail past its end
        let b = tiff(true, &[(0x0111, 4, 1, 0u32.to_le_bytes()), (0x0117, 4, 1, 4_000_000_000u32.to_le_bytes())], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("image data"));
        let b = tiff(true, &[(0x0201, 4, 1, 20u32.to_le_bytes()), (0x0202, 4, 1, 30u32.to_le_bytes())], 0, &[]);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("image data"));
        // many values all pointing at the same bytes: inside, but over the total
        let tail = vec![b'a'; 1 << 16];
        let entries: Vec<_> = (0..300u16).map(|t| (0x9000 + t, 7, 1 << 16, (8 + 2 + 300 * 12 + 4u32).to_le_bytes())).collect();
        let b = tiff(true, &entries, 0, &tail);
        assert!(check(&mut b.as_slice()).unwrap_err().contains("add up"));
        // a chain of more IFDs than allowed, each a new offset
        let mut b = b"II*\0".to_vec();
        b.extend(8u32.to_le_bytes());
        for i in 0..(MAX_IFDS as u32 + 1) {
            b.extend(0u16.to_le_bytes());
            b.extend((8 + 6 * (i + 1)).to_le_bytes());
        }
        assert!(check(&mut b.as_slice()).unwrap_err().contains("IFDs"));
        // a whole file may hold a multi-page chain or a pyramid that long: its own, larger limit
        let chain = |n: u32| {
            let mut b = b"II*\0".to_vec();
            b.extend(8u32.to_le_bytes());
            for i in 0..n {
                b.extend(0u16.to_le_bytes());
                b.extend((if i + 1 == n { 0 } else { 8 + 6 * (i + 1) }).to_le_bytes());
            }
            b
        };
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(chain(MAX_IFDS as u32 + 1))), Ok(()));
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(chain(MAX_FILE_IFDS as u32))), Ok(()));
        let why = tiff_structure(&mut std::io::Cursor::new(chain(MAX_FILE_IFDS as u32 + 1)));
        assert_eq!(why, Err("the file has more than 4096 IFDs".to_string()));
        // an offset outside, said of a file
        let mut b = chain(3);
        b.truncate(b.len() - 6);
        assert_eq!(tiff_structure(&mut std::io::Cursor::new(b)), Err("a TIFF IFD offset (20) is outside the file".to_string()));
    }

    #[test]
    fn exif_orientation_takes_short_or_long_and_the_first_value() {
        for le in [true, false] {
            let u32b = |v: u32| if le { v.to_le_bytes() } else { v.to_be_bytes() };
            let b = tiff(le, &[(0x0112, 3, 1, short(6, le))], 0, &[]);
            assert_eq!(exif_orientation(&mut b.as_slice()), Ok(Some(6)));
            let b = tiff(le, &[(0x0112, 4, 1, u32b(8))], 0, &[]);
            assert_eq!(exif_orientation(&mut b.as_slice()), Ok(Some(8)));
            // SHORT count 2: both inline, the first taken
            let two = if le { [3, 0, 5, 0] } else { [0, 3, 0, 5] };
            let b = tiff(le, &[(0x0112, 3, 2, two)], 0, &[]);
            assert_eq!(exif_orientation(&mut b.as_slice()), Ok(Some(3)));
            // LONG count 2: out of line, at 8 + 2 + 12 + 4 = 26
            let mut tail = u32b(7).to_vec();
            tail.extend(u32b(2));
            let b = tiff(le, &[(0x0112, 4, 2, u32b(26))], 0, &tail);
            assert_eq!(exif_orientation(&mut b.as_slice()), Ok(Some(7)));
            let b = tiff(le, &[(0x0112, 3, 1, short(9, le))], 0, &[]);
            assert!(exif_orientation(&mut b.as_slice()).unwrap_err().contains("not 1-8"));
            let b = tiff(le, &[(0x0112, 2, 1, [b'6', 0, 0, 0])], 0, &[]);
            assert!(exif_orientation(&mut b.as_slice()).is_err());
            let b = tiff(le, &[(0x0112, 3, 0, [0; 4])], 0, &[]);
            assert!(exif_orientation(&mut b.as_slice()).is_err());
            let b = tiff(le, &[(0x010F, 2, 1, [0; 4])], 0, &[]);
            assert_eq!(exif_orientation(&mut b.as_slice()), Ok(None));
        }
    }

    #[test]
    fn xmp_orientation_is_read_when_well_formed() {
        assert_eq!(xmp_orientation("<rdf:Description tiff:Orientation=\"6\"/>"), Ok(Some(6)));
        assert_eq!(xmp_orientation("<rdf:Description tiff:Orientation='3'/>"), Ok(Some(3)));
        assert_eq!(xmp_orientation("<tiff:Orientation> 8 </tiff:Orientation>"), Ok(Some(8)));
        assert_eq!(xmp_orientation("<x:xmpmeta/>"), Ok(None));
        assert!(xmp_orientation("<tiff:Orientation>6").is_err());
        assert!(xmp_orientation("tiff:Orientation=\"6").is_err());
        assert!(xmp_orientation("tiff:Orientation=\"66\"").is_err());
        assert!(xmp_orientation("tiff:Orientation=\"0\"").is_err());
        assert!(xmp_orientation("tiff:Orientation=6").is_err());
    }

    fn jpeg_of(segments: &[(u8, Vec<u8>)]) -> Vec<u8> {
        let mut j = vec![0xFF, 0xD8];
        for (m, data) in segments {
            j.extend([0xFF, *m]);
            j.extend(((data.len() + 2) as u16).to_be_bytes());
            j.extend(data);
        }
        j.extend([0xFF, 0xDA, 0, 2, 0xFF, 0xD9]);
        j
    }

    fn app1_exif(orientation: u16) -> Vec<u8> {
        let mut s = EXIF_HEADER.to_vec();
        s.extend(tiff(false, &[(0x0112, 3, 1, short(orientation, false))], 0, &[]));
        s
    }

    fn app1_xmp(x: &str) -> Vec<u8> {
        let mut s = XMP_JPEG_HEADER.to_vec();
        s.extend(x.as_bytes());
        s
    }

    #[test]
    fn orientation_of_files_follows_the_rule() {
        // EXIF first, then the XMP
        let j = jpeg_of(&[(0xE1, app1_exif(6)), (0xE1, app1_xmp("tiff:Orientation=\"3\""))]);
        assert_eq!(orientation_of(&j), (6, None));
        // two EXIF segments: the first one wins, with a note
        let j = jpeg_of(&[(0xE1, app1_exif(8)), (0xE1, app1_exif(3))]);
        let (o, note) = orientation_of(&j);
        assert_eq!(o, 8);
        assert!(note.unwrap().contains("2 EXIF blocks"));
        // only in XMP
        assert_eq!(orientation_of(&jpeg_of(&[(0xE1, app1_xmp("<tiff:Orientation>5</tiff:Orientation>"))])), (5, None));
        // EXIF unusable: the XMP's, with a note
        let (o, note) = orientation_of(&jpeg_of(&[(0xE1, app1_exif(0)), (0xE1, app1_xmp("tiff:Orientation=\"2\""))]));
        assert_eq!(o, 2);
        assert!(note.unwrap().contains("not 1-8"));
        // malformed XMP: upright, with a note
        let (o, note) = orientation_of(&jpeg_of(&[(0xE1, app1_xmp("tiff:Orientation=\"7"))]));
        assert_eq!(o, 1);
        assert!(note.unwrap().contains("malformed"));
        assert_eq!(orientation_of(&jpeg_of(&[])), (1, None));
        assert_eq!(orientation_of(b"junk"), (1, None));
        // a TIFF file: its own IFD0
        assert_eq!(orientation_of(&tiff(true, &[(0x0112, 4, 1, 5u32.to_le_bytes())], 0, &[])), (5, None));
        // a PNG eXIf chunk, with and without the Exif header
        for header in [&b""[..], EXIF_HEADER] {
            let mut data = header.to_vec();
            data.extend(tiff(true, &[(0x0112, 3, 1, short(7, true))], 0, &[]));
            assert_eq!(orientation_of(&png_of(&[(*b"eXIf", data)])), (7, None));
        }
        let mut itxt = XMP_PNG_KEYWORD.to_vec();
        itxt.extend(b"\0\0\0\0\0<tiff:Orientation>4</tiff:Orientation>");
        assert_eq!(orientation_of(&png_of(&[(*b"iTXt", itxt)])), (4, None));
    }

    pub(crate) fn png_of(chunks: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
        let mut p = b"\x89PNG\r\n\x1a\n".to_vec();
        for (k, d) in chunks.iter().chain([(*b"IEND", vec![])].iter()) {
            p.extend((d.len() as u32).to_be_bytes());
            p.extend(k);
            p.extend(d);
            p.extend([0; 4]); // CRC: not read here
        }
        p
    }

    #[test]
    fn png_icc_is_inflated_within_the_cap() {
        let zeros = vec![0u8; 1 << 20];
        let z = fdeflate_compress(&zeros);
        let mut d = b"bomb\0\0".to_vec();
        d.extend(&z);
        let p = png_of(&[(*b"iCCP", d)]);
        let (f, at) = png(&mut std::io::Cursor::new(&p), 1 << 16);
        assert!(f.icc.unwrap().unwrap_err().contains("more than 65536"));
        assert_eq!(at, vec![(8, z.len() as u64 + 6 + 12)]);
        let (f, _) = png(&mut std::io::Cursor::new(&p), 1 << 21);
        assert_eq!(f.icc.unwrap().unwrap().len(), 1 << 20);
    }

    /// zlib of `data` with stored blocks' worth of effort: enough for a test.
    pub(crate) fn fdeflate_compress(data: &[u8]) -> Vec<u8> {
        fdeflate::compress_to_vec(data)
    }
}
