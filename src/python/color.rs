//! pyo3 bindings (feature "python") of [`crate::files::color`]: the pixel
//! conventions the Python I/O layer shares with the `uwhl-rs` binary
//! (docs/OUTPUTS.md). Each call releases the GIL.

use crate::files::color;
use crate::files::transfer::{Codec, Transfer};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

fn slice<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'a, T>, what: &str) -> PyResult<&'a [T]> {
    a.as_slice()
        .map_err(|_| PyValueError::new_err(format!("{what} must be C-contiguous")))
}

fn same_shape<'py, T: numpy::Element>(
    py: Python<'py>,
    v: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    PyArray1::from_vec(py, v).reshape(shape)
}

fn rgb_shape(shape: &[usize], what: &str) -> PyResult<()> {
    if shape.len() != 3 || shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "{what} has shape {shape:?}; expected (H, W, 3)"
        )));
    }
    Ok(())
}

/// 16-bit codes (any shape) to float32 in [0, 1], through the inverse sRGB curve when `linearize`.
#[pyfunction]
fn _decode_u16<'py>(
    py: Python<'py>,
    codes: PyReadonlyArrayDyn<'py, u16>,
    linearize: bool,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let s = slice(&codes, "codes")?;
    let v = py.detach(|| color::decode_u16(s, linearize));
    same_shape(py, v, codes.shape())
}

/// float32 values (any shape) to uint8 or uint16 codes (`bits` 8 or 16),
/// through the sRGB curve when `srgb`.
#[pyfunction]
fn _quantize<'py>(
    py: Python<'py>,
    data: PyReadonlyArrayDyn<'py, f32>,
    bits: u32,
    srgb: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let s = slice(&data, "data")?;
    let shape = data.shape().to_vec();
    match bits {
        8 => Ok(same_shape(py, py.detach(|| color::quantize_u8(s, srgb)), &shape)?.into_any()),
        16 => Ok(same_shape(py, py.detach(|| color::quantize_u16(s, srgb)), &shape)?.into_any()),
        _ => Err(PyValueError::new_err(format!("bits must be 8 or 16, got {bits}"))),
    }
}

/// A transmission map (H, W) to its colour-mapped uint8 image (H, W, 3).
#[pyfunction]
fn _colormap<'py>(
    py: Python<'py>,
    t: PyReadonlyArrayDyn<'py, f32>,
) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
    let s = slice(&t, "t")?;
    let mut shape = t.shape().to_vec();
    shape.push(3);
    let v = py.detach(|| color::colormap(s));
    same_shape(py, v, &shape)
}

/// Block-average downscale of an (H, W, C) float32 image by an integer factor.
#[pyfunction]
fn _downscale<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    factor: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let shape = image.shape().to_vec();
    let (h, w, c) = match shape.as_slice() {
        [h, w, c] => (*h, *w, *c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "image has shape {shape:?}; expected (H, W, C)"
            )))
        }
    };
    let s = slice(&image, "image")?;
    let (v, hs, ws) = py.detach(|| crate::kernels::filters::downscale(s, h, w, c, factor));
    same_shape(py, v, &[hs, ws, c])
}

/// METHOD §2 reference preprocessing of a non-linearised sRGB image (H, W, 3).
#[pyfunction]
fn _reference_srgb<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    rgb_shape(image.shape(), "image")?;
    let s = slice(&image, "image")?;
    let v = py.detach(|| color::reference_srgb_stretch(s, None));
    same_shape(py, v, image.shape())
}

/// METHOD §2 reference preprocessing of a white-balanced linear raw image (H, W, 3).
#[pyfunction]
fn _reference_raw<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    rgb_shape(image.shape(), "image")?;
    let s = slice(&image, "image")?;
    let v = py.detach(|| color::reference_raw_stretch(s));
    same_shape(py, v, image.shape())
}

