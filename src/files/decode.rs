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
use std::io::{BufRead, Cursor, Seek};

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
}

fn image_error(e: ImageError) -> Failure {
    match e {
        ImageError::Limits(l) => Failure::new(Kind::Budget, format!("decoder limit: {l}")),
        ImageError::Unsupported(u) => Failure::new(Kind::Input, format!("unsupported: {u}")),
        other => Failure::new(Kind::Input, format!("cannot decode: {other}")),
    }
}

/// Whether a JPEG stream is complete: an end-of-image marker (FF D9)
/// follows its last start-of-scan marker (FF DA). Inside entropy-coded data
/// 0xFF is always followed by 0x00 or a restart marker, so the only FF D9
/// after the last scan header is the real end. The JPEG decoder fills a
/// truncated scan with gray and reports success; a cut-off frame must be an
/// error instead (Pillow refuses it too).
pub fn jpeg_complete(bytes: &[u8]) -> bool {
    let last_sos = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    match last_sos.and_then(|i| bytes.get(i..)) {
        Some(tail) => tail.windows(2).any(|w| w == [0xFF, 0xD9]),
        None => false,
    }
}

/// Reads a whole JPEG file (bounded by the memory budget) and checks that it
/// is complete; the JPEG decoder holds the whole file in memory anyway.
fn read_jpeg<R: BufRead + Seek>(mut reader: R, limits: &Limits) -> Result<Vec<u8>, Failure> {
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
    if !jpeg_complete(&bytes) {
        return Err(Failure::new(
            Kind::Input,
            "cannot decode: truncated JPEG (no end-of-image marker after the last scan)",
        ));
    }
    Ok(bytes)
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

/// Opens a decoder on `reader`, checks the header (pixel count, then the
/// caller's `check`), decodes and orients. Returns the image, its format
/// name and the EXIF orientation code applied.
fn open<R: BufRead + Seek>(
    reader: R,
    limits: &Limits,
    orient: bool,
    check: impl FnOnce(&Header) -> Result<(), Failure>,
) -> Result<(DynamicImage, &'static str, u8, Option<Vec<u8>>), Failure> {
    let reader = ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| Failure::new(Kind::Input, format!("cannot read: {e}")))?;
    if reader.format() == Some(ImageFormat::Png) {
        // the PNG decoder reads up to the first data chunk before it tells
        // the size: a header claiming an absurd size is refused from IHDR
        let mut r = reader.into_inner();
        let mut head = [0u8; 24];
        let got = r.read(&mut head).map_err(|e| Failure::new(Kind::Input, format!("cannot read: {e}")))?;
        r.seek(std::io::SeekFrom::Start(0)).map_err(|e| Failure::new(Kind::Input, format!("cannot read: {e}")))?;
        let mut ihdr = None;
        if got == head.len() && &head[12..16] == b"IHDR" {
            let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
            let (w, h) = (be(&head[16..20]), be(&head[20..24]));
            too_many_pixels(w, h, limits)?;
            ihdr = Some((w, h));
        }
        return open_reader(ImageReader::with_format(r, ImageFormat::Png), limits, orient, check, ihdr);
    }
    if reader.format() == Some(ImageFormat::Jpeg) {
        let bytes = read_jpeg(reader.into_inner(), limits)?;
        let reader = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Jpeg);
        return open_reader(reader, limits, orient, check, None);
    }
    open_reader(reader, limits, orient, check, None)
}

