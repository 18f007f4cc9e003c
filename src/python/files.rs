//! The files layer's per-input path for the Python command: decoding
//! JPEG/PNG/TIFF with the binary's decoder (`crate::files::decode`), the
//! settings of one input made from keywords through the option table
//! (`crate::files::settings::Settings::set`), and the writing half
//! (`crate::files::pipeline::write_outputs`: encodes, metadata, sidecar,
//! commit). Python keeps what Rust cannot do: raw decoding (rawpy), object
//! storage (fsspec), Dask, and the contact sheet's drawing.

use super::{failure_to_py, mask_slice, parse_choices, ParameterError, PyClaim, PyRestoration};
use crate::error::{Failure, Kind};
use crate::files::decode::{decode, Header, Limits};
use crate::files::options::{spec, Kind as OptKind, Value};
use crate::files::pipeline::{write_outputs, Outputs, Timing};
use crate::files::settings::{Preprocess, Settings};
use crate::files::sidecar::{parameters, Estimates, Source};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The settings of one input's processing (core `Settings`): every
/// keyword of `uwhl_rs.files.restore_file` that the option table knows,
/// method and file keys alike, checked by the table's own parser; None
/// leaves the default.
#[pyclass(name = "FileSettings", module = "uwhl_rs._core", frozen)]
pub struct PyFileSettings(pub(crate) Settings);

/// The text of a file option's value as a command line would give it.
fn as_text(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_instance_of::<pyo3::types::PyBool>() {
        return Err(ParameterError::new_err(format!("{v} is not a value of this keyword")));
    }
    Ok(v.str()?.to_string())
}

#[pymethods]
impl PyFileSettings {
    #[new]
    #[pyo3(signature = (**kwargs))]
    fn new(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut s = Settings::default();
        let Some(kwargs) = kwargs else { return Ok(Self(s)) };
        // a window given, not defaulted, as the binary tells --port from its default
        let mut port_given = false;
        for (k, v) in kwargs.iter() {
            let key: String = k.extract()?;
            let spec = spec(&key)
                .ok_or_else(|| PyTypeError::new_err(format!("unexpected keyword argument {key:?}")))?;
            if v.is_none() {
                continue;
            }
            port_given |= key == "port";
            if key == "water_types" {
                s.water_types = Some(parse_choices(&v)?);
                continue;
            }
            let value = if spec.method {
                match super::method_value(spec, &v)? {
                    Some(value) => value,
                    None => continue,
                }
            } else {
                match spec.kind {
                    OptKind::Flag => {
                        if !v.is_truthy()? {
                            continue;
                        }
                        Value::On
                    }
                    _ => spec
                        .parse(&as_text(&v)?)
                        .map_err(|m| ParameterError::new_err(m.replacen(spec.flag, spec.key, 1)))?,
                }
            };
            if !s.set(spec.key, value).map_err(failure_to_py)? {
                return Err(PyTypeError::new_err(format!("{key:?} is not an option of one input's processing")));
            }
        }
        let bits = s.bits.map(u64::from);
        crate::files::options::check_combination(
            s.format.name(),
            bits,
            None,
            false,
            s.linear,
            s.preprocess.name(),
            crate::files::options::Names::Keywords,
        )
        .map_err(ParameterError::new_err)?;
        crate::files::options::check_distance(
            s.distance.is_some(),
            s.altitude.is_some(),
            s.fov.is_some(),
            s.depth_along_axis,
            false,
            port_given,
            crate::files::options::Names::Keywords,
        )
        .map_err(ParameterError::new_err)?;
        crate::files::options::check_water(s.water_from.is_some(), s.water_types.is_some(), crate::files::options::Names::Keywords)
            .map_err(ParameterError::new_err)?;
        Ok(Self(s))
    }

    /// With `altitude`: what the sidecar's `distance.source` says of it; else None.
    #[getter]
    fn altitude(&self) -> Option<String> {
        self.0.altitude.as_ref().map(crate::files::nav::AltitudeSource::label)
    }

    /// Whether the distance maps hold depth along the camera's axis
    /// (`distance_kind="depth"`), turned into ranges by `depth_to_range_for`.
    #[getter]
    fn depth_along_axis(&self) -> bool {
        self.0.depth_along_axis
    }

    /// The memory budget in bytes.
    #[getter]
    fn max_memory(&self) -> u64 {
        self.0.params.max_memory
    }