/// Decodes a PNG file's bytes to (codes, bit depth): an (H, W, 3) uint8 or
/// uint16 array (gray is replicated, alpha dropped, palettes expanded).
/// Used for 16-bit PNGs, which Pillow reads only as 8 bits.
#[pyfunction]
fn _decode_png<'py>(py: Python<'py>, data: &[u8], max_pixels: u64) -> PyResult<Bound<'py, PyAny>> {
    let bad = |e: String| PyValueError::new_err(format!("corrupt or unsupported PNG: {e}"));
    let mut dec = png::Decoder::new(std::io::Cursor::new(data));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(|e| bad(e.to_string()))?;
    let (w, h) = {
        let info = reader.info();
        (info.width as usize, info.height as usize)
    };
    if (w as u64).saturating_mul(h as u64) > max_pixels {
        return Err(PyValueError::new_err(format!(
            "PNG is {w}x{h} pixels, over the limit of {max_pixels} pixels"
        )));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| bad("image too large".into()))?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(|e| bad(e.to_string()))?;
    let (ct, depth) = reader.output_color_type();
    let chans = ct.samples();
    let wide = depth == png::BitDepth::Sixteen;
    let bytes = if wide { 2 } else { 1 };
    let line = frame.line_size;
    let pick = |px: &[u8], c: usize| -> u16 {
        // gray(+alpha) replicates channel 0; RGB(A) takes 0..3
        let k = if chans < 3 { 0 } else { c } * bytes;
        match (px.get(k), px.get(k + 1)) {
            (Some(&hi), Some(&lo)) if wide => u16::from_be_bytes([hi, lo]),
            (Some(&v), _) => u16::from(v),
            _ => 0,
        }
    };
    let mut out: Vec<u16> = Vec::with_capacity(h * w * 3);
    for row in buf.chunks(line).take(h) {
        for px in row.chunks(chans * bytes).take(w) {
            for c in 0..3 {
                out.push(pick(px, c));
            }
        }
    }
    if out.len() != h * w * 3 {
        return Err(bad("truncated image data".into()));
    }
    if wide {
        Ok(same_shape(py, out, &[h, w, 3])?.into_any())
    } else {
        let v: Vec<u8> = out.into_iter().map(|v| v as u8).collect();
        Ok(same_shape(py, v, &[h, w, 3])?.into_any())
    }
}

/// PNG bytes of an (H, W) or (H, W, 3) image of codes.
fn png_bytes(samples: &[u8], w: usize, h: usize, rgb: bool, wide: bool) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::with_capacity(samples.len() / 2 + 1024);
    let mut enc = png::Encoder::new(&mut out, w as u32, h as u32);
    enc.set_color(if rgb { png::ColorType::Rgb } else { png::ColorType::Grayscale });
    enc.set_depth(if wide { png::BitDepth::Sixteen } else { png::BitDepth::Eight });
    // fdeflate with per-row adaptive filters: on 1080p transmission maps
    // 5x faster than zlib level 1 after a Sub filter, at about the same size
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(png::Filter::Adaptive);
    let mut writer = enc.write_header()?;
    writer.write_image_data(samples)?;
    writer.finish()?;
    Ok(out)
}

/// Encodes an (H, W) or (H, W, 3) C-contiguous uint8 or uint16 array as PNG
/// bytes (8 or 16 bits, gray or RGB), with the GIL released.
#[pyfunction]
fn _encode_png<'py>(py: Python<'py>, a: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyBytes>> {
    let check = |shape: &[usize]| -> PyResult<(usize, usize, bool)> {
        match *shape {
            [h, w] if h > 0 && w > 0 => Ok((h, w, false)),
            [h, w, 3] if h > 0 && w > 0 => Ok((h, w, true)),
            _ => Err(PyValueError::new_err(format!("cannot write an array of shape {shape:?} as PNG (need HxW or HxWx3, non-empty)"))),
        }
    };
    let too_big = |h: usize, w: usize| PyValueError::new_err(format!("{w}x{h} is too large for a PNG"));
    let failed = |e: png::EncodingError| PyValueError::new_err(format!("PNG encoding failed: {e}"));
    let bytes = if let Ok(arr) = a.cast::<PyArrayDyn<u8>>() {
        let ro = arr.readonly();
        let (h, w, rgb) = check(ro.shape())?;
        if u32::try_from(w.max(h)).is_err() {
            return Err(too_big(h, w));
        }
        let s = slice(&ro, "image")?;
        py.detach(|| png_bytes(s, w, h, rgb, false)).map_err(failed)?
    } else if let Ok(arr) = a.cast::<PyArrayDyn<u16>>() {
        let ro = arr.readonly();
        let (h, w, rgb) = check(ro.shape())?;
        if u32::try_from(w.max(h)).is_err() {
            return Err(too_big(h, w));
        }
        let s = slice(&ro, "image")?;
        py.detach(|| {
            let be: Vec<u8> = s.iter().flat_map(|v| v.to_be_bytes()).collect();
            png_bytes(&be, w, h, rgb, true)
        })
        .map_err(failed)?
    } else {
        return Err(PyValueError::new_err("PNG samples must be a uint8 or uint16 array"));
    };
    Ok(PyBytes::new(py, &bytes))
}

