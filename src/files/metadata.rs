//! The photograph's metadata carried into its corrected photo, one
//! implementation for both commands (docs/OUTPUTS.md "Metadata"): the
//! input's EXIF (camera, lens, exposure, time, GPS, depth and altitude tags)
//! and XMP, with the tags that describe pixels made true of the written
//! image (Orientation 1, PixelX/YDimension, ColorSpace sRGB), and the
//! restoration recorded in XMP under this project's namespace.
//!
//! EXIF is read and written by `little_exif`; JPEG segments and PNG chunks
//! (the XMP packet, the ICC profile) by `img-parts`. A photo whose metadata
//! cannot be read still restores: the reason is a note of [`Carried`].

use bytes::Bytes;
use img_parts::jpeg::{markers, Jpeg, JpegSegment};
use img_parts::png::{Png, PngChunk};
use img_parts::ImageEXIF;
use little_exif::exif_tag::ExifTag;
use little_exif::filetype::FileExtension;
use little_exif::ifd::ExifTagGroup;
use little_exif::metadata::Metadata;

/// The XMP namespace of the restoration record.
pub const XMP_NAMESPACE: &str = "https://uwhl-rs.github.io/ns/restoration/1.0/";

/// The prefix of [`XMP_NAMESPACE`] in the packets written.
pub const XMP_PREFIX: &str = "uwhl";

/// The header of an XMP APP1 segment in JPEG.
const XMP_JPEG_HEADER: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";

/// The keyword of the iTXt chunk that holds XMP in PNG.
const XMP_PNG_KEYWORD: &[u8] = b"XML:com.adobe.xmp";

/// The TIFF tag of an XMP packet.
const TIFF_XMP_TAG: u16 = 700;

/// IFD0 tags carried from the input: what describes the photograph (camera,
/// author, time), never its pixel layout (size, strips, compression).
const IFD0_CARRIED: &[u16] = &[
    0x010E, // ImageDescription
    0x010F, // Make
    0x0110, // Model
    0x0131, // Software
    0x0132, // DateTime
    0x013B, // Artist
    0x8298, // Copyright
    0x011A, // XResolution
    0x011B, // YResolution
    0x0128, // ResolutionUnit
];

/// Exif sub-IFD tags rewritten for the output (its size and colour space).
const EXIF_REWRITTEN: &[u16] = &[0xA001, 0xA002, 0xA003, 0xA005];

/// What an input file holds besides its pixels.
#[derive(Debug, Default, Clone)]
pub struct Carried {
    /// the EXIF tags carried over (IFD0's descriptive ones, the Exif
    /// sub-IFD, GPS), None when the input has none
    pub exif: Option<Metadata>,
    /// the input's XMP packet
    pub xmp: Option<String>,
    /// the input's embedded ICC profile
    pub icc: Option<Vec<u8>>,
    /// why something could not be read (the sidecar's `source.notes`)
    pub notes: Vec<String>,
    /// the input's EXIF ExifImageWidth and ExifImageHeight (the size the
    /// camera wrote, the sensor's pixels the focal plane resolution counts
    /// in), which are rewritten, not carried, since the output's size is
    /// its own
    pub exif_size: Option<(u32, u32)>,
}

/// The container of a file, from its first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Container {
    /// JPEG (JFIF or EXIF)
    Jpeg,
    /// PNG
    Png,
    /// TIFF, and the raw formats built on it (DNG, NEF, CR2, ARW, ...)
    Tiff,
}

impl Container {
    /// The container of `bytes`, if one of the three.
    pub fn sniff(bytes: &[u8]) -> Option<Self> {
        if bytes.starts_with(&[0xFF, 0xD8]) {
            Some(Self::Jpeg)
        } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(Self::Png)
        } else if bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*") {
            Some(Self::Tiff)
        } else {
            None
        }
    }

    fn extension(self) -> FileExtension {
        match self {
            Self::Jpeg => FileExtension::JPEG,
            Self::Png => FileExtension::PNG { as_zTXt_chunk: false },
            Self::Tiff => FileExtension::TIFF,
        }
    }
}

/// Reads the metadata of an input file (`bytes`, the whole file, taken so
/// that it is not copied). Never fails: what cannot be read is a note.
/// The blocks are found and checked by the bounded readers of
/// `files::exif` (loops, counts, sizes, offsets) before `little_exif`
/// parses the EXIF; a block refused there is dropped with its reason.
pub fn read(bytes: Vec<u8>) -> Carried {
    let Some(kind) = Container::sniff(&bytes) else {
        return Carried { notes: vec![NOT_A_CONTAINER.into()], ..Carried::default() };
    };
    let found = crate::files::exif::scan(&mut std::io::Cursor::new(bytes.as_slice()), crate::files::exif::MAX_BLOCK);
    read_found(kind, found, &bytes)
}

const NOT_A_CONTAINER: &str = "metadata: not a JPEG, PNG or TIFF container; none carried";

/// [`read`] of the file at `path` (a regular file), reading of a JPEG or
/// PNG only the blocks before its image data (`files::exif::scan` stops
/// there): a photo's lens or time is found without reading the photo
/// again. A TIFF is its own EXIF block and is read whole.
pub fn read_path(path: &std::path::Path) -> Result<Carried, String> {
    use std::io::Read;
    crate::files::jobs::regular_file(path)?;
    let mut f = std::fs::File::open(path).map_err(|e| format!("cannot read the photo's metadata: {e}"))?;
    let mut head = [0u8; 8];
    let n = f.read(&mut head).map_err(|e| format!("cannot read the photo's metadata: {e}"))?;
    match Container::sniff(head.get(..n).unwrap_or_default()) {
        Some(kind @ (Container::Jpeg | Container::Png)) => {
            let found = crate::files::exif::scan(&mut std::io::BufReader::new(f), crate::files::exif::MAX_BLOCK);
            Ok(read_found(kind, found, &[]))
        }
        _ => std::fs::read(path).map(read).map_err(|e| format!("cannot read the photo's metadata: {e}")),
    }
}

