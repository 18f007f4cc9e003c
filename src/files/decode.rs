//! Decoding of PNG, JPEG and TIFF inputs (8 or 16 bits per sample) with
//! limits: the header is read first, the caller's memory plan is checked
//! against it, and only then is the image decoded, with the decoders' own
//! allocation limit set to the budget.
//!
//! Channels: gray is replicated to R = G = B, alpha is dropped (not
//! composited). 8- and 16-bit samples are sRGB codes (decoded through the
//! inverse curve unless told otherwise); 32-bit float samples (TIFF) are
//! taken as linear values, as the Python reader does. EXIF orientation is
//! applied to inputs (not to masks), as on the Python side.

use crate::error::{Failure, Kind};
use crate::files::color::{decode_u16, decode_u8};
use image::{ColorType, DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader};
use crate::files::exif;
use crate::files::jpeg::read_jpeg;
use std::io::{BufRead, BufReader, Cursor, Read, Seek, SeekFrom};

/// Limits on one decoded file.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// largest accepted width x height
    pub max_pixels: u64,
    /// memory budget in bytes (also the decoders' allocation limit)
    pub max_memory: u64,
}

/// What the header says, before the pixels are decoded.
#[derive(Debug, Clone, Copy)]
pub struct Header {
    /// rows after orientation
    pub height: usize,
    /// columns after orientation
    pub width: usize,
    /// decoded bytes per pixel
    pub bpp: u64,
    /// the decoded buffer is already 3-channel
    pub is_rgb: bool,
    /// a rotation or flip will be applied (EXIF orientation)
    pub oriented: bool,
}

/// The bytes a pixel of colour type `ct` decodes to, and whether the
/// decoded buffer is already three channels ([`Header`]'s `bpp` and
/// `is_rgb`): a JPEG decoder holds its component planes (as many bytes
/// again) beside the interleaved output while it works, so it never is.
pub fn decoded_layout(ct: ColorType, jpeg: bool) -> (u64, bool) {
    let is_rgb = matches!(ct, ColorType::Rgb8 | ColorType::Rgb16 | ColorType::Rgb32F) && !jpeg;
    (u64::from(ct.bytes_per_pixel()), is_rgb)
}

/// A decoded input: H x W x 3 values in [0, 1] and where they came from.
#[derive(Debug, Clone)]
pub struct Decoded {
    /// interleaved RGB, linear unless decoded with `linearize = false`
    pub data: Vec<f32>,
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// "PNG", "JPEG" or "TIFF"
    pub format: &'static str,
    /// bits per sample of the file: 8, 16 or 32 (float)
    pub bits: u8,
    /// float samples, taken as linear whatever was asked
    pub is_float: bool,
    /// the EXIF orientation that was applied (1 = none)
    pub orientation: u8,
    /// the embedded ICC profile: its description, whether the codes were
    /// converted through it (not sRGB), and why it could not be read
    pub icc_profile: Option<(String, bool, Option<String>)>,
    /// what in the metadata was ignored and why (orientation), for the
    /// sidecar's `source.notes`; the ICC profile's reason is in `icc_profile`
    pub notes: Vec<String>,
}

/// Where a classic TIFF header holds the offset of IFD0 (bytes 4-7).
const IFD0_OFFSET_AT: u64 = 4;

/// A reader that presents a classic TIFF `inner` with `ifd0` (the offset
/// of another IFD, in the file's byte order) in its header when given: a
/// TIFF whose first IFD is a thumbnail is shown to the decoder with IFD0
/// being the full image.
struct Patched<R> {
    inner: R,
    ifd0: Option<[u8; 4]>,
    pos: u64,
}

impl<R: Read + Seek> Patched<R> {
    fn new(inner: R, ifd0: Option<[u8; 4]>) -> Self {
        Self { inner, ifd0, pos: 0 }
    }
}

impl<R: Read + Seek> Read for Patched<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(bytes) = self.ifd0 {
            // the patched bytes this read covers
            for (k, &v) in (IFD0_OFFSET_AT..).zip(&bytes) {
                let into = k.checked_sub(self.pos).and_then(|i| usize::try_from(i).ok()).filter(|&i| i < n);
                if let Some(b) = into.and_then(|i| buf.get_mut(i)) {
                    *b = v;
                }
            }
        }
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R: Read + Seek> Seek for Patched<R> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.inner.seek(to)?;
        Ok(self.pos)
    }
}

/// A reader that presents `inner` without some byte ranges (whole PNG
/// chunks the pixel decoder must not inflate or hold: the ICC profile,
/// read with a cap by `files::exif`, and oversized text and EXIF chunks).
struct Without<R> {
    inner: R,
    /// (start, length) in `inner`, sorted, not overlapping
    holes: Vec<(u64, u64)>,
    /// position as presented
    pos: u64,
    /// length as presented
    len: u64,
    /// where `inner` is (seeks are saved when reads follow each other)
    at: Option<u64>,
}

impl<R: Read + Seek> Without<R> {
    fn new(mut inner: R, holes: Vec<(u64, u64)>) -> std::io::Result<Self> {
        let total = inner.seek(SeekFrom::End(0))?;
        let len = total.saturating_sub(holes.iter().map(|h| h.1).sum());
        inner.seek(SeekFrom::Start(0))?;
        Ok(Self { inner, holes, pos: 0, len, at: Some(0) })
    }