/// Adds the colour functions to `uwhl_rs._core`.
/// The curve named `transfer` (`--transfer`'s names); ValueError otherwise.
fn curve(transfer: &str) -> PyResult<Transfer> {
    Transfer::parse(transfer).ok_or_else(|| {
        PyValueError::new_err(format!("transfer {transfer:?} is not one of bt709, srgb, gamma22, gamma28, linear"))
    })
}

/// The curve a video stream's transfer tag (FFmpeg's name) says: its
/// `--transfer` name, None when the tag says nothing; ValueError naming a
/// curve that is not read (HDR, log).
#[pyfunction]
fn transfer_of_tag(tag: &str) -> PyResult<Option<&'static str>> {
    Transfer::from_tag(tag).map(|t| t.map(Transfer::name)).map_err(PyValueError::new_err)
}

/// A video frame's 8- or 16-bit codes (uint8 or uint16, (H, W, 3)) to
/// linear light (float32) through the inverse of `transfer`
/// (`crate::files::transfer`).
#[pyfunction]
fn frame_to_linear<'py>(py: Python<'py>, codes: &Bound<'py, PyAny>, transfer: &str) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let t = curve(transfer)?;
    if let Ok(a) = codes.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        rgb_shape(a.shape(), "codes")?;
        let s = slice(&a, "codes")?;
        let mut out = vec![0f32; s.len()];
        py.detach(|| Codec::new(t, 8).decode_u8(s, &mut out));
        return same_shape(py, out, a.shape());
    }
    let a = codes
        .extract::<PyReadonlyArrayDyn<'py, u16>>()
        .map_err(|_| PyValueError::new_err("codes must be a uint8 or uint16 array"))?;
    rgb_shape(a.shape(), "codes")?;
    let s = slice(&a, "codes")?;
    let mut out = vec![0f32; s.len()];
    py.detach(|| Codec::new(t, 16).decode_u16(s, &mut out));
    same_shape(py, out, a.shape())
}

/// Linear light (float32, (H, W, 3)) to `bits` (8 or 16) codes through
/// `transfer`, rounded to nearest (`crate::files::transfer`).
#[pyfunction]
fn frame_from_linear<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    transfer: &str,
    bits: u32,
) -> PyResult<Bound<'py, PyAny>> {
    let t = curve(transfer)?;
    rgb_shape(image.shape(), "image")?;
    let s = slice(&image, "image")?;
    let shape = image.shape().to_vec();
    match bits {
        8 => {
            let mut out = vec![0u8; s.len()];
            py.detach(|| Codec::new(t, 8).encode_u8(s, &mut out));
            Ok(same_shape(py, out, &shape)?.into_any())
        }
        16 => {
            let mut out = vec![0u16; s.len()];
            py.detach(|| Codec::new(t, 16).encode_u16(s, &mut out));
            Ok(same_shape(py, out, &shape)?.into_any())
        }
        _ => Err(PyValueError::new_err(format!("bits must be 8 or 16, got {bits}"))),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(transfer_of_tag, m)?)?;
    m.add_function(wrap_pyfunction!(frame_to_linear, m)?)?;
    m.add_function(wrap_pyfunction!(frame_from_linear, m)?)?;
    m.add_function(wrap_pyfunction!(_decode_u16, m)?)?;
    m.add_function(wrap_pyfunction!(_quantize, m)?)?;
    m.add_function(wrap_pyfunction!(_colormap, m)?)?;
    m.add_function(wrap_pyfunction!(_downscale, m)?)?;
    m.add_function(wrap_pyfunction!(_reference_srgb, m)?)?;
    m.add_function(wrap_pyfunction!(_reference_raw, m)?)?;
    m.add_function(wrap_pyfunction!(_decode_png, m)?)?;
    m.add_function(wrap_pyfunction!(_encode_png, m)?)?;
    Ok(())
}