    /// The sidecar's `parameters` of these settings, as JSON text
    /// (`crate::files::sidecar::parameters`, what every sidecar records).
    #[getter]
    fn parameters(&self) -> String {
        parameters(&self.0).to_string()
    }

    /// With `water_from`: the dive's water type `(name, beta_BR, beta_BG)`
    /// (`crate::files::dive`), the one candidate of every photo; else None.
    #[getter]
    fn dive_water_type(&self) -> Option<(String, f64, f64)> {
        self.0.water_from.as_ref().map(|d| (d.water_type.name.clone(), d.water_type.beta_br, d.water_type.beta_bg))
    }

    /// With `water_from`: the console's notes on the folder's sidecars that
    /// gave no fit (`crate::files::dive::DiveWater::notes`); else empty.
    #[getter]
    fn dive_water_notes(&self) -> Vec<String> {
        self.0.water_from.as_ref().map(|d| d.notes()).unwrap_or_default()
    }
}

/// Decodes a PNG, JPEG or TIFF file with the binary's decoder: returns
/// `(image, info)`, image float32 (H, W, 3) through the inverse sRGB curve
/// when `linearize` (float TIFFs as they are), info a dict with `format`,
/// `bits`, `is_float`, `orientation` (applied), `icc_profile` (None or
/// `(description, converted, why_unreadable)`) and `notes` (what the
/// metadata readers dropped or chose, src/files/exif.rs).
/// `on_header(height, width, bytes_per_pixel, oriented)` is called from
/// the header before the pixels are decoded (the memory plan); what it
/// raises propagates. A file the decoder refuses raises ImageError, one
/// over a limit MemoryError.
#[pyfunction]
#[pyo3(signature = (path, linearize, max_pixels, max_memory, on_header=None))]
fn decode_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    linearize: bool,
    max_pixels: u64,
    max_memory: u64,
    on_header: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let file = crate::files::pipeline::open_input(&path).map_err(failure_to_py)?;
    let limits = Limits { max_pixels, max_memory };
    let mut hook_error: Option<PyErr> = None;
    // the header hook runs Python, so the GIL is held while decoding
    let decoded = decode(std::io::BufReader::new(file), &limits, linearize, |h: &Header| {
        if let Some(f) = &on_header {
            if let Err(e) = f.call1((h.height, h.width, h.bpp, h.oriented)) {
                hook_error = Some(e);
                return Err(Failure::new(Kind::Internal, "refused by the header hook"));
            }
        }
        Ok(())
    });
    if let Some(e) = hook_error {
        return Err(e);
    }
    let d = decoded.map_err(failure_to_py)?;
    let info = PyDict::new(py);
    info.set_item("format", d.format)?;
    info.set_item("bits", d.bits)?;
    info.set_item("is_float", d.is_float)?;
    info.set_item("orientation", d.orientation)?;
    info.set_item("icc_profile", d.icc_profile.clone())?;
    info.set_item("notes", d.notes.clone())?;
    let image = PyArray1::from_vec(py, d.data).reshape([d.height, d.width, 3])?.into_any();
    Ok((image, info))
}

/// A mask file as H x W bools (nonzero = true), read by the binary's mask
/// reader (`crate::files::pipeline::load_mask`: regular files only, the
/// pixel limit and the memory budget from its header). `what` names the
/// argument in messages; a mask that cannot be read raises ParameterError,
/// one over the budget MemoryError.
#[pyfunction]
#[pyo3(signature = (path, what, max_pixels, max_memory))]
fn decode_mask_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    what: &str,
    max_pixels: u64,
    max_memory: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let limits = Limits { max_pixels, max_memory };
    let m = crate::files::pipeline::load_mask(&path, what, &limits).map_err(failure_to_py)?;
    Ok(PyArray1::from_vec(py, m.data).reshape([m.height, m.width])?.into_any())
}