    /// The position in `inner` of the presented position `pos`, and how
    /// many bytes may be read from there before the next hole.
    fn map(&self, pos: u64) -> (u64, u64) {
        let mut phys = pos;
        for &(start, n) in &self.holes {
            if phys < start {
                return (phys, start - phys);
            }
            phys += n;
        }
        (phys, u64::MAX)
    }
}

impl<R: Read + Seek> Read for Without<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let (phys, room) = self.map(self.pos);
        if self.at != Some(phys) {
            self.at = None;
            self.inner.seek(SeekFrom::Start(phys))?;
        }
        let n = buf.len().min(usize::try_from(room).unwrap_or(usize::MAX));
        let got = self.inner.read(buf.get_mut(..n).unwrap_or_default());
        let got = got.inspect_err(|_| self.at = None)?;
        self.pos += got as u64;
        self.at = Some(phys + got as u64);
        Ok(got)
    }
}

impl<R: Read + Seek> Seek for Without<R> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let target = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.len.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos = target.ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "seek before the start"))?;
        Ok(self.pos)
    }
}

/// The largest ICC profile held for an input: [`exif::MAX_BLOCK`], and at
/// most a sixteenth of the memory budget (it is counted in the budget).
fn icc_cap(limits: &Limits) -> u64 {
    exif::MAX_BLOCK.min(limits.max_memory / 16)
}

fn image_error(e: ImageError) -> Failure {
    match e {
        ImageError::Limits(l) => Failure::new(Kind::Budget, format!("decoder limit: {l}")),
        ImageError::Unsupported(u) => Failure::new(Kind::Input, format!("unsupported: {u}")),
        // the I/O error's own words ("failed to fill whole buffer") say nothing of the file
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Failure::new(
            Kind::Input,
            "cannot decode: the file ends before its image data does (truncated, or its offsets point past its end)",
        ),
        other => Failure::new(Kind::Input, format!("cannot decode: {other}")),
    }
}

/// The pixel limit (`--max-pixels`) checked on a header's size.
fn too_many_pixels(w: u32, h: u32, limits: &Limits) -> Result<(), Failure> {
    let pixels = u64::from(w) * u64::from(h);
    if pixels > limits.max_pixels {
        return Err(Failure::new(
            Kind::Budget,
            format!("{w}x{h} = {pixels} pixels is over the limit of {} pixels (--max-pixels)", limits.max_pixels),
        ));
    }
    Ok(())
}

/// The metadata read before the pixels: the orientation (1 when not
/// oriented) and why it was taken so, and the ICC profile (None: none;
/// Err: refused, with the reason; Ok(None): left to the decoder).
struct Meta {
    orientation: u8,
    notes: Vec<String>,
    /// the codes are linear light already (a PNG's gAMA of 1.0): no sRGB curve
    linear_codes: bool,
    icc: Option<Result<Option<Vec<u8>>, String>>,
}