/// [`read`] from the blocks `found` in a file of container `kind`; `bytes`
/// is the whole file for a TIFF (its own EXIF block), unused otherwise.
fn read_found(kind: Container, found: crate::files::exif::Found, bytes: &[u8]) -> Carried {
    use crate::files::exif;
    let mut out = Carried::default();
    if found.exif_blocks > 1 {
        out.notes.push(format!("metadata: {} EXIF blocks; the first one is carried", found.exif_blocks));
    }
    // a TIFF file is its own EXIF block
    let block: Option<Result<&[u8], String>> = match (kind, &found.exif) {
        (Container::Tiff, _) => Some(Ok(bytes)),
        (_, Some(Ok(b))) => Some(Ok(b.as_slice())),
        (_, Some(Err(e))) => Some(Err(e.clone())),
        (_, None) => None,
    };
    let block = block.map(|b| b.and_then(|b| exif::check(&mut &b[..]).map(|_| b)));
    match block {
        None => {}
        Some(Err(e)) => out.notes.push(format!("metadata: the EXIF is not carried ({e})")),
        Some(Ok(b)) => {
            let mut v = b.to_vec();
            let mut gone = Vec::new();
            // an entry that would trip an assertion inside little_exif (a
            // GPSAltitudeRef stored as a SHORT of 256) goes first: its panic
            // is caught, but its message would reach stderr
            if let Some((lean, g)) = exif::without_entries(&v, &panics_little_exif) {
                (v, gone) = (lean, g);
            }
            let parse = |v: &Vec<u8>| std::panic::catch_unwind(|| Metadata::new_from_vec(v, FileExtension::TIFF));
            let mut parsed = parse(&v);
            // one known tag of a type little_exif does not take (an Orientation
            // or a UserComment written as text) fails the whole block: read
            // again without such entries
            if parsed.is_err() || matches!(&parsed, Ok(Err(e)) if !is_absent(e)) {
                if let Some((lean, g)) = exif::without_entries(&v, &unexpected_type) {
                    gone.extend(g);
                    v = lean;
                    parsed = parse(&v);
                }
            }
            if !gone.is_empty() {
                out.notes.push(left_out_note(&gone));
            }
            match parsed {
                Ok(Ok(m)) => {
                    if kind == Container::Tiff {
                        out.xmp = m.get_tag_by_hex(TIFF_XMP_TAG, None).next().map(|t| {
                            let raw = t.value_as_u8_vec(&m.get_endian());
                            String::from_utf8_lossy(&raw).trim_end_matches('\0').to_string()
                        });
                    }
                    out.exif_size = exif_size(&m);
                    out.exif = carried_exif(&m);
                }
                Ok(Err(e)) if is_absent(&e) => {}
                Ok(Err(e)) => out.notes.push(format!("metadata: the EXIF cannot be read ({e}); not carried")),
                Err(_) => out.notes.push("metadata: the EXIF is malformed; not carried".into()),
            }
        }
    }
    match found.xmp {
        Some(Ok(x)) => out.xmp = Some(x),
        Some(Err(e)) => out.notes.push(format!("metadata: the XMP is not carried ({e})")),
        None => {}
    }
    match found.icc {
        Some(Ok(p)) => out.icc = Some(p),
        Some(Err(e)) => out.notes.push(format!("metadata: the ICC profile is ignored ({e})")),
        None => {}
    }
    out
}

/// The type little_exif expects of a tag it knows, in the IFD it is in.
fn expected_type(e: &crate::files::exif::EntryView) -> Option<u16> {
    use crate::files::exif::Group;
    let group = match e.group {
        Group::Ifd0 => ExifTagGroup::GENERIC,
        Group::Exif => ExifTagGroup::EXIF,
        Group::Gps => ExifTagGroup::GPS,
        Group::Interop => ExifTagGroup::INTEROP,
    };
    ExifTag::from_u16(e.tag, &group).ok().map(|t| t.format().as_u16())
}

/// Whether little_exif would panic on the entry: a BYTE tag stored as
/// SHORT values over 255 (it asserts they fit).
fn panics_little_exif(e: &crate::files::exif::EntryView) -> bool {
    expected_type(e) == Some(1) && e.kind == 3 && e.values.iter().any(|&v| v > 255)
}

/// Whether an EXIF entry of a tag little_exif knows has a type it refuses
/// for it. It takes the widenings among BYTE, SHORT and LONG, unsigned
/// rationals for signed ones, and two texts of the GPS IFD: an altitude
/// reference written "0" or "1", a processing method written as ASCII.
fn unexpected_type(e: &crate::files::exif::EntryView) -> bool {
    let Some(want) = expected_type(e) else { return false };
    let gps = e.group == crate::files::exif::Group::Gps;
    let taken = match (want, e.kind) {
        (w, k) if w == k => true,
        (4, 3) | (4, 1) | (3, 4) | (3, 1) | (10, 5) => true,
        (1, 3) => !panics_little_exif(e),
        (1, 2) => gps && e.tag == 0x0005 && e.values.first().is_some_and(|b| matches!(b, 0x00 | 0x01 | 0x30 | 0x31)),
        (7, 2) => gps && e.tag == 0x001B,
        _ => false,
    };
    !taken
}

/// The note for the EXIF entries left out: each tag once, at most eight named.
fn left_out_note(tags: &[u16]) -> String {
    let mut once: Vec<u16> = Vec::new();
    for t in tags {
        if !once.contains(t) {
            once.push(*t);
        }
    }
    let named: Vec<String> = once.iter().take(8).map(|t| format!("0x{t:04X}")).collect();
    let more = if once.len() > 8 { format!(" and {} more", once.len() - 8) } else { String::new() };
    format!("metadata: EXIF tag {}{more} of a type it cannot have, left out", named.join(", "))
}

fn is_absent(e: &std::io::Error) -> bool {
    let s = e.to_string().to_ascii_lowercase();
    s.contains("no exif") || s.contains("no metadata") || s.contains("could not find") || s.contains("not found")
}

/// The input's tags worth carrying: IFD0's descriptive ones, the Exif
/// sub-IFD (less what is rewritten) and GPS; no thumbnail (IFD1), no pixel layout.
/// The EXIF ExifImageWidth and ExifImageHeight of `m`, both nonzero.
fn exif_size(m: &Metadata) -> Option<(u32, u32)> {
    let (mut w, mut h) = (None, None);
    for ifd in m.get_ifds() {
        for tag in ifd.get_tags() {
            match tag {
                ExifTag::ExifImageWidth(v) => w = v.first().copied().filter(|x| *x > 0),
                ExifTag::ExifImageHeight(v) => h = v.first().copied().filter(|x| *x > 0),
                _ => {}
            }
        }
    }
    w.zip(h)
}

fn carried_exif(m: &Metadata) -> Option<Metadata> {
    let mut out = Metadata::new();
    let mut n = 0;
    for ifd in m.get_ifds() {
        if ifd.get_generic_ifd_nr() != 0 {
            continue;
        }
        let group = ifd.get_ifd_type();
        for tag in ifd.get_tags() {
            let hex = tag.as_u16();
            let keep = match group {
                ExifTagGroup::GENERIC => IFD0_CARRIED.contains(&hex),
                ExifTagGroup::EXIF => !EXIF_REWRITTEN.contains(&hex) && !matches!(tag, ExifTag::InteropOffset(_)),
                ExifTagGroup::GPS => true,
                _ => false,
            };
            if keep && !is_offset(tag) {
                out.set_tag(tag.clone());
                n += 1;
            }
        }
    }
    (n > 0).then_some(out)
}

fn is_offset(tag: &ExifTag) -> bool {
    matches!(tag, ExifTag::ExifOffset(_) | ExifTag::GPSInfo(_) | ExifTag::InteropOffset(_))
}