/// An input's distance map for `--distance TEMPLATE` (the binary's reader,
/// `crate::files::depth`): `(path, map or None, why not or None)`. A map
/// that cannot be read is not an error: the photo is restored without it
/// and flagged `distance_missing`. With `photo` (its height and width), a
/// map far larger than the photo is refused from its header. The fourth
/// value counts the distances beyond float32 read as unknown (the
/// sidecar's `distance.out_of_range`).
#[pyfunction]
#[pyo3(signature = (template, input, max_pixels, max_memory, photo=None))]
#[allow(clippy::type_complexity)]
fn read_distance_for<'py>(
    py: Python<'py>,
    template: &str,
    input: PathBuf,
    max_pixels: u64,
    max_memory: u64,
    photo: Option<(u64, u64)>,
) -> PyResult<(String, Option<Bound<'py, PyAny>>, Option<String>, usize)> {
    let path = match crate::files::depth::expand(template, &input) {
        Ok(p) => p,
        Err(why) => return Ok((template.to_string(), None, Some(why), 0)),
    };
    let shown = path.to_string_lossy().into_owned();
    match py.detach(|| crate::files::depth::read_distance_of(&path, max_pixels, max_memory, photo)) {
        Ok(m) => {
            let out = m.out_of_range;
            Ok((shown, Some(PyArray1::from_vec(py, m.data).reshape([m.height, m.width])?.into_any()), None, out))
        }
        Err(f) => {
            let why = format!("{shown}: {}", f.message);
            Ok((shown, None, Some(why), 0))
        }
    }
}

/// A distance map file as H x W metres (NaN = unknown), read by the
/// binary's reader (`crate::files::depth`): `uwhl evaluate` reads a
/// manifest's maps with it, so both read the same formats the same way.
/// With `photo` (its height and width), a map far larger than the photo is
/// refused from its header.
#[pyfunction]
#[pyo3(signature = (path, max_pixels, max_memory, photo=None))]
fn read_distance_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    max_pixels: u64,
    max_memory: u64,
    photo: Option<(u64, u64)>,
) -> PyResult<Bound<'py, PyAny>> {
    let m = py.detach(|| crate::files::depth::read_distance_of(&path, max_pixels, max_memory, photo)).map_err(failure_to_py)?;
    Ok(PyArray1::from_vec(py, m.data).reshape([m.height, m.width])?.into_any())
}

/// What a mask's size error adds for an input its EXIF `orientation`
/// turned (`crate::files::pipeline::upright_said`), as the binary says it.
#[pyfunction]
fn upright_said(orientation: u8) -> String {
    crate::files::pipeline::upright_said(orientation)
}

/// The ranges (an array), the sidecar's `distance.depth` (JSON) and why not.
type RangeFor<'py> = (Option<Bound<'py, PyAny>>, Option<String>, Option<String>);

/// With `distance_kind="depth"`: an input's map of depth along the camera's
/// axis turned into ranges (METHOD §13.7, the binary's `LensOf`), with the
/// lens of `fov` or the photo's EXIF and `port`, for a photo of `height` x
/// `width` upright pixels: `(ranges or None, the sidecar's distance.depth as
/// JSON or None, why not or None)`. Without a lens the photo is restored
/// without distance and flagged `distance_missing`.
#[pyfunction]
#[pyo3(signature = (settings, input, depth, height, width))]
fn depth_to_range_for<'py>(
    py: Python<'py>,
    settings: &PyFileSettings,
    input: PathBuf,
    depth: numpy::PyReadonlyArray2<'py, f32>,
    height: usize,
    width: usize,
) -> PyResult<RangeFor<'py>> {
    let opts = &settings.0;
    let [mh, mw] = [depth.shape()[0], depth.shape()[1]];
    let data = depth.as_array().iter().copied().collect::<Vec<f32>>();
    let mut map = crate::files::depth::DistanceMap { data, height: mh, width: mw, out_of_range: 0 };
    let (fov, port) = (opts.fov, opts.port);
    let made = py.detach(|| {
        let lens = crate::files::nav::LensOf::of(fov, &input)?;
        lens.to_range(&mut map, (height, width), port)
    });
    Ok(match made {
        Ok(record) => (Some(PyArray1::from_vec(py, map.data).reshape([mh, mw])?.into_any()), Some(record.to_string()), None),
        Err(why) => (None, None, Some(why)),
    })
}