/// Opens a decoder on `reader`, checks the header (pixel count, then the
/// caller's `check`), decodes and orients. Returns the image, its format
/// name, the orientation applied and the metadata read. The orientation
/// and the ICC profile are read by `files::exif` (bounded, one rule for
/// both commands), not by the decoders; a PNG's iCCP chunk and oversized
/// text chunks are hidden from the PNG decoder.
fn open<R: BufRead + Seek>(
    reader: R,
    limits: &Limits,
    orient: bool,
    check: impl FnOnce(&Header) -> Result<(), Failure>,
) -> Result<(DynamicImage, &'static str, Meta), Failure> {
    let io = |e: std::io::Error| Failure::new(Kind::Input, format!("cannot read: {e}"));
    let reader = ImageReader::new(reader)
        .with_guessed_format()
        .map_err(io)?;
    let cap = icc_cap(limits);
    let oriented = |r: &mut dyn FnMut() -> (u8, Option<String>)| if orient { r() } else { (1, None) };
    match reader.format() {
        Some(ImageFormat::Jpeg) => {
            let bytes = read_jpeg(reader.into_inner(), limits)?;
            let (orientation, note) = oriented(&mut || exif::orientation_of(&bytes));
            let icc = exif::jpeg(&mut Cursor::new(&bytes), cap).icc.map(|r| r.map(Some));
            let reader = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Jpeg);
            open_reader(reader, limits, Meta { orientation, notes: note.into_iter().collect(), linear_codes: false, icc }, check, None)
        }
        Some(ImageFormat::Png) => {
            let mut inner = reader.into_inner();
            // the PNG decoder reads up to the first data chunk before it
            // tells the size: a header claiming an absurd size is refused
            // from IHDR
            let mut head = [0u8; 24];
            let got = inner.read(&mut head).map_err(io)?;
            inner.seek(SeekFrom::Start(0)).map_err(io)?;
            let mut ihdr = None;
            if got == head.len() && &head[12..16] == b"IHDR" {
                let be = |b: &[u8]| b.first_chunk::<4>().map_or(0, |&b| u32::from_be_bytes(b));
                let (w, h) = (be(&head[16..20]), be(&head[20..24]));
                too_many_pixels(w, h, limits)?;
                ihdr = Some((w, h));
            }
            let (orientation, note) = oriented(&mut || exif::orientation_from(&mut inner));
            let (found, holes) = exif::png(&mut inner, cap);
            let (mut notes, linear_codes) = png_colour(&found);
            if found.animated {
                notes.push("an animated PNG: its first frame is read".into());
            }
            if let Some(n) = note {
                notes.insert(0, n);
            }
            let icc = found.icc.map(|r| r.map(Some));
            inner.seek(SeekFrom::Start(0)).map_err(io)?;
            let hidden = BufReader::new(Without::new(inner, holes).map_err(io)?);
            let reader = ImageReader::with_format(hidden, ImageFormat::Png);
            open_reader(reader, limits, Meta { orientation, notes, linear_codes, icc }, check, ihdr)
        }
        Some(ImageFormat::Tiff) => {
            let mut inner = reader.into_inner();
            exif::tiff_structure(&mut inner).map_err(|why| Failure::new(Kind::Input, format!("a damaged TIFF: {why}")))?;
            // the image decoded: not a thumbnail stored first, nor integers taken for floats
            let pick = exif::ReaderSource::new(&mut inner)
                .map_err(io)
                .and_then(|mut s| exif::tiff_pick(&mut s).map_err(|why| Failure::new(Kind::Input, why)))?;
            let mut notes: Vec<String> = Vec::new();
            let mut ifd0 = None;
            if let Some(p) = &pick {
                if p.offset != p.first {
                    notes.push(format!(
                        "the file's first image is a reduced-resolution one (a thumbnail); its full-resolution image (IFD {}) is read",
                        p.index
                    ));
                    let at = u32::try_from(p.offset).unwrap_or(0);
                    ifd0 = Some(if p.little_endian { at.to_le_bytes() } else { at.to_be_bytes() });
                }
                if p.pages > 1 {
                    notes.push(format!("the file holds {} full-resolution images; the first is read", p.pages));
                }
            }
            // from here on the file is seen with the picked image first: its
            // orientation, its XMP and its layout are the ones read
            inner.seek(SeekFrom::Start(0)).map_err(io)?;
            let mut inner = BufReader::new(Patched::new(inner, ifd0));
            let (orientation, note) = oriented(&mut || exif::orientation_from(&mut inner));
            if let Some(n) = note {
                notes.insert(0, n);
            }
            // what the file holds, read before the decoder takes the reader:
            // its words for a layout it cannot read are its own type names
            // ("color type Unknown(16)")
            let layout = exif::ReaderSource::new(&mut inner).ok().and_then(|mut s| exif::tiff_layout(&mut s));
            inner.seek(SeekFrom::Start(0)).map_err(io)?;
            let reader = ImageReader::with_format(inner, ImageFormat::Tiff);
            open_reader(reader, limits, Meta { orientation, notes, linear_codes: false, icc: Some(Ok(None)) }, check, None).map_err(|f| {
                match layout {
                    Some(l) if f.kind == Kind::Input && f.message.starts_with("unsupported") => Failure::new(
                        Kind::Input,
                        format!(
                            "unsupported TIFF layout: {l}; gray, RGB, RGBA and CMYK of 8 or 16 bits, and RGB of \
                             32-bit floats, are read ({})",
                            f.message
                        ),
                    ),
                    _ => f,
                }
            })
        }
        _ => {
            // BigTIFF ("II+", "MM\0+"): a TIFF the decoder does not recognise; say so, not "unrecognised"
            let guessed = reader.format();
            let mut inner = reader.into_inner();
            let mut sig = [0u8; 4];
            let got = inner.read(&mut sig).map_err(io)?;
            if got == 4 && (&sig == b"II+\0" || &sig == b"MM\0+") {
                return Err(Failure::new(Kind::Input, "a BigTIFF file: not read (save it as a classic TIFF, PNG or JPEG)"));
            }
            inner.seek(SeekFrom::Start(0)).map_err(io)?;
            let mut reader = ImageReader::new(inner);
            if let Some(f) = guessed {
                reader.set_format(f);
            }
            open_reader(reader, limits, Meta { orientation: 1, notes: Vec::new(), linear_codes: false, icc: None }, check, None)
        }
    }
}