/// The EXIF of an output of `width` x `height` sRGB pixels, upright: the
/// carried tags with Orientation 1, ColorSpace 1 (sRGB) and the pixel size.
pub fn output_exif(c: &Carried, width: u32, height: u32) -> Metadata {
    let mut m = c.exif.clone().unwrap_or_default();
    m.set_tag(ExifTag::Orientation(vec![1]));
    m.set_tag(ExifTag::ColorSpace(vec![1]));
    m.set_tag(ExifTag::ExifImageWidth(vec![width]));
    m.set_tag(ExifTag::ExifImageHeight(vec![height]));
    m
}

/// The EXIF time tag as written (DateTimeOriginal, else DateTime), trimmed;
/// None without one. What a photo whose [`taken_at`] is None shows of it.
pub fn time_tag(m: &Metadata) -> Option<String> {
    time_fields(m).0
}

/// The EXIF OffsetTimeOriginal as written when it is there and is not an
/// offset `taken_at` keeps (`+HH:MM` within a day): the time is then read
/// without it, which is another instant unless the camera was on UTC.
pub fn unread_offset(m: &Metadata) -> Option<String> {
    time_fields(m).2.map(|s| s.trim_end_matches('\0').trim().to_string()).filter(|s| !s.is_empty() && !is_utc_offset(s))
}

/// The EXIF fields of the time, in one pass over the tags: [`time_tag`],
/// SubSecTimeOriginal and OffsetTimeOriginal as written.
fn time_fields(m: &Metadata) -> (Option<String>, Option<String>, Option<String>) {
    let (mut original, mut fallback, mut subsec, mut offset) = (None, None, None, None);
    for ifd in m.get_ifds() {
        for tag in ifd.get_tags() {
            match tag {
                ExifTag::DateTimeOriginal(s) => original = Some(s.clone()),
                ExifTag::ModifyDate(s) => fallback = Some(s.clone()),
                ExifTag::SubSecTimeOriginal(s) => subsec = Some(s.clone()),
                ExifTag::OffsetTimeOriginal(s) => offset = Some(s.clone()),
                _ => {}
            }
        }
    }
    let raw = original.or(fallback).map(|s| s.trim_end_matches('\0').trim().to_string()).filter(|s| !s.is_empty());
    (raw, subsec, offset)
}

/// When the photograph was taken, from its EXIF: DateTimeOriginal (else
/// DateTime) as ISO 8601, with SubSecTimeOriginal and OffsetTimeOriginal
/// when present (`2026-11-30T10:15:42.437+10:00`). A fraction is digits,
/// at most nine of them kept (nanoseconds); an offset is `+HH:MM` or
/// `-HH:MM` within a day (hours 00-23, minutes 00-59). Any other value of
/// either is left out and the time kept: `+99:99` or 80 digits written
/// into the sidecar made the report and the iFDO refuse it whole.
pub fn taken_at(m: &Metadata) -> Option<String> {
    let (raw, subsec, offset) = time_fields(m);
    let raw = raw?;
    let raw = raw.as_str();
    // "YYYY:MM:DD HH:MM:SS"
    let (date, time) = raw.split_once(' ')?;
    // bytes, not characters: a hostile value may hold any UTF-8 (found by fuzz/meta_carry)
    let time = time.as_bytes().get(..8)?;
    let clock = |c: &u8| c.is_ascii_digit() || *c == b':';
    if date.len() != 10 || !date.bytes().all(|c| clock(&c)) || !time.iter().all(clock) {
        return None;
    }
    if !is_calendar_time(date.as_bytes(), time) {
        return None;
    }
    let mut iso = format!("{}T{}", date.replace(':', "-"), String::from_utf8_lossy(time));
    if let Some(sub) = subsec.map(|s| s.trim_end_matches('\0').trim().to_string()).filter(|s| !s.is_empty() && s.chars().all(|c| c.is_ascii_digit())) {
        iso.push('.');
        iso.push_str(sub.get(..9).unwrap_or(&sub));
    }
    if let Some(off) = offset.map(|s| s.trim_end_matches('\0').trim().to_string()).filter(|s| is_utc_offset(s)) {
        iso.push_str(&off);
    }
    Some(iso)
}

/// Whether `s` is an EXIF time offset within a day: `+HH:MM` or `-HH:MM`,
/// hours 00-23 and minutes 00-59.
fn is_utc_offset(s: &str) -> bool {
    let b = s.as_bytes();
    let two = |at: usize, max: u8| match (b.get(at), b.get(at + 1)) {
        (Some(h @ b'0'..=b'9'), Some(l @ b'0'..=b'9')) => (h - b'0') * 10 + (l - b'0') <= max,
        _ => false,
    };
    b.len() == 6 && matches!(b.first(), Some(b'+' | b'-')) && b.get(3) == Some(&b':') && two(1, 23) && two(4, 59)
}

/// Whether `YYYY:MM:DD` and `HH:MM:SS` (digits and colons already checked)
/// name a time that exists: year 1-9999, month 1-12, the day within its
/// month, hour 0-23, minute and second 0-59. A camera with no clock set
/// writes `0000:00:00 00:00:00`; a hostile file any digits. Such a value is
/// no time: the readers of the sidecar refuse what ISO 8601 cannot be.
fn is_calendar_time(date: &[u8], time: &[u8]) -> bool {
    let num = |b: &[u8]| b.iter().try_fold(0u32, |n, c| c.is_ascii_digit().then(|| n * 10 + u32::from(c - b'0')));
    let field = |b: &[u8], at: usize, n: usize| b.get(at..at + n).and_then(num);
    let (Some(y), Some(m), Some(d)) = (field(date, 0, 4), field(date, 5, 2), field(date, 8, 2)) else { return false };
    let (Some(hh), Some(mm), Some(ss)) = (field(time, 0, 2), field(time, 3, 2), field(time, 6, 2)) else { return false };
    if date.get(4) != Some(&b':') || date.get(7) != Some(&b':') || time.get(2) != Some(&b':') || time.get(5) != Some(&b':') {
        return false;
    }
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days = match m {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if leap => 29,
        2 => 28,
        _ => return false,
    };
    y >= 1 && (1..=days).contains(&d) && hh < 24 && mm < 60 && ss < 60
}