/// `ihdr`: a PNG's size from its header chunk. The PNG decoder reads up to
/// the first data chunk before it starts; when it fails there, the memory
/// plan is still checked from that size (RGBA 16-bit, the most a PNG
/// decodes to), so that a file over the budget is reported as such.
fn open_reader<R: BufRead + Seek>(
    reader: ImageReader<R>,
    limits: &Limits,
    orient: bool,
    check: impl FnOnce(&Header) -> Result<(), Failure>,
    ihdr: Option<(u32, u32)>,
) -> Result<(DynamicImage, &'static str, u8, Option<Vec<u8>>), Failure> {
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
    lim.max_alloc = Some(limits.max_memory);
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
    // A damaged EXIF block is not worth refusing the picture for.
    let orientation = if orient {
        decoder
            .orientation()
            .unwrap_or(image::metadata::Orientation::NoTransforms)
    } else {
        image::metadata::Orientation::NoTransforms
    };
    let code = orientation.to_exif();
    let swap = matches!(code, 5..=8);
    let ct = decoder.color_type();
    let (height, width) = if swap { (w, h) } else { (h, w) };
    check(&Header {
        height: height as usize,
        width: width as usize,
        bpp: u64::from(ct.bytes_per_pixel()),
        // a JPEG decoder holds its component planes (as many bytes again)
        // beside the interleaved output while it works
        is_rgb: matches!(ct, ColorType::Rgb8 | ColorType::Rgb16 | ColorType::Rgb32F) && format != "JPEG",
        oriented: code != 1,
    })?;
    // a damaged profile is not either: the image is then read as sRGB
    let icc = decoder.icc_profile().ok().flatten();
    let mut img = DynamicImage::from_decoder(decoder).map_err(image_error)?;
    img.apply_orientation(orientation);
    Ok((img, format, code, icc))
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
    let (img, format, orientation, icc) = open(reader, limits, true, check)?;
    let (height, width) = (img.height() as usize, img.width() as usize);
    // a profile other than sRGB: its codes go to the working space through it (src/files/icc.rs)
    let (profile, convert) = match icc.as_deref().map(crate::files::icc::classify) {
        None => (None, false),
        Some(crate::files::icc::Profile::Srgb(name)) => (Some((name, false, None)), false),
        Some(crate::files::icc::Profile::Other(name)) => (Some((name, true, None)), true),
        Some(crate::files::icc::Profile::Unreadable(why)) => (Some((String::new(), false, Some(why))), false),
    };
    let through = |codes: Vec<f32>| -> Result<Vec<f32>, Failure> {
        let mut v = codes;
        crate::files::icc::convert(icc.as_deref().unwrap_or_default(), &mut v, linearize)
            .map_err(|e| Failure::new(Kind::Input, e))?;
        Ok(v)
    };
    let (data, bits) = match img.color() {
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 if convert => {
            (through(img.into_rgb8().as_raw().iter().map(|&c| f32::from(c) / 255.0).collect())?, 8)
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 if convert => {
            (through(img.into_rgb16().as_raw().iter().map(|&c| f32::from(c) / 65535.0).collect())?, 16)
        }
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 => {
            (decode_u8(img.into_rgb8().as_raw(), linearize), 8)
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 => {
            (decode_u16(img.into_rgb16().as_raw(), linearize), 16)
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
        orientation,
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

/// Decodes a mask image (not oriented): a pixel is true when any of its
/// first three channels is nonzero (RGBA: alpha ignored; gray + alpha:
/// either). Returns (mask, height, width).
pub fn decode_mask<R: BufRead + Seek>(
    reader: R,
    limits: &Limits,
) -> Result<(Vec<bool>, usize, usize), Failure> {
    let budget = limits.max_memory;
    let (img, _, _, _) = open(reader, limits, false, |h| {
        let n = (h.height as u64).saturating_mul(h.width as u64);
        // decoded + converted (6 bytes per pixel) + the bools
        let need = n.saturating_mul(h.bpp.saturating_mul(2).saturating_add(7));
        if need > budget {
            return Err(Failure::new(
                Kind::Budget,
                format!("mask of {}x{} pixels needs about {need} bytes, over --max-memory {budget}", h.height, h.width),
            ));
        }
        Ok(())
    })?;
    let (h, w) = (img.height() as usize, img.width() as usize);
    let c = usize::from(img.color().channel_count());
    let mask = match img {
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
    fn truncated_jpeg_is_an_input_error() {
        use image::ImageEncoder;
        let px: Vec<u8> = (0..16 * 16 * 3).map(|i| (i * 7 % 251) as u8).collect();
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 90)
            .write_image(&px, 16, 16, image::ExtendedColorType::Rgb8)
            .unwrap();
        assert!(jpeg_complete(&jpg));
        let d = decode(Cursor::new(jpg.clone()), &NO_LIMIT, true, |_| Ok(())).unwrap();
        assert_eq!((d.format, d.height, d.width), ("JPEG", 16, 16));
        let cut = &jpg[..jpg.len() - 10];
        assert!(!jpeg_complete(cut));
        let e = decode(Cursor::new(cut), &NO_LIMIT, true, |_| Ok(())).unwrap_err();
        assert_eq!(e.kind, Kind::Input);
        assert!(e.message.contains("truncated"), "{e}");
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
}
