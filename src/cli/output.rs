//! Writing the outputs of docs/OUTPUTS.md: every file goes to a temporary
//! name in its folder and is renamed into place; a [`Transaction`] that is
//! not committed removes the files it already renamed, so a failed input
//! leaves nothing behind.

use super::args::Format;
use super::{CliError, Kind};
use crate::color::{colormap, quantize_u16, quantize_u8};
use image::codecs::png::PngEncoder;
use image::codecs::tiff::TiffEncoder;
use image::{ImageBuffer, Luma, Pixel, Rgb};
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

fn write_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::new(Kind::Write, format!("cannot write {}: {e}", path.display()))
}

/// Temporary files made by this process so far (their names' counter).
static TEMPS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Creates a new temporary file beside `path`, exclusively (`O_EXCL`: a
/// file or symlink already at that name is never opened, so a planted link
/// cannot redirect the write), under a short name `.uwhl-PID-N.tmp` that
/// fits whatever the length of the output's name (the same scheme as the
/// Python command's).
fn create_temp(path: &Path) -> Result<(PathBuf, File), CliError> {
    let pid = std::process::id();
    let mut last = None;
    for _ in 0..1000 {
        let n = TEMPS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = path.with_file_name(format!(".uwhl-{pid}-{n}.tmp"));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(write_error(&tmp, e)),
        }
    }
    Err(write_error(path, last.map_or_else(|| "no temporary name is free".to_string(), |e| e.to_string())))
}

/// The files of one input written so far; dropped without [`Transaction::commit`]
/// it removes them.
#[derive(Debug, Default)]
pub struct Transaction {
    done: Vec<PathBuf>,
    committed: bool,
}

impl Transaction {
    /// A transaction with nothing written.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `path` through `body` into a temporary file of the same folder,
    /// syncs it and renames it into place.
    pub fn write(
        &mut self,
        path: &Path,
        body: impl FnOnce(&mut BufWriter<File>) -> Result<(), CliError>,
    ) -> Result<(), CliError> {
        if path.file_name().is_none() {
            return Err(CliError::new(Kind::Internal, format!("no file name in {}", path.display())));
        }
        let (tmp, file) = create_temp(path)?;
        let result = (|| {
            let mut out = BufWriter::new(file);
            body(&mut out)?;
            out.flush().map_err(|e| write_error(&tmp, e))?;
            let file = out.into_inner().map_err(|e| write_error(&tmp, e.error()))?;
            file.sync_all().map_err(|e| write_error(&tmp, e))?;
            fs::rename(&tmp, path).map_err(|e| write_error(path, e))
        })();
        if result.is_err() {
            let _ = fs::remove_file(&tmp);
        } else {
            self.done.push(path.to_path_buf());
        }
        result
    }

    /// Keeps the written files.
    pub fn commit(mut self) {
        self.committed = true;
    }
}

impl Drop for Transaction {
    fn drop(&mut self) {
        if !self.committed {
            for p in &self.done {
                let _ = fs::remove_file(p);
            }
        }
    }
}

fn buffer<P: Pixel>(w: usize, h: usize, data: Vec<P::Subpixel>) -> Result<ImageBuffer<P, Vec<P::Subpixel>>, CliError> {
    let (wu, hu) = (u32::try_from(w), u32::try_from(h));
    match (wu, hu) {
        (Ok(wu), Ok(hu)) => ImageBuffer::from_raw(wu, hu, data),
        _ => None,
    }
    .ok_or_else(|| CliError::new(Kind::Internal, format!("buffer does not hold a {w}x{h} image")))
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
fn to_bytes(path: &Path, fill: impl FnOnce(&mut Vec<u8>) -> image::ImageResult<()>) -> Result<Vec<u8>, CliError> {
    let mut out = Vec::new();
    fill(&mut out).map_err(|e| write_error(path, e))?;
    Ok(out)
}

/// The file bytes of the restored image (interleaved RGB in [0, 1]) for `path`.
pub fn encode_image(path: &Path, data: &[f32], h: usize, w: usize, enc: Encoding) -> Result<Vec<u8>, CliError> {
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
pub fn encode_transmission(path: &Path, t: &[f32], h: usize, w: usize) -> Result<Vec<u8>, CliError> {
    let img = buffer::<Luma<u16>>(w, h, quantize_u16(t, false))?;
    to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
}

/// The file bytes of t through the colour map as 8-bit RGB PNG.
pub fn encode_transmission_color(path: &Path, t: &[f32], h: usize, w: usize) -> Result<Vec<u8>, CliError> {
    let img = buffer::<Rgb<u8>>(w, h, colormap(t))?;
    to_bytes(path, |f| img.write_with_encoder(PngEncoder::new(f)))
}

/// Writes bytes (an encoded image, the sidecar).
pub fn write_bytes(tx: &mut Transaction, path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    tx.write(path, |f| f.write_all(bytes).map_err(|e| write_error(path, e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_are_created_exclusively_under_short_names() {
        let d = std::env::temp_dir().join(format!("uwhl-tmpnames-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        // links planted at the next temporary names point outside the folder
        let victim = d.join("victim");
        fs::write(&victim, b"keep").unwrap();
        let next = TEMPS.load(std::sync::atomic::Ordering::Relaxed);
        for k in next..next + 5 {
            std::os::unix::fs::symlink(&victim, d.join(format!(".uwhl-{}-{k}.tmp", std::process::id()))).unwrap();
        }
        // an output name of 250 bytes: its temporary name still fits
        let long = d.join(format!("{}.png", "x".repeat(246)));
        let mut tx = Transaction::new();
        tx.write(&long, |f| f.write_all(b"data").map_err(|e| write_error(&long, e))).unwrap();
        tx.commit();
        assert_eq!(fs::read(&long).unwrap(), b"data");
        assert_eq!(fs::read(&victim).unwrap(), b"keep");
        let _ = fs::remove_dir_all(&d);
    }

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

    #[test]
    fn uncommitted_transaction_removes_its_files() {
        let dir = std::env::temp_dir().join(format!("uwhl-tx-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.txt"), dir.join("b.txt"));
        {
            let mut tx = Transaction::new();
            write_bytes(&mut tx, &a, b"1").unwrap();
            let e = tx.write(&b, |_| Err(CliError::new(Kind::Write, "disk full")));
            assert!(e.is_err());
            assert!(a.exists() && !b.exists());
        }
        assert!(!a.exists());
        let mut tx = Transaction::new();
        write_bytes(&mut tx, &a, b"2").unwrap();
        tx.commit();
        assert_eq!(fs::read(&a).unwrap(), b"2");
        // no temporary file is left
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(&dir).unwrap();
    }
}