/// Where the photograph was taken, from its EXIF GPS IFD: latitude and
/// longitude in decimal degrees (south and west negative) and the altitude
/// in metres (negative below sea level: a depth), when given. A hemisphere
/// letter other than N/S or E/W (either case) is no position; an altitude reference
/// other than 0 (above sea level) or 1 (below) is no altitude.
pub fn position(m: &Metadata) -> Option<(f64, f64, Option<f64>)> {
    let dms = |v: &[little_exif::rational::uR64]| -> Option<f64> {
        let f = |r: &little_exif::rational::uR64| (r.denominator != 0).then(|| f64::from(r.nominator) / f64::from(r.denominator));
        Some(f(v.first()?)? + f(v.get(1)?)? / 60.0 + f(v.get(2)?)? / 3600.0)
    };
    let (mut lat, mut lon, mut lat_ref, mut lon_ref, mut alt, mut alt_ref) = (None, None, None, None, None, None);
    for ifd in m.get_ifds() {
        for tag in ifd.get_tags() {
            match tag {
                ExifTag::GPSLatitude(v) => lat = dms(v),
                ExifTag::GPSLongitude(v) => lon = dms(v),
                ExifTag::GPSLatitudeRef(s) => lat_ref = Some(s.trim_end_matches('\0').to_string()),
                ExifTag::GPSLongitudeRef(s) => lon_ref = Some(s.trim_end_matches('\0').to_string()),
                ExifTag::GPSAltitude(v) => {
                    alt = v.first().filter(|r| r.denominator != 0).map(|r| f64::from(r.nominator) / f64::from(r.denominator));
                }
                ExifTag::GPSAltitudeRef(v) => alt_ref = Some(v.first().copied()),
                _ => {}
            }
        }
    }
    // a reference that is neither letter (in either case) leaves the
    // hemisphere unknown: no position
    let sign = |r: &Option<String>, pos: &str, neg: &str| match r.as_deref().map(str::trim) {
        None => Some(1.0),
        Some(x) if x.eq_ignore_ascii_case(pos) => Some(1.0),
        Some(x) if x.eq_ignore_ascii_case(neg) => Some(-1.0),
        Some(_) => None,
    };
    let (lat, lon) = (lat? * sign(&lat_ref, "N", "S")?, lon? * sign(&lon_ref, "E", "W")?);
    // 0 above sea level, 1 below it (EXIF 2.3); 2 and 3 are ellipsoidal
    // heights (EXIF 3.0), another reference than the sea's: no altitude then
    let alt_sign = match alt_ref {
        None | Some(Some(0)) => Some(1.0),
        Some(Some(1)) => Some(-1.0),
        Some(_) => None,
    };
    // a position off the globe (latitude 1000, minutes of 99 past 89 degrees)
    // is none: the sidecar's readers and the iFDO's schema refuse it
    if !(lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0) {
        return None;
    }
    Some((lat, lon, alt.filter(|a| a.is_finite()).zip(alt_sign).map(|(a, k)| k * a)))
}

/// Lowercase hexadecimal SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The image UUID of a corrected photo (docs/OUTPUTS.md "Metadata"), as
/// the 32 hexadecimal digits EXIF's ImageUniqueID holds: the iFDO's
/// `image-uuid`, which the standard asks to be embedded in the file. It has
/// the layout of a version 4 UUID (the iFDO schema admits no other) with
/// its 122 free bits taken from SHA-256 over the input file's hash and the
/// restoration record, not from a random source: both commands, and a
/// rerun on the same input with the same parameters, give a photo the same
/// UUID; a photo restored otherwise, or under another name, gets another.
pub fn image_uuid(input_sha256: &str, record: &Record) -> String {
    let mut text = format!("uwhl-rs image uuid\n{input_sha256}\n");
    for (k, v) in record {
        text.push_str(&format!("{k}={v}\n"));
    }
    let hex = sha256_hex(text.as_bytes());
    let mut digits: Vec<u8> = hex.bytes().take(32).collect();
    if let Some(d) = digits.get_mut(12) {
        *d = b'4'; // version 4
    }
    if let Some(d) = digits.get_mut(16) {
        // RFC 4122 variant: 10xx
        *d = match char::from(*d).to_digit(16).unwrap_or(0) & 3 {
            0 => b'8',
            1 => b'9',
            2 => b'a',
            _ => b'b',
        };
    }
    String::from_utf8(digits).unwrap_or_default()
}

/// The input's own ImageUniqueID (EXIF 0xA420), if it has one.
fn unique_id(m: &Metadata) -> Option<String> {
    m.get_ifds().iter().flat_map(|i| i.get_tags()).find_map(|t| match t {
        ExifTag::ImageUniqueID(s) => Some(s.trim_end_matches('\0').trim().to_string()).filter(|s| !s.is_empty()),
        _ => None,
    })
}