/// An input's distance from `--altitude` (METHOD §13.7, the binary's
/// `crate::files::nav`): the camera over a flat seabed seen in a photo of
/// `height` x `width` upright pixels, made at the processed size:
/// `(source, map or None, why not or None, the sidecar's distance.floor as
/// JSON or None)`. A photo without a pose or a lens is not an error: it is
/// restored without distance and flagged `distance_missing`.
#[pyfunction]
#[pyo3(signature = (settings, input, height, width, processed_height, processed_width))]
#[allow(clippy::type_complexity)]
fn floor_for<'py>(
    py: Python<'py>,
    settings: &PyFileSettings,
    input: PathBuf,
    height: usize,
    width: usize,
    processed_height: usize,
    processed_width: usize,
) -> PyResult<(String, Option<Bound<'py, PyAny>>, Option<String>, Option<String>)> {
    let opts = &settings.0;
    let Some(src) = opts.altitude.as_ref() else {
        return Err(PyRuntimeError::new_err("floor_for needs settings with altitude"));
    };
    let (fov, port) = (opts.fov, opts.port);
    let made = py.detach(|| {
        let camera = crate::files::nav::camera_for(src, fov, &input)?;
        crate::files::nav::floor_map(&camera, port, (height, width), (processed_height, processed_width))
    });
    Ok(match made {
        Ok((m, record)) => (
            src.label(),
            Some(PyArray1::from_vec(py, m.data).reshape([m.height, m.width])?.into_any()),
            None,
            Some(record.to_string()),
        ),
        Err(why) => (src.label(), None, Some(why), None),
    })
}

/// The sidecar's `source` from the Python reader's fields (`ImageMeta`
/// plus the restored size): the keys of `crate::files::sidecar::Source`.
fn source_of(d: &Bound<'_, PyDict>) -> PyResult<Source> {
    fn get<'py, T: FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, k: &str) -> PyResult<T> {
        d.get_item(k)?
            .ok_or_else(|| PyTypeError::new_err(format!("source lacks {k:?}")))?
            .extract()
            .map_err(|_| PyTypeError::new_err(format!("source {k:?} is not of its type")))
    }
    let icc: Option<(String, bool, Option<String>)> = get(d, "icc_profile")?;
    Ok(Source {
        kind: get(d, "kind")?,
        format: get(d, "format")?,
        bits: get(d, "bits")?,
        height: get(d, "height")?,
        width: get(d, "width")?,
        orientation: get(d, "orientation")?,
        linear: get(d, "linear")?,
        preprocess: if get::<String>(d, "preprocess")? == "reference" { Preprocess::Reference } else { Preprocess::None },
        processed_height: get(d, "processed_height")?,
        processed_width: get(d, "processed_width")?,
        icc_profile: icc,
        camera_matrix: get(d, "camera_matrix")?,
        white_balance: get(d, "white_balance")?,
        notes: get(d, "notes")?,
    })
}