/// `ihdr`: a PNG's size from its header chunk. The PNG decoder reads up to
/// the first data chunk before it starts; when it fails there, the memory
/// plan is still checked from that size (RGBA 16-bit, the most a PNG
/// decodes to), so that a file over the budget is reported as such.
fn open_reader<R: BufRead + Seek>(
    reader: ImageReader<R>,
    limits: &Limits,
    mut meta: Meta,
    check: impl FnOnce(&Header) -> Result<(), Failure>,
    ihdr: Option<(u32, u32)>,
) -> Result<(DynamicImage, &'static str, Meta), Failure> {
    let format = match reader.format() {
        Some(ImageFormat::Png) => "PNG",
        Some(ImageFormat::Jpeg) => "JPEG",
        Some(ImageFormat::Tiff) => "TIFF",
        Some(f) => {
            return Err(Failure::new(
                Kind::Input,
                format!("unsupported format {f:?}: PNG, JPEG and TIFF are read"),
            ))
        }
        None => {
            return Err(Failure::new(
                Kind::Input,
                "not a PNG, JPEG or TIFF file (unrecognised signature)",
            ))
        }
    };
    let side = u32::try_from(limits.max_pixels).unwrap_or(u32::MAX);
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(side);
    lim.max_image_height = Some(side);
    // the ICC profile already held is part of the budget
    let held = match &meta.icc {
        Some(Ok(Some(p))) => p.len() as u64,
        _ => 0,
    };
    lim.max_alloc = Some(limits.max_memory.saturating_sub(held));
    let mut reader = reader;
    reader.limits(lim);
    let mut decoder = match reader.into_decoder() {
        Ok(d) => d,
        Err(e) => {
            if let Some((w, h)) = ihdr {
                check(&Header { height: h as usize, width: w as usize, bpp: 8, is_rgb: false, oriented: false })?;
            }
            return Err(image_error(e));
        }
    };
    let (w, h) = decoder.dimensions();
    too_many_pixels(w, h, limits)?;
    if w == 0 || h == 0 {
        return Err(Failure::new(Kind::Input, format!("empty image ({w}x{h})")));
    }
    let orientation = image::metadata::Orientation::from_exif(meta.orientation)
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let code = orientation.to_exif();
    let swap = matches!(code, 5..=8);
    let ct = decoder.color_type();
    let (height, width) = if swap { (w, h) } else { (h, w) };
    let (bpp, is_rgb) = decoded_layout(ct, format == "JPEG");
    check(&Header { height: height as usize, width: width as usize, bpp, is_rgb, oriented: code != 1 })?;
    // TIFF: the decoder's profile (its tag values are bounded by the decoder's limits), capped alike
    if let Some(Ok(None)) = meta.icc {
        meta.icc = match decoder.icc_profile() {
            Ok(Some(p)) if p.len() as u64 > icc_cap(limits) => {
                Some(Err(format!("the ICC profile is {} bytes, over {}", p.len(), icc_cap(limits))))
            }
            Ok(Some(p)) => Some(Ok(Some(p))),
            Ok(None) => None,
            Err(e) => Some(Err(format!("the ICC profile cannot be read ({e})"))),
        };
    }
    let mut img = DynamicImage::from_decoder(decoder).map_err(image_error)?;
    img.apply_orientation(orientation);
    Ok((img, format, meta))
}

/// What a PNG's own colour chunks say, when no ICC profile or sRGB chunk
/// overrides them (the PNG rule): notes, and whether its codes are linear
/// light. A gAMA of 1.0 (within 1%) is applied: the codes are read without
/// the sRGB curve. Another gAMA than sRGB's 1/2.2 and a cICP chunk
/// (BT.2020, PQ, ...) are not applied, and said: the codes are read as sRGB.
fn png_colour(found: &exif::Found) -> (Vec<String>, bool) {
    if found.icc.is_some() || found.srgb {
        return (Vec::new(), false);
    }
    if let Some([primaries, transfer, _, _]) = found.cicp {
        return (
            vec![format!(
                "the PNG's cICP chunk (colour primaries {primaries}, transfer {transfer}) is not applied: its codes are read as sRGB"
            )],
            false,
        );
    }
    match found.gamma.map(|g| f64::from(g) / 100_000.0) {
        Some(g) if (g - 1.0).abs() <= 0.01 => (
            vec!["the PNG's gAMA chunk says its codes are linear light (gamma 1.0): read without the sRGB curve".into()],
            true,
        ),
        Some(g) if (g - 1.0 / 2.2).abs() > 0.005 => {
            (vec![format!("the PNG's gAMA chunk ({g:.5}) is not applied: its codes are read as sRGB")], false)
        }
        _ => (Vec::new(), false),
    }
}

/// The share of the pixels that are not fully opaque, when the image has
/// an alpha channel and some are (the restoration takes every pixel as
/// scene: the user is told).
fn not_opaque(img: &DynamicImage) -> Option<f64> {
    let n = (img.width() as usize * img.height() as usize).max(1) as f64;
    let count = match img {
        DynamicImage::ImageLumaA8(b) => b.pixels().filter(|p| p.0[1] < u8::MAX).count(),
        DynamicImage::ImageRgba8(b) => b.pixels().filter(|p| p.0[3] < u8::MAX).count(),
        DynamicImage::ImageLumaA16(b) => b.pixels().filter(|p| p.0[1] < u16::MAX).count(),
        DynamicImage::ImageRgba16(b) => b.pixels().filter(|p| p.0[3] < u16::MAX).count(),
        DynamicImage::ImageRgba32F(b) => b.pixels().filter(|p| p.0[3] < 1.0).count(),
        _ => 0,
    };
    (count > 0).then(|| count as f64 / n)
}