/// The restoration, as recorded in XMP: `(property, value)` pairs of the
/// [`XMP_NAMESPACE`], written in this order.
pub type Record = Vec<(&'static str, String)>;

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The `rdf:Description` of the restoration record.
pub fn record_description(record: &Record) -> String {
    let mut s = format!("<rdf:Description rdf:about=\"\" xmlns:{XMP_PREFIX}=\"{XMP_NAMESPACE}\">");
    for (k, v) in record {
        s.push_str(&format!("<{XMP_PREFIX}:{k}>{}</{XMP_PREFIX}:{k}>", xml_escape(v)));
    }
    s.push_str("</rdf:Description>");
    s
}

/// The XMP packet of the output: the input's packet (if any) with the
/// restoration's description added, an earlier restoration record
/// replaced, and `tiff:Orientation` made 1 (the pixels are upright);
/// without one, a packet of the record alone.
pub fn output_xmp(c: &Carried, record: &Record) -> String {
    let desc = record_description(record);
    if let Some(packet) = c.xmp.as_deref() {
        let mut p = remove_record(packet);
        p = set_orientation(&p);
        if let Some(at) = p.rfind("</rdf:RDF>") {
            p.insert_str(at, &desc);
            return p;
        }
    }
    format!(
        "<?xpacket begin=\"\u{feff}\" id=\"W5M0MpCehiHzreSzNTczkc9d\"?>\
<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">{desc}\
</rdf:RDF></x:xmpmeta><?xpacket end=\"w\"?>"
    )
}

/// `packet` without an `rdf:Description` of this project's namespace (a
/// restored photo restored again gets one record, its own).
fn remove_record(packet: &str) -> String {
    let mut p = packet.to_string();
    let marker = format!("xmlns:{XMP_PREFIX}=\"{XMP_NAMESPACE}\"");
    while let Some(at) = p.find(&marker) {
        let (Some(start), Some(end)) = (p[..at].rfind("<rdf:Description"), p[at..].find("</rdf:Description>")) else {
            break;
        };
        p.replace_range(start..at + end + "</rdf:Description>".len(), "");
    }
    p
}

/// `tiff:Orientation` set to 1, as an attribute or an element.
fn set_orientation(packet: &str) -> String {
    let mut p = packet.to_string();
    for (open, close) in [("tiff:Orientation=\"", "\""), ("<tiff:Orientation>", "</tiff:Orientation>")] {
        let mut from = 0;
        while let Some(i) = p[from..].find(open) {
            let v0 = from + i + open.len();
            let Some(len) = p[v0..].find(close) else { break };
            p.replace_range(v0..v0 + len, "1");
            from = v0 + 1;
        }
    }
    p
}

/// Embeds `exif` and the XMP `packet` into the encoded output `file`
/// (JPEG, PNG or TIFF, by its first bytes). An earlier EXIF or XMP of the
/// encoder is replaced. `file` is shared, not copied: the caller keeps the
/// photo as encoded if this fails.
pub fn embed(file: &Bytes, exif: &Metadata, packet: &str) -> Result<Vec<u8>, String> {
    let kind = Container::sniff(file).ok_or("the output is not a JPEG, PNG or TIFF")?;
    if kind == Container::Tiff {
        // TIFF keeps its EXIF in the image's own IFD0: the encoder's tags
        // (size, strips) and the carried ones are written back together
        let mut out = file.to_vec();
        let mut m = std::panic::catch_unwind(|| Metadata::new_from_vec(&out, FileExtension::TIFF))
            .map_err(|_| "cannot read the output TIFF's tags".to_string())?
            .map_err(|e| format!("cannot read the output TIFF's tags: {e}"))?;
        for ifd in exif.get_ifds() {
            for tag in ifd.get_tags() {
                if !is_offset(tag) {
                    m.set_tag(tag.clone());
                }
            }
        }
        m.set_tag(ExifTag::UnknownINT8U(packet.as_bytes().to_vec(), TIFF_XMP_TAG, ExifTagGroup::GENERIC));
        write_exif(&m, &mut out, kind)?;
        return Ok(out);
    }
    let tiff = std::panic::catch_unwind(|| exif.encode())
        .map_err(|_| "cannot encode the EXIF (the encoder failed)".to_string())?
        .map_err(|e| format!("cannot encode the EXIF: {e}"))?;
    match kind {
        Container::Jpeg => {
            let mut j = Jpeg::from_bytes(file.clone()).map_err(|e| format!("the output JPEG: {e}"))?;
            j.set_exif(Some(Bytes::from(tiff)));
            let segments = j.segments_mut();
            segments.retain(|s| !(s.marker() == markers::APP1 && s.contents().starts_with(XMP_JPEG_HEADER)));
            let mut contents = XMP_JPEG_HEADER.to_vec();
            contents.extend_from_slice(packet.as_bytes());
            if contents.len() > 65533 {
                return Err(format!("the XMP packet ({} bytes) is larger than one JPEG segment holds", packet.len()));
            }
            // after the APPn segments (JFIF, EXIF)
            let at = segments.iter().position(|s| !(0xE0..=0xEF).contains(&s.marker())).unwrap_or(segments.len());
            segments.insert(at, JpegSegment::new_with_contents(markers::APP1, Bytes::from(contents)));
            Ok(Vec::from(j.encoder().bytes()))
        }
        Container::Png => {
            let mut p = Png::from_bytes(file.clone()).map_err(|e| format!("the output PNG: {e}"))?;
            p.set_exif(Some(Bytes::from(tiff)));
            let chunks = p.chunks_mut();
            chunks.retain(|c| !(&c.kind() == b"iTXt" && c.contents().starts_with(XMP_PNG_KEYWORD)));
            let mut data = XMP_PNG_KEYWORD.to_vec();
            data.extend_from_slice(b"\0\0\0\0\0");
            data.extend_from_slice(packet.as_bytes());
            let at = chunks.iter().position(|c| &c.kind() == b"IDAT").unwrap_or(chunks.len());
            chunks.insert(at, PngChunk::new(*b"iTXt", Bytes::from(data)));
            Ok(Vec::from(p.encoder().bytes()))
        }
        Container::Tiff => Err("unreachable".into()),
    }
}

fn write_exif(m: &Metadata, file: &mut Vec<u8>, kind: Container) -> Result<(), String> {
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| m.write_to_vec(file, kind.extension())));
    match r {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(format!("cannot write the EXIF: {e}")),
        Err(_) => Err("cannot write the EXIF (the writer failed)".into()),
    }
}

/// A sidecar value as one text field (of the XMP record, of summary.csv):
/// strings as they are, null or absent as nothing, the rest as JSON.
pub fn value_text(v: Option<&serde_json::Value>) -> String {
    match v {
        None | Some(serde_json::Value::Null) => String::new(),
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(v) => v.to_string(),
    }
}

/// The restoration record from the sidecar's fields (both commands write
/// them alike): water type, A, flags, the profile and its steps, t_scale,
/// the candidate types, the version, and the sidecar's file name.
pub fn record_from_sidecar(side: &serde_json::Value, sidecar_name: &str) -> Record {
    use serde_json::Value;
    let text = value_text;
    let p = side.get("parameters");
    let param = |k: &str| text(p.and_then(|p| p.get(k)));
    let a = side
        .get("veiling_light")
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|v| format!("{:.6}", v.as_f64().unwrap_or(f64::NAN))).collect::<Vec<_>>().join(" "))
        .unwrap_or_default();
    let list = |v: Option<&Value>| match v.and_then(Value::as_array) {
        Some(items) => items
            .iter()
            .map(|x| match x {
                Value::Array(spec) => text(spec.first()),
                other => text(Some(other)),
            })
            .collect::<Vec<_>>()
            .join(","),
        None => String::new(),
    };
    let t_scale = p.and_then(|p| p.get("t_scale")).and_then(Value::as_f64).map(|v| format!("{v:.6}")).unwrap_or_default();
    let types = list(p.and_then(|p| p.get("water_types")));
    vec![
        ("WaterType", text(side.get("water_type"))),
        ("VeilingLight", a),
        ("Flags", list(side.get("flags"))),
        ("Method", param("method")),
        ("Selection", param("selection")),
        ("WhiteBalance", param("white_balance")),
        ("TypeChoice", param("type_choice")),
        ("HazeFloor", param("haze_floor")),
        ("TScale", t_scale),
        ("WaterTypes", if types.is_empty() { "all".into() } else { types }),
        ("Version", text(side.get("uwhl_version"))),
        ("Sidecar", sidecar_name.to_string()),
    ]
}

/// Where the shown colours come from (METHOD §12.5), for the XMP record:
/// `Fallback` (the sidecar's `parameters.fallback`), `FallbackShare` (the
/// share of the shown colour that is the input's own balance, 0-1) and
/// `VeilExcess` (the share of object pixels under more veil than light),
/// each empty when the sidecar has none (the paper profile, a known
/// distance).
pub fn colour_source(side: &serde_json::Value) -> Record {
    let number = |k: &str| side.get(k).and_then(serde_json::Value::as_f64).map(|v| format!("{v:.4}")).unwrap_or_default();
    vec![
        ("Fallback", value_text(side.get("parameters").and_then(|p| p.get("fallback")))),
        ("FallbackShare", number("fallback_share")),
        ("VeilExcess", number("veil_excess")),
    ]
}

