//! Encoding the outputs of docs/OUTPUTS.md into memory; `crate::files::commit`
//! puts them in place (temporaries, sidecar last, synced).

use crate::files::settings::Format;
use crate::error::{Failure, Kind};
use crate::files::color::{colormap, quantize_u16, quantize_u8};
use image::codecs::png::PngEncoder;
use image::codecs::tiff::TiffEncoder;
use image::{ImageBuffer, Luma, Pixel, Rgb};
use std::path::Path;

fn write_error(path: &Path, e: impl std::fmt::Display) -> Failure {
    Failure::new(Kind::Write, format!("cannot write {}: {e}", path.display()))
}

fn buffer<P: Pixel>(w: usize, h: usize, data: Vec<P::Subpixel>) -> Result<ImageBuffer<P, Vec<P::Subpixel>>, Failure> {
    let (wu, hu) = (u32::try_from(w), u32::try_from(h));
    match (wu, hu) {
        (Ok(wu), Ok(hu)) => ImageBuffer::from_raw(wu, hu, data),
        _ => None,
    }
    .ok_or_else(|| Failure::new(Kind::Internal, format!("buffer does not hold a {w}x{h} image")))
}

/// How the restored image is encoded.
#[derive(Debug, Clone, Copy)]
pub struct Encoding {
    /// file format
    pub format: Format,
    /// 8 or 16 (JPEG: always 8)
    pub bits: u8,
    /// the values are linear: apply the sRGB curve
    pub srgb: bool,
    /// JPEG quality
    pub quality: u8,
}

/// The bytes `fill` encodes into memory (an error names `path`, the file
/// they are for).
fn to_bytes(path: &Path, fill: impl FnOnce(&mut Vec<u8>) -> image::ImageResult<()>) -> Result<Vec<u8>, Failure> {
    let mut out = Vec::new();
    fill(&mut out).map_err(|e| write_error(path, e))?;
    Ok(out)
}

/// The file bytes of the restored image (interleaved RGB in [0, 1]) for `path`.
pub fn encode_image(path: &Path, data: &[f32], h: usize, w: usize, enc: Encoding) -> Result<Vec<u8>, Failure> {
    let srgb = enc.srgb;
    let wide = enc.bits == 16;
    match enc.format {
        Format::Jpg => {
            let (Ok(w16), Ok(h16)) = (u16::try_from(w), u16::try_from(h)) else {
                return Err(write_error(path, format!("{w}x{h} is larger than JPEG allows (65535 per side)")));
            };
            let codes = quantize_u8(data, srgb);
            let mut out = Vec::new();
            jpeg_encoder::Encoder::new(&mut out, enc.quality)
                .encode(&codes, w16, h16, jpeg_encoder::ColorType::Rgb)
                .map_err(|e| write_error(path, e))?;
            Ok(out)
        }
        Format::Png if wide => {
            let img = buffer::<Rgb<u16>>(w, h, quantize_u16(data, srgb))?;
            to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
        }
        Format::Png => {
            let img = buffer::<Rgb<u8>>(w, h, quantize_u8(data, srgb))?;
            to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
        }
        Format::Tiff if wide => {
            let img = buffer::<Rgb<u16>>(w, h, quantize_u16(data, srgb))?;
            to_bytes(path, |f| img.write_with_encoder(TiffEncoder::new(std::io::Cursor::new(f))))
        }
        Format::Tiff => {
            let img = buffer::<Rgb<u8>>(w, h, quantize_u8(data, srgb))?;
            to_bytes(path, |f| img.write_with_encoder(TiffEncoder::new(std::io::Cursor::new(f))))
        }
    }
}

/// The file bytes of t as 16-bit grayscale PNG: `floor(t * 65535 + 0.5)`.
pub fn encode_transmission(path: &Path, t: &[f32], h: usize, w: usize) -> Result<Vec<u8>, Failure> {
    let img = buffer::<Luma<u16>>(w, h, quantize_u16(t, false))?;
    to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
}

/// The file bytes of t through the colour map as 8-bit RGB PNG.
pub fn encode_transmission_color(path: &Path, t: &[f32], h: usize, w: usize) -> Result<Vec<u8>, Failure> {
    let img = buffer::<Rgb<u8>>(w, h, colormap(t))?;
    to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_jpeg_wider_than_the_format_allows_is_a_write_error() {
        let w = 70_000;
        let data = vec![0.5f32; 3 * w];
        let jpg = Encoding {
            format: Format::Jpg,
            bits: 8,
            srgb: true,
            quality: 95,
        };
        let e = encode_image(Path::new("wide.jpg"), &data, 1, w, jpg).unwrap_err();
        assert!(e.message.contains("larger than JPEG allows") && e.message.contains("wide.jpg"), "{}", e.message);
        // PNG holds it
        let png = Encoding { format: Format::Png, ..jpg };
        assert!(encode_image(Path::new("wide.png"), &data, 1, w, png).is_ok());
    }
}