/// Decodes one file's bytes from `reader` to H x W x 3 values in [0, 1],
/// through the inverse sRGB curve when `linearize`. `check` sees the header
/// before the pixels are decoded and may refuse it (the memory plan).
pub fn decode<R: BufRead + Seek>(
    reader: R,
    limits: &Limits,
    linearize: bool,
    check: impl FnOnce(&Header) -> Result<(), Failure>,
) -> Result<Decoded, Failure> {
    let (img, format, mut meta) = open(reader, limits, true, check)?;
    let (height, width) = (img.height() as usize, img.width() as usize);
    if let Some(share) = not_opaque(&img) {
        meta.notes.push(format!(
            "the alpha channel is ignored: {:.1}% of the pixels are not opaque, and are restored as scene",
            100.0 * share
        ));
    }
    let (icc, refused) = match meta.icc {
        Some(Ok(p)) => (p, None),
        Some(Err(why)) => (None, Some(why)),
        None => (None, None),
    };
    // a profile other than sRGB: its codes go to the working space through it (src/files/icc.rs)
    let (mut profile, convert) = match icc.as_deref().map(crate::files::icc::classify) {
        None => (refused.map(|why| (String::new(), false, Some(why))), false),
        Some(crate::files::icc::Profile::Srgb(name)) => (Some((name, false, None)), false),
        Some(crate::files::icc::Profile::Other(name)) => (Some((name, true, None)), true),
        Some(crate::files::icc::Profile::Unreadable(why)) => (Some((String::new(), false, Some(why))), false),
    };
    // a profile that cannot be applied, or that makes the image degenerate,
    // is ignored (the codes read as sRGB), never a failure of the photo
    let mut ignore = |why: String| {
        if let Some(p) = profile.as_mut() {
            p.1 = false;
            p.2 = Some(why);
        }
    };
    let (data, bits) = match img.color() {
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 if convert => {
            let codes = img.into_rgb8();
            let (v, why) = through_profile(codes.as_raw(), 255.0, icc.as_deref().unwrap_or_default(), linearize, decode_u8);
            if let Some(why) = why {
                ignore(why);
            }
            (v, 8)
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 if convert => {
            let codes = img.into_rgb16();
            let (v, why) = through_profile(codes.as_raw(), 65535.0, icc.as_deref().unwrap_or_default(), linearize, decode_u16);
            if let Some(why) = why {
                ignore(why);
            }
            (v, 16)
        }
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 => {
            (decode_u8(img.into_rgb8().as_raw(), linearize && !meta.linear_codes), 8)
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 => {
            (decode_u16(img.into_rgb16().as_raw(), linearize && !meta.linear_codes), 16)
        }
        ColorType::Rgb32F | ColorType::Rgba32F => (img.into_rgb32f().into_raw(), 32),
        other => {
            return Err(Failure::new(
                Kind::Input,
                format!("unsupported sample type {other:?}: 8/16-bit integer and 32-bit float images are read"),
            ))
        }
    };
    Ok(Decoded {
        data,
        height,
        width,
        format,
        bits,
        is_float: bits == 32,
        orientation: meta.orientation,
        notes: meta.notes,
        // float samples are taken as linear values, whatever their profile (as the Python reader does)
        icc_profile: if bits == 32 { None } else { profile },
    })
}

/// Per pixel: is any of its first three channels nonzero (gray + alpha
/// counts both, as `a[..., :3] != 0` does in the Python reader).
fn nonzero<T: PartialEq + Default>(raw: &[T], channels: usize) -> Vec<bool> {
    let zero = T::default();
    raw.chunks_exact(channels.max(1))
        .map(|p| p.iter().take(3).any(|v| *v != zero))
        .collect()
}

/// `codes` (full scale `full`) through the ICC profile `icc`
/// (src/files/icc.rs), or, when the profile turns out broken midway, read as
/// sRGB by `plain` with the reason. The codes are kept beside the converted
/// values, not copied a third time.
fn through_profile<T: Copy + Into<f32>>(
    codes: &[T],
    full: f32,
    icc: &[u8],
    linearize: bool,
    plain: fn(&[T], bool) -> Vec<f32>,
) -> (Vec<f32>, Option<String>) {
    let mut v: Vec<f32> = codes.iter().map(|&c| c.into() / full).collect();
    match crate::files::icc::convert(icc, &mut v, linearize) {
        Ok(()) => (v, None),
        Err(why) => {
            drop(v);
            (plain(codes, linearize), Some(why))
        }
    }
}

/// Per pixel of a JPEG mask (8-bit gray or RGB): is any of its first three
/// channels at least half the mask's brightest value. Lossy compression rings
/// around a drawn edge and turns black pixels beside it into small nonzero
/// codes, which the nonzero rule would take as true (a mask drawn 0/255 and
/// saved at quality 75 gains a band of true pixels around every shape); the
/// half-way threshold keeps the edge where it was drawn, and a mask drawn
/// 0/1 is still read as nonzero.
fn at_least_half(raw: &[u8], channels: usize) -> Vec<bool> {
    let top = raw.chunks_exact(channels.max(1)).flat_map(|p| p.iter().take(3)).copied().max().unwrap_or(0);
    let half = top.div_ceil(2).max(1);
    raw.chunks_exact(channels.max(1))
        .map(|p| p.iter().take(3).any(|v| *v >= half))
        .collect()
}

/// Whether RGBA integer samples are black everywhere while their alpha
/// varies: a mask drawn in its alpha only.
fn drawn_in_alpha<T: Copy + PartialEq + Default>(rgba: &[T]) -> bool {
    let px = rgba.as_chunks::<4>().0;
    let first = px.first().map(|&[_, _, _, a]| a);
    px.iter().all(|&[r, g, b, _]| [r, g, b] == [T::default(); 3]) && px.iter().any(|&[_, _, _, a]| Some(a) != first)
}

/// Decodes a mask image (not oriented): a pixel is true when any of its
/// first three channels is nonzero (RGBA: alpha ignored; gray + alpha:
/// either); in a JPEG, when it reaches half the mask's brightest value
/// ([`at_least_half`]). Returns (mask, height, width).
pub fn decode_mask<R: BufRead + Seek>(
    reader: R,
    limits: &Limits,
) -> Result<(Vec<bool>, usize, usize), Failure> {
    let budget = limits.max_memory;
    let (img, format, _) = open(reader, limits, false, |h| {
        let n = (h.height as u64).saturating_mul(h.width as u64);
        // decoded + converted (6 bytes per pixel) + the bools
        let need = n.saturating_mul(h.bpp.saturating_mul(2).saturating_add(7));
        if need > budget {
            return Err(Failure::new(
                Kind::Budget,
                format!("mask of {}x{} pixels needs about {need} bytes, over --max-memory {budget}", h.width, h.height),
            ));
        }
        Ok(())
    })?;
    let (h, w) = (img.height() as usize, img.width() as usize);
    let c = usize::from(img.color().channel_count());
    // a mask drawn in the alpha of a black image reads as all false: say why
    let alpha_only = match &img {
        DynamicImage::ImageRgba8(b) => drawn_in_alpha(b.as_raw()),
        DynamicImage::ImageRgba16(b) => drawn_in_alpha(b.as_raw()),
        _ => false,
    };
    if alpha_only {
        return Err(Failure::new(
            Kind::Input,
            "the mask's colour is black everywhere and only its alpha varies: a mask is read from its colour \
             (nonzero = true), not from its alpha",
        ));
    }
    let mask = match img {
        DynamicImage::ImageLuma8(b) if format == "JPEG" => at_least_half(b.as_raw(), c),
        DynamicImage::ImageRgb8(b) if format == "JPEG" => at_least_half(b.as_raw(), c),
        DynamicImage::ImageLuma8(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageLumaA8(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgb8(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgba8(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageLuma16(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageLumaA16(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgb16(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgba16(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgb32F(b) => nonzero(b.as_raw(), c),
        DynamicImage::ImageRgba32F(b) => nonzero(b.as_raw(), c),
        other => nonzero(other.into_rgb16().as_raw(), 3),
    };
    Ok((mask, h, w))
}

#[cfg(test)]
mod tests {
    use super::*;

    const NO_LIMIT: Limits = Limits {
        max_pixels: 1 << 40,
        max_memory: 1 << 40,
    };

    fn png(w: u32, h: u32, ct: image::ExtendedColorType, data: &[u8]) -> Vec<u8> {
        use image::ImageEncoder;
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(data, w, h, ct)
            .unwrap();
        out
    }

    #[test]
    fn gray_is_replicated_and_alpha_dropped() {
        let g = png(2, 1, image::ExtendedColorType::L8, &[0, 255]);
        let d = decode(Cursor::new(g), &NO_LIMIT, false, |_| Ok(())).unwrap();
        assert_eq!(d.data, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        assert_eq!((d.format, d.bits, d.orientation), ("PNG", 8, 1));
        let rgba = png(1, 1, image::ExtendedColorType::Rgba8, &[255, 0, 51, 0]);
        let d = decode(Cursor::new(rgba), &NO_LIMIT, false, |_| Ok(())).unwrap();
        assert_eq!(d.data, vec![1.0, 0.0, 0.2]);
    }

    #[test]
    fn sixteen_bit_codes_are_kept() {
        // PNG stores big-endian; the encoder takes native-endian u16 bytes
        let px: [u16; 3] = [0, 32768, 65535];
        let bytes: Vec<u8> = px.iter().flat_map(|v| v.to_ne_bytes()).collect();
        let f = png(1, 1, image::ExtendedColorType::Rgb16, &bytes);
        let d = decode(Cursor::new(f), &NO_LIMIT, true, |_| Ok(())).unwrap();
        assert_eq!(d.bits, 16);
        assert_eq!(d.data, decode_u16(&px, true));
    }

    #[test]
    fn limits_refuse_before_decoding() {
        let f = png(4, 3, image::ExtendedColorType::Rgb8, &[7; 36]);
        let lim = Limits {
            max_pixels: 11,
            ..NO_LIMIT
        };
        let e = decode(Cursor::new(f.clone()), &lim, true, |_| Ok(())).unwrap_err();
        assert_eq!(e.kind, Kind::Budget);
        let e = decode(Cursor::new(f), &NO_LIMIT, true, |h| {
            assert_eq!((h.height, h.width, h.bpp, h.is_rgb), (3, 4, 3, true));
            Err(Failure::new(Kind::Budget, "no"))
        })
        .unwrap_err();
        assert_eq!(e.message, "no");
    }

    #[test]
    fn garbage_is_an_input_error() {
        for bytes in [&b""[..], b"hello", b"\x89PNG\r\n\x1a\n\0\0"] {
            let e = decode(Cursor::new(bytes), &NO_LIMIT, true, |_| Ok(())).unwrap_err();
            assert_eq!(e.kind, Kind::Input, "{bytes:?}: {e}");
        }
    }

    #[test]
    fn mask_nonzero_is_used() {
        let f = png(3, 1, image::ExtendedColorType::Rgb8, &[0, 0, 0, 0, 1, 0, 9, 9, 9]);
        let (m, h, w) = decode_mask(Cursor::new(f), &NO_LIMIT).unwrap();
        assert_eq!((m, h, w), (vec![false, true, true], 1, 3));
        let f = png(3, 1, image::ExtendedColorType::Rgba8, &[0, 0, 0, 9, 0, 2, 0, 0, 1, 1, 1, 0]);
        let (m, _, _) = decode_mask(Cursor::new(f), &NO_LIMIT).unwrap();
        assert_eq!(m, vec![false, true, true]);
        let f = png(2, 1, image::ExtendedColorType::La8, &[0, 5, 0, 0]);
        let (m, _, _) = decode_mask(Cursor::new(f), &NO_LIMIT).unwrap();
        assert_eq!(m, vec![true, false]);
    }

    /// A JPEG mask: a disc drawn 0/`on` on a gray 80 x 60 image, saved at
    /// quality 75, and the disc itself.
    fn jpeg_disc(on: u8) -> (Vec<u8>, Vec<bool>) {
        let (w, h) = (80u32, 60u32);
        let disc: Vec<bool> = (0..h * w)
            .map(|i| {
                let (y, x) = (f64::from(i / w), f64::from(i % w));
                (y - 29.3).powi(2) + (x - 37.6).powi(2) <= 19.5f64.powi(2)
            })
            .collect();
        let px: Vec<u8> = disc.iter().map(|&d| if d { on } else { 0 }).collect();
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 75)
            .encode(&px, w, h, image::ExtendedColorType::L8)
            .unwrap();
        (out, disc)
    }

    #[test]
    fn a_jpeg_mask_keeps_its_drawn_edge() {
        let (f, disc) = jpeg_disc(255);
        // what a nonzero reading of the same codes would give: the ringing band
        let ringing = {
            let img = image::load_from_memory(&f).unwrap().into_luma8();
            img.as_raw().iter().zip(&disc).filter(|&(&v, &d)| (v != 0) != d).count()
        };
        assert!(ringing > 100, "the encoder did not ring ({ringing} pixels): the test shows nothing");
        let (m, h, w) = decode_mask(Cursor::new(f), &NO_LIMIT).unwrap();
        assert_eq!((h, w), (60, 80));
        let wrong = m.iter().zip(&disc).filter(|(a, b)| a != b).count();
        // the disc's edge is about 120 pixels long; a pixel cut by it may go either way
        assert!(wrong <= 12, "{wrong} pixels differ from the disc drawn");
        // drawn 0/1, its codes stay at most 2: read as nonzero (half of 1 or 2 is 1)
        let (f, _) = jpeg_disc(1);
        let codes = image::load_from_memory(&f).unwrap().into_luma8().into_raw();
        assert!(codes.iter().all(|&v| v <= 2) && codes.contains(&1));
        let (m, _, _) = decode_mask(Cursor::new(f), &NO_LIMIT).unwrap();
        assert_eq!(m, codes.iter().map(|&v| v != 0).collect::<Vec<_>>());
    }

    /// A PNG of `w` x `h` RGB pixels with `chunks` (kind, data) before IDAT,
    /// framed with their CRCs by hand.
    fn png_with(w: u32, h: u32, px: &[u8], chunks: &[(&[u8; 4], Vec<u8>)]) -> Vec<u8> {
        let plain = png(w, h, image::ExtendedColorType::Rgb8, px);
        let idat = plain.windows(4).position(|c| c == b"IDAT").unwrap() - 4;
        let mut out = plain[..idat].to_vec();
        for (k, d) in chunks {
            out.extend((d.len() as u32).to_be_bytes());
            let mut kd = k.to_vec();
            kd.extend(d);
            out.extend(&kd);
            out.extend(crc32(&kd).to_be_bytes());
        }
        out.extend(&plain[idat..]);
        out
    }

    /// CRC-32 (ISO 3309, PNG's), bit by bit.
    fn crc32(data: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in data {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    fn exif_orientation_block(kind: u16, count: u32, value: [u8; 4], tail: &[u8]) -> Vec<u8> {
        let mut b = b"II*\0\x08\0\0\0\x01\0\x12\x01".to_vec();
        b.extend(kind.to_le_bytes());
        b.extend(count.to_le_bytes());
        b.extend(value);
        b.extend([0; 4]);
        b.extend(tail);
        b
    }

    #[test]
    fn orientation_stored_as_long_or_with_two_values_is_applied() {
        // 3 x 1 pixels; orientation 6 (rotate 90 clockwise) makes them 1 x 3
        let px: Vec<u8> = (0..9).map(|i| i as u8 * 20).collect();
        let cases = [
            exif_orientation_block(4, 1, 6u32.to_le_bytes(), &[]),
            exif_orientation_block(3, 2, [6, 0, 1, 0], &[]),
            // LONG x 2 out of line at 26
            exif_orientation_block(4, 2, 26u32.to_le_bytes(), &[6, 0, 0, 0, 1, 0, 0, 0]),
        ];
        for block in cases {
            let f = png_with(3, 1, &px, &[(b"eXIf", block)]);
            let d = decode(Cursor::new(f), &NO_LIMIT, false, |h| {
                assert!(h.oriented && (h.height, h.width) == (3, 1));
                Ok(())
            })
            .unwrap();
            assert_eq!((d.orientation, d.height, d.width), (6, 3, 1));
        }
        // only in XMP
        let mut itxt = b"XML:com.adobe.xmp\0\0\0\0\0".to_vec();
        itxt.extend(b"<rdf:Description tiff:Orientation=\"8\"/>");
        let d = decode(Cursor::new(png_with(3, 1, &px, &[(b"iTXt", itxt)])), &NO_LIMIT, false, |_| Ok(())).unwrap();
        assert_eq!((d.orientation, d.height, d.width), (8, 3, 1));
        // a looping EXIF block: upright, no failure
        let mut looping = exif_orientation_block(3, 1, [6, 0, 0, 0], &[]);
        looping[22..26].copy_from_slice(&8u32.to_le_bytes());
        let d = decode(Cursor::new(png_with(3, 1, &px, &[(b"eXIf", looping)])), &NO_LIMIT, false, |_| Ok(())).unwrap();
        assert_eq!(d.orientation, 6, "IFD0 itself is readable: its orientation counts");
    }

    fn iccp(profile: &[u8]) -> Vec<u8> {
        let mut d = b"p\0\0".to_vec();
        d.extend(fdeflate::compress_to_vec(profile));
        d
    }

    #[test]
    fn an_inflating_icc_chunk_is_refused_by_its_size_within_the_budget() {
        let px = [90u8, 120, 30, 10, 200, 60];
        let bomb = iccp(&vec![0u8; 64 << 20]);
        let lim = Limits { max_pixels: 1 << 20, max_memory: 512 << 20 };
        let d = decode(Cursor::new(png_with(2, 1, &px, &[(b"iCCP", bomb.clone())])), &lim, false, |_| Ok(())).unwrap();
        let (_, converted, why) = d.icc_profile.unwrap();
        assert!(!converted && why.unwrap().contains("more than"));
        assert_eq!(d.data, decode_u8(&px, false));
        // under a small budget the cap is a sixteenth of it
        let lim = Limits { max_pixels: 1 << 20, max_memory: 1 << 20 };
        let d = decode(Cursor::new(png_with(2, 1, &px, &[(b"iCCP", bomb)])), &lim, false, |_| Ok(())).unwrap();
        assert!(d.icc_profile.unwrap().2.unwrap().contains("65536"));
    }

    #[test]
    fn a_profile_that_makes_the_image_constant_or_is_not_rgb_is_ignored() {
        use moxcms::{ColorProfile, ToneReprCurve};
        let px = [90u8, 120, 30, 10, 200, 60];
        let mut flat = ColorProfile::new_adobe_rgb();
        let one = ToneReprCurve::Lut(vec![40000, 40000]);
        flat.red_trc = Some(one.clone());
        flat.green_trc = Some(one.clone());
        flat.blue_trc = Some(one);
        let flat = flat.encode().unwrap();
        let d = decode(Cursor::new(png_with(2, 1, &px, &[(b"iCCP", iccp(&flat))])), &NO_LIMIT, true, |_| Ok(())).unwrap();
        let (_, converted, why) = d.icc_profile.unwrap();
        assert!(!converted && why.unwrap().contains("one colour"));
        assert_eq!(d.data, decode_u8(&px, true));
        // the data colour space of the header (bytes 16..20) said Lab
        let mut lab = ColorProfile::new_adobe_rgb().encode().unwrap();
        lab[16..20].copy_from_slice(b"Lab ");
        let d = decode(Cursor::new(png_with(2, 1, &px, &[(b"iCCP", iccp(&lab))])), &NO_LIMIT, true, |_| Ok(())).unwrap();
        let (_, converted, why) = d.icc_profile.unwrap();
        assert!(!converted && why.unwrap().contains("not RGB"), "{:?}", d.notes);
        assert_eq!(d.data, decode_u8(&px, true));
        // a good Adobe RGB profile is still applied
        let adobe = ColorProfile::new_adobe_rgb().encode().unwrap();
        let d = decode(Cursor::new(png_with(2, 1, &px, &[(b"iCCP", iccp(&adobe))])), &NO_LIMIT, true, |_| Ok(())).unwrap();
        assert!(d.icc_profile.unwrap().1);
        assert_ne!(d.data, decode_u8(&px, true));
    }

    #[test]
    fn without_presents_the_file_minus_its_holes() {
        let data: Vec<u8> = (0..100u8).collect();
        let mut w = Without::new(Cursor::new(data.clone()), vec![(10, 5), (50, 20)]).unwrap();
        let mut all: Vec<u8> = Vec::new();
        // small reads cross the holes one piece at a time
        let mut buf = [0u8; 7];
        loop {
            let n = w.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            all.extend(&buf[..n]);
        }
        let expect: Vec<u8> = data.iter().copied().filter(|&b| !(10..15).contains(&b) && !(50..70).contains(&b)).collect();
        assert_eq!(all, expect);
        assert_eq!(w.seek(SeekFrom::End(0)).unwrap(), 75);
        w.seek(SeekFrom::Start(44)).unwrap();
        let mut b = [0u8; 3];
        w.read_exact(&mut b).unwrap();
        assert_eq!(b, [49, 70, 71]);
        w.seek(SeekFrom::Current(-4)).unwrap();
        w.read_exact(&mut b).unwrap();
        assert_eq!(b, [48, 49, 70]);
    }
}