/// Carries the metadata of the input file (`input`, its bytes) into the
/// encoded output `encoded` of `width` x `height` pixels, with the
/// restoration record of the sidecar `side`: the output's bytes and the
/// sidecar's `metadata` object. Never fails: when the metadata cannot be
/// written, the output is returned as encoded and the reason noted.
pub fn carry(input: Vec<u8>, encoded: Vec<u8>, side: &serde_json::Value, sidecar_name: &str, width: u32, height: u32)
    -> (Vec<u8>, serde_json::Value) {
    let input_sha256 = sha256_hex(&input);
    carry_read(read(input), input_sha256, encoded, side, sidecar_name, width, height)
}

/// [`carry`] with the input's metadata already read (`c`) and its hash.
fn carry_read(c: Carried, input_sha256: String, encoded: Vec<u8>, side: &serde_json::Value, sidecar_name: &str,
    width: u32, height: u32) -> (Vec<u8>, serde_json::Value) {
    let exif_tags = c.exif.as_ref().map_or(0, |m| m.get_ifds().iter().map(|i| i.get_tags().len()).sum::<usize>());
    let input_uuid = c.exif.as_ref().and_then(unique_id);
    let mut record = record_from_sidecar(side, sidecar_name);
    let uuid = image_uuid(&input_sha256, &record);
    // where the colours come from, in the photo's own record but not in its
    // UUID: it follows from the input and the parameters the UUID already has
    record.extend(colour_source(side));
    let mut exif = output_exif(&c, width, height);
    exif.set_tag(ExifTag::ImageUniqueID(uuid.clone()));
    let xmp = output_xmp(&c, &record);
    let mut notes = c.notes.clone();
    let original = Bytes::from(encoded);
    let (bytes, written) = match embed(&original, &exif, &xmp) {
        Ok(b) => (b, true),
        Err(e) if c.xmp.is_some() => {
            // the input's packet may not fit (one JPEG segment): the record alone
            let own = output_xmp(&Carried::default(), &record);
            match embed(&original, &exif, &own) {
                Ok(b) => {
                    notes.push(format!("metadata: the input's XMP is not carried ({e}); the record is"));
                    (b, true)
                }
                Err(e) => {
                    notes.push(format!("metadata: {e}; the photo is written without it"));
                    (Vec::from(original), false)
                }
            }
        }
        Err(e) => {
            notes.push(format!("metadata: {e}; the photo is written without it"));
            (Vec::from(original), false)
        }
    };
    let taken = c.exif.as_ref().and_then(taken_at);
    if taken.is_none() && c.exif.as_ref().is_some_and(has_time) {
        notes.push("metadata: the EXIF time is not a date and time that exists; no time recorded".into());
    }
    if c.exif.as_ref().is_some_and(|m| has_position(m) && position(m).is_none()) {
        notes.push("metadata: the EXIF GPS position is incomplete or off the globe; no position recorded".into());
    }
    let gps = c.exif.as_ref().and_then(position).map(|(lat, lon, alt)| {
        serde_json::json!({"latitude": lat, "longitude": lon, "altitude": alt})
    });
    let summary = serde_json::json!({
        "written": written,
        "exif_tags_carried": exif_tags,
        "input_xmp": c.xmp.is_some(),
        "input_icc_profile": c.icc.is_some(),
        "taken_at": taken,
        "gps": gps,
        "image_uuid": written.then_some(uuid),
        "photo_sha256": sha256_hex(&bytes),
        "input_sha256": input_sha256,
        "input_image_uuid": input_uuid,
        "notes": notes,
    });
    (bytes, summary)
}

/// [`carry`] with the input read from `input_path` (both commands write
/// the photo before the input is read again): when it cannot be read, the
/// photo is returned as encoded and the reason noted. Only what the
/// metadata needs is held: the hash is streamed over the file, a JPEG's or
/// PNG's metadata segments are found by seeking past the others, and a
/// TIFF (its own EXIF block, which the EXIF parser takes whole) is read
/// only when it is at most `tiff_cap` bytes (what the memory plan holds
/// for it, `files::budget`); a larger one's EXIF is not carried, with a note.
pub fn carry_from(input_path: &std::path::Path, encoded: Vec<u8>, side: &serde_json::Value, sidecar_name: &str,
    width: u32, height: u32, tiff_cap: u64) -> (Vec<u8>, serde_json::Value) {
    match read_from(input_path, tiff_cap) {
        Ok((c, input_sha256)) => carry_read(c, input_sha256, encoded, side, sidecar_name, width, height),
        Err(e) => {
            let photo_sha256 = sha256_hex(&encoded);
            (
                encoded,
                serde_json::json!({"written": false, "exif_tags_carried": 0, "input_xmp": false,
                    "input_icc_profile": false, "taken_at": null, "gps": null, "image_uuid": null,
                    "photo_sha256": photo_sha256, "input_sha256": null, "input_image_uuid": null,
                    "notes": [format!("metadata: cannot read the input again ({e}); none carried")]}),
            )
        }
    }
}

/// A frame's photo (a still of a video, a frame of a pipe: no file of its
/// own to carry metadata from) with the restoration's record embedded and
/// an image UUID derived from the frame's name (`label`, e.g. `dive.mp4#120`)
/// and the record, as a photo's is from its input's SHA-256, so that the
/// frame is an image of the iFDO; `note` says why nothing else is carried.
/// `input_sha256` is null: the frame has none.
pub fn carry_frame(encoded: Vec<u8>, side: &serde_json::Value, sidecar_name: &str, width: u32, height: u32,
    label: &str, note: &str) -> (Vec<u8>, serde_json::Value) {
    let carried = Carried { notes: vec![note.to_string()], ..Carried::default() };
    let (bytes, mut summary) = carry_read(carried, sha256_hex(label.as_bytes()), encoded, side, sidecar_name, width, height);
    if let Some(o) = summary.as_object_mut() {
        o.insert("input_sha256".into(), serde_json::Value::Null);
    }
    (bytes, summary)
}

/// The metadata of the file at `path` and its SHA-256, reading what
/// [`carry_from`] says.
fn read_from(path: &std::path::Path, tiff_cap: u64) -> std::io::Result<(Carried, String)> {
    use sha2::Digest;
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::io::BufReader::with_capacity(1 << 16, std::fs::File::open(path)?);
    let mut hasher = sha2::Sha256::new();
    let mut head = Vec::with_capacity(8);
    let mut len = 0u64;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        let chunk = buf.get(..n).unwrap_or_default();
        let room = 8usize.saturating_sub(head.len());
        head.extend(chunk.iter().take(room));
        hasher.update(chunk);
        len += n as u64;
    }
    let sha = hasher.finalize().iter().map(|b| format!("{b:02x}")).collect::<String>();
    let Some(kind) = Container::sniff(&head) else {
        return Ok((Carried { notes: vec![NOT_A_CONTAINER.into()], ..Carried::default() }, sha));
    };
    f.seek(SeekFrom::Start(0))?;
    let carried = match kind {
        Container::Tiff if len > tiff_cap => Carried {
            notes: vec![format!(
                "metadata: the TIFF file is {len} bytes, more than the {tiff_cap} its memory plan holds for \
                 reading its tags again; its EXIF is not carried"
            )],
            ..Carried::default()
        },
        Container::Tiff => {
            let mut bytes = Vec::new();
            bytes.try_reserve_exact(usize::try_from(len).unwrap_or(usize::MAX)).map_err(std::io::Error::other)?;
            f.read_to_end(&mut bytes)?;
            read(bytes)
        }
        _ => {
            let found = crate::files::exif::scan(&mut f, crate::files::exif::MAX_BLOCK);
            read_found(kind, found, &[])
        }
    };
    Ok((carried, sha))
}