/// Writes one input's outputs through its claim and returns the sidecar
/// as JSON text (`crate::files::pipeline::write_outputs`, the binary's
/// writing half): `image` is the restored image to encode (raw inputs:
/// through the camera matrix), `source` the reader's fields,
/// `contact_sheet` an encoded PNG when asked for, `reused` whether a
/// sequence reused its estimates (None outside a sequence), `input` the
/// file whose metadata is carried into the photo (None for a video's
/// frame), and the seconds spent reading, restoring, drawing the sheet and
/// in all so far.
/// The claim is used up; on failure its temporaries are removed.
#[pyfunction]
#[pyo3(signature = (claim, res, image, source, settings, input, label, contact_sheet, reused, read, restore, sheet_seconds, elapsed, distance_source=None, distance_missing=None, distance_floor=None, distance_depth=None, distance_out_of_range=0))]
#[allow(clippy::too_many_arguments)]
fn write_input_outputs(
    py: Python<'_>,
    claim: &PyClaim,
    res: &PyRestoration,
    image: PyReadonlyArray3<'_, f32>,
    source: &Bound<'_, PyDict>,
    settings: &PyFileSettings,
    input: Option<PathBuf>,
    label: PathBuf,
    contact_sheet: Option<Bound<'_, PyBytes>>,
    reused: Option<bool>,
    read: f64,
    restore: f64,
    sheet_seconds: Option<f64>,
    elapsed: f64,
    distance_source: Option<String>,
    distance_missing: Option<String>,
    distance_floor: Option<String>,
    distance_depth: Option<String>,
    distance_out_of_range: usize,
) -> PyResult<String> {
    let source = source_of(source)?;
    let record = res.distance_json.as_deref().and_then(|t| serde_json::from_str::<serde_json::Value>(t).ok());
    let mut distance = match &distance_source {
        Some(src) => crate::files::sidecar::distance_entry(record, src, distance_missing.as_deref()),
        None => record,
    };
    if let (true, Some(serde_json::Value::Object(o))) = (distance_out_of_range > 0, distance.as_mut()) {
        o.insert("out_of_range".into(), serde_json::Value::from(distance_out_of_range));
    }
    for (key, text) in [("floor", &distance_floor), ("depth", &distance_depth)] {
        let value = text.as_deref().and_then(|t| serde_json::from_str::<serde_json::Value>(t).ok());
        if let (Some(v), Some(serde_json::Value::Object(o))) = (value, distance.as_mut()) {
            o.insert(key.into(), v);
        }
    }
    let (h, w) = res.shape;
    if (source.processed_height, source.processed_width) != (h, w) || image.shape() != [h, w, 3] {
        return Err(PyRuntimeError::new_err("the image, the restoration and the source disagree on the size"));
    }
    let image = image.as_slice().map_err(|_| PyRuntimeError::new_err("the image must be C-contiguous"))?;
    let t = res.transmission.bind(py).cast::<numpy::PyArray2<f32>>()?.readonly();
    let vm = res.veiling_mask.bind(py).cast::<numpy::PyArray2<bool>>()?.readonly();
    let transmission = t.as_slice().map_err(|_| PyRuntimeError::new_err("transmission is not contiguous"))?;
    let conf = match &res.confidence {
        Some(c) => Some(c.bind(py).cast::<numpy::PyArray2<f32>>()?.readonly()),
        None => None,
    };
    let confidence = match &conf {
        Some(c) if c.shape() == [h, w] => {
            Some(c.as_slice().map_err(|_| PyRuntimeError::new_err("confidence is not contiguous"))?)
        }
        Some(_) => return Err(PyRuntimeError::new_err("the confidence map and the restoration disagree on the size")),
        None => None,
    };
    let vm = Some(vm);
    let water = mask_slice("veiling_mask", &vm, h, w)?.unwrap_or_default();
    let mut scores = Vec::new();
    for (k, v) in res.scores.bind(py).iter() {
        scores.push((k.extract::<String>()?, v.extract::<f64>()?));
    }
    let estimates = Estimates {
        water_type: &res.wt,
        scores: &scores,
        excluded: &res.excluded,
        veiling_light: [res.veiling_light.0, res.veiling_light.1, res.veiling_light.2],
        vl_pixels: water.iter().filter(|&&b| b).count(),
        pixels: h.saturating_mul(w),
        flags: res
            .flags
            .iter()
            .map(String::as_str)
            .chain(distance_missing.as_ref().map(|_| crate::Flag::DistanceMissing.name()))
            .collect(),
        guided_radius: res.guided_radius,
        guided_subsample: res.guided_subsample,
        veil_excess: res.veil_excess,
        fallback_share: res.fallback_share,
        distance,
    };
    let sheet = contact_sheet.as_ref().map(|b| b.as_bytes().to_vec());
    let claimed = claim
        .inner
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .take()
        .ok_or_else(|| PyRuntimeError::new_err("this claim is committed or released"))?;
    let params = parameters(&settings.0);
    // a name that is not UTF-8 is written as the binary writes it (U+FFFD)
    let label = label.to_string_lossy().into_owned();
    let start = Instant::now().checked_sub(Duration::from_secs_f64(elapsed.max(0.0))).unwrap_or_else(Instant::now);
    let side = py
        .detach(|| {
            write_outputs(
                claimed,
                Outputs {
                    label: &label,
                    input: input.as_deref(),
                    implementation: "python",
                    source: &source,
                    estimates,
                    image,
                    transmission,
                    confidence,
                    contact_sheet: sheet.as_deref(),
                    reused,
                    parameters: &params,
                },
                &settings.0,
                Timing { read, restore, contact_sheet: sheet_seconds, start },
            )
        })
        .map_err(failure_to_py)?;
    Ok(side.to_string())
}

/// Registers the classes and functions of this module in `_core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFileSettings>()?;
    m.add_function(wrap_pyfunction!(decode_file, m)?)?;
    m.add("FLOAT_NOT_PREPROCESSED", crate::files::pipeline::FLOAT_NOT_PREPROCESSED)?;
    m.add_function(wrap_pyfunction!(upright_said, m)?)?;
    m.add_function(wrap_pyfunction!(decode_mask_file, m)?)?;
    m.add_function(wrap_pyfunction!(read_distance_for, m)?)?;
    m.add_function(wrap_pyfunction!(read_distance_file, m)?)?;
    m.add_function(wrap_pyfunction!(depth_to_range_for, m)?)?;
    m.add_function(wrap_pyfunction!(floor_for, m)?)?;
    m.add_function(wrap_pyfunction!(write_input_outputs, m)?)?;
    Ok(())
}