/// Whether the EXIF has a time tag (DateTimeOriginal or DateTime).
fn has_time(m: &Metadata) -> bool {
    m.get_ifds().iter().flat_map(|i| i.get_tags()).any(|t| matches!(t, ExifTag::DateTimeOriginal(_) | ExifTag::ModifyDate(_)))
}

/// Whether the EXIF has a GPS latitude or longitude tag.
fn has_position(m: &Metadata) -> bool {
    m.get_ifds().iter().flat_map(|i| i.get_tags()).any(|t| matches!(t, ExifTag::GPSLatitude(_) | ExifTag::GPSLongitude(_)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_record_replaces_an_earlier_one_and_orientation_becomes_upright() {
        let rec: Record = vec![("WaterType", "3C".into()), ("Note", "a < b & c".into())];
        let first = output_xmp(&Carried::default(), &rec);
        assert!(first.contains("<uwhl:WaterType>3C</uwhl:WaterType>") && first.contains("a &lt; b &amp; c"));
        let input = "<x:xmpmeta><rdf:RDF><rdf:Description tiff:Orientation=\"6\" xmp:Rating=\"3\"/>\
<rdf:Description><tiff:Orientation>8</tiff:Orientation></rdf:Description></rdf:RDF></x:xmpmeta>";
        let c = Carried { xmp: Some(input.into()), ..Carried::default() };
        let once = output_xmp(&c, &rec);
        assert!(once.contains("tiff:Orientation=\"1\"") && once.contains("<tiff:Orientation>1</tiff:Orientation>"));
        assert!(once.contains("xmp:Rating=\"3\""));
        let again = output_xmp(&Carried { xmp: Some(once.clone()), ..Carried::default() }, &vec![("WaterType", "II".into())]);
        assert_eq!(again.matches(XMP_NAMESPACE).count(), 1);
        assert!(again.contains("<uwhl:WaterType>II</uwhl:WaterType>") && !again.contains(">3C<"));
    }

    #[test]
    fn image_uuids_have_the_version_4_layout_and_follow_input_and_record() {
        // SHA-256 of the empty string, FIPS 180-2's test vector
        assert_eq!(sha256_hex(b""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
        let rec: Record = vec![("WaterType", "3C".into())];
        let a = image_uuid(&sha256_hex(b"photo"), &rec);
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|b| b.is_ascii_hexdigit() && !b.is_ascii_uppercase()));
        assert_eq!(&a[12..13], "4");
        assert!("89ab".contains(&a[16..17]));
        assert_eq!(a, image_uuid(&sha256_hex(b"photo"), &rec));
        assert_ne!(a, image_uuid(&sha256_hex(b"photo2"), &rec));
        assert_ne!(a, image_uuid(&sha256_hex(b"photo"), &vec![("WaterType", "II".into())]));
    }

    #[test]
    fn garbage_is_a_note_not_a_failure() {
        let c = read(b"\xFF\xD8\xFF\xE1\x00\x10Exif\0\0garbage-garbage".to_vec());
        assert!(c.exif.is_none());
        let c = read(b"not an image".to_vec());
        assert!(c.exif.is_none() && !c.notes.is_empty());
    }

    /// A JPEG of 8 x 8 pixels with `app1` as its first APP1 segment.
    #[cfg(feature = "cli")]
    fn jpeg_with_app1(app1: &[u8]) -> Vec<u8> {
        use image::ImageEncoder;
        let mut j = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut j).write_image(&[80; 192], 8, 8, image::ExtendedColorType::Rgb8).unwrap();
        let mut out = j[..2].to_vec();
        out.extend([0xFF, 0xE1]);
        out.extend(((app1.len() + 2) as u16).to_be_bytes());
        out.extend(app1);
        out.extend(&j[2..]);
        out
    }

    /// "Exif\0\0" and a little-endian block: IFD0 with Make "Nikon" and
    /// its next-IFD link `next`.
    #[cfg(feature = "cli")]
    fn exif_with_make(next: u32) -> Vec<u8> {
        let mut b = b"Exif\0\0II*\0\x08\0\0\0\x01\0\x0F\x01\x02\0\x06\0\0\0\x1A\0\0\0".to_vec();
        b.extend(next.to_le_bytes());
        b.extend(b"Nikon\0");
        b
    }

    #[test]
    #[cfg(feature = "cli")]
    fn a_looping_exif_block_is_dropped_with_a_note_and_a_sound_one_carried() {
        let c = read(jpeg_with_app1(&exif_with_make(0)));
        assert!(c.notes.is_empty(), "{:?}", c.notes);
        let m = c.exif.expect("the sound block is carried");
        assert!(m.get_ifds().iter().flat_map(|i| i.get_tags()).any(|t| matches!(t, ExifTag::Make(s) if s.starts_with("Nikon"))));
        // the next-IFD link pointing at IFD0 itself
        let c = read(jpeg_with_app1(&exif_with_make(8)));
        assert!(c.exif.is_none());
        assert!(c.notes.iter().any(|n| n.contains("loop")), "{:?}", c.notes);
    }

    #[test]
    #[cfg(feature = "cli")]
    fn an_entry_of_a_type_its_tag_cannot_have_costs_only_itself() {
        // IFD0: Make "Nikon", Orientation written as the text "6", DateTime
        // (0x0132) of 20 bytes: little_exif refuses the whole block for the
        // Orientation; read again without it, the make and the time stay
        let mut b = b"Exif\0\0II*\0\x08\0\0\0\x03\0".to_vec();
        let values = 8 + 2 + 3 * 12 + 4;
        for (tag, kind, count, value) in [
            (0x010Fu16, 2u16, 6u32, values as u32),
            (0x0112, 2, 2, u32::from_le_bytes(*b"6\0\0\0")),
            (0x0132, 2, 20, values as u32 + 6),
        ] {
            b.extend(tag.to_le_bytes());
            b.extend(kind.to_le_bytes());
            b.extend(count.to_le_bytes());
            b.extend(value.to_le_bytes());
        }
        b.extend(0u32.to_le_bytes());
        b.extend(b"Nikon\0");
        b.extend(b"2026:01:02 03:04:05\0");
        let c = read(jpeg_with_app1(&b));
        assert_eq!(c.notes, vec!["metadata: EXIF tag 0x0112 of a type it cannot have, left out".to_string()]);
        let m = c.exif.expect("the rest of the block is carried");
        let tags: Vec<&ExifTag> = m.get_ifds().iter().flat_map(|i| i.get_tags()).collect();
        assert!(tags.iter().any(|t| matches!(t, ExifTag::Make(s) if s.starts_with("Nikon"))));
        assert!(!tags.iter().any(|t| t.as_u16() == 0x0112));
        // an Orientation of its own type: nothing is left out
        let mut good = b.clone();
        good[6 + 8 + 2 + 12 + 2..6 + 8 + 2 + 12 + 12].copy_from_slice(&[3, 0, 1, 0, 0, 0, 6, 0, 0, 0]);
        let c = read(jpeg_with_app1(&good));
        assert!(c.notes.is_empty(), "{:?}", c.notes);
    }

    #[test]
    fn the_types_little_exif_refuses_are_the_ones_left_out() {
        use crate::files::exif::{EntryView, Group};
        let e = |group, tag, kind, values: &[u64]| unexpected_type(&EntryView { group, tag, kind, values });
        // its own type, and the widenings it takes
        assert!(!e(Group::Ifd0, 0x0112, 3, &[6]));
        assert!(!e(Group::Ifd0, 0x0128, 1, &[2]), "ResolutionUnit as BYTE");
        assert!(!e(Group::Gps, 0x0005, 2, &[u64::from(b'1'), 0]), "GPSAltitudeRef as the text 1");
        assert!(!e(Group::Gps, 0x0005, 3, &[1]), "GPSAltitudeRef as a SHORT that fits");
        // text where a number or bytes are, and a SHORT over a byte's range
        assert!(e(Group::Ifd0, 0x0112, 2, &[u64::from(b'6'), 0]));
        assert!(e(Group::Exif, 0x9286, 2, &[65, 66]), "UserComment as ASCII");
        assert!(e(Group::Exif, 0x9000, 2, &[48, 50, 51, 48]), "ExifVersion as ASCII");
        assert!(e(Group::Gps, 0x0005, 2, &[u64::from(b'x')]));
        assert!(e(Group::Gps, 0x0005, 3, &[256]) && panics_little_exif(&EntryView { group: Group::Gps, tag: 0x0005, kind: 3, values: &[256] }));
        // a tag little_exif does not know is never judged
        assert!(!e(Group::Ifd0, 0xC6F4, 2, &[]));
        // the note: each tag once, eight at most
        assert_eq!(left_out_note(&[0x0112, 0x0112]), "metadata: EXIF tag 0x0112 of a type it cannot have, left out");
        let many: Vec<u16> = (0..10).collect();
        assert!(left_out_note(&many).ends_with("0x0007 and 2 more of a type it cannot have, left out"));
    }

    #[test]
    fn a_time_with_non_ascii_characters_is_no_time_not_a_panic() {
        let mut m = Metadata::new();
        m.set_tag(ExifTag::DateTimeOriginal("2026:01:02 03:\u{ff}\u{ff}\u{ff}\u{ff}".into()));
        assert_eq!(taken_at(&m), None);
        m.set_tag(ExifTag::DateTimeOriginal("2026:01:02 03:04:05".into()));
        assert_eq!(taken_at(&m).as_deref(), Some("2026-01-02T03:04:05"));
    }

    #[test]
    fn an_offset_that_is_not_one_is_named_for_a_log_by_time() {
        let mut m = Metadata::new();
        m.set_tag(ExifTag::DateTimeOriginal("2026:01:02 03:04:05".into()));
        assert_eq!(unread_offset(&m), None);
        for (written, unread) in [("+10:00", None), ("-03:30", None), ("+1000", Some("+1000")), ("+99:00", Some("+99:00")), ("  ", None)] {
            m.set_tag(ExifTag::OffsetTimeOriginal(written.into()));
            assert_eq!(unread_offset(&m).as_deref(), unread, "{written:?}");
        }
    }

    #[test]
    fn gps_references_must_be_known_letters_and_codes() {
        use little_exif::rational::uR64;
        let r = |n: u32| uR64 { nominator: n, denominator: 1 };
        let at = |lat_ref: &str, lon_ref: &str, alt_ref: Option<u8>| {
            let mut m = Metadata::new();
            m.set_tag(ExifTag::GPSLatitude(vec![r(33), r(30), r(0)]));
            m.set_tag(ExifTag::GPSLongitude(vec![r(151), r(15), r(0)]));
            m.set_tag(ExifTag::GPSLatitudeRef(lat_ref.into()));
            m.set_tag(ExifTag::GPSLongitudeRef(lon_ref.into()));
            m.set_tag(ExifTag::GPSAltitude(vec![r(12)]));
            if let Some(a) = alt_ref {
                m.set_tag(ExifTag::GPSAltitudeRef(vec![a]));
            }
            position(&m)
        };
        assert_eq!(at("S", "E", Some(1)), Some((-33.5, 151.25, Some(-12.0))));
        assert_eq!(at("N", "W", Some(0)), Some((33.5, -151.25, Some(12.0))));
        assert_eq!(at("s", "w", Some(0)), Some((-33.5, -151.25, Some(12.0))), "a writer's lowercase letters");
        assert_eq!(at("N", "E", None), Some((33.5, 151.25, Some(12.0))));
        // EXIF 3.0's ellipsoidal heights are not heights above the sea: no altitude
        assert_eq!(at("N", "E", Some(2)), Some((33.5, 151.25, None)));
        assert_eq!(at("N", "E", Some(7)), Some((33.5, 151.25, None)));
        // a letter that names no hemisphere: no position at all
        assert_eq!(at("X", "E", Some(0)), None);
        assert_eq!(at("S", "Q", Some(0)), None);
    }

    #[test]
    fn a_bad_offset_or_fraction_is_left_out_and_the_time_kept() {
        let with = |sub: &str, off: &str| {
            let mut m = Metadata::new();
            m.set_tag(ExifTag::DateTimeOriginal("2026:01:02 03:04:05".into()));
            m.set_tag(ExifTag::SubSecTimeOriginal(sub.into()));
            m.set_tag(ExifTag::OffsetTimeOriginal(off.into()));
            taken_at(&m).unwrap()
        };
        assert_eq!(with("437", "+10:00"), "2026-01-02T03:04:05.437+10:00");
        assert_eq!(with("5", "-23:59"), "2026-01-02T03:04:05.5-23:59");
        for off in ["+99:99", "ABCDEF", "+24:00", "+10:60", "+1:000", "10:00+", "+10:00:00", "+１0:0"] {
            assert_eq!(with("1", off), "2026-01-02T03:04:05.1", "{off}");
        }
        // digits beyond nanoseconds are dropped: 80 of them ran past the sidecar's 64 characters
        assert_eq!(with(&"7".repeat(80), "+00:00"), "2026-01-02T03:04:05.777777777+00:00");
        assert_eq!(with("12a", "+01:00"), "2026-01-02T03:04:05+01:00");
    }
}
