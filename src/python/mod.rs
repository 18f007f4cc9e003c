//! pyo3 bindings (feature "python"): numpy in, numpy out, the GIL released
//! for the whole Rust call, failures mapped to Python exceptions in one
//! function ([`failure_to_py`]). No algorithm code lives here.

mod color;
mod files;
mod outdir;
#[cfg(feature = "internals")]
mod hooks;

use crate::error::Error;
use crate::method::params::{Input, Params, Restoration};
use crate::method::pipeline::restore;
use crate::method::sequence::Sequence;
use std::sync::Mutex;
use crate::method::water::{WaterType, JERLOV};
use crate::ImageRef;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};

create_exception!(
    _core,
    UwhlError,
    PyValueError,
    "Bad input to uwhl_rs (a ValueError)."
);
create_exception!(
    _core,
    ImageError,
    UwhlError,
    "The image is unusable: shape, size, NaN/Inf, range, constant."
);
create_exception!(
    _core,
    ParameterError,
    UwhlError,
    "A parameter, mask or water type is invalid."
);

/// The one place where failures become Python exceptions: by kind, input
/// -> ImageError, usage -> ParameterError, budget -> MemoryError, write ->
/// OSError, internal -> RuntimeError.
pub(crate) fn failure_to_py(f: crate::error::Failure) -> PyErr {
    use crate::error::Kind;
    match f.kind {
        Kind::Input => ImageError::new_err(f.message),
        Kind::Usage => ParameterError::new_err(f.message),
        Kind::Budget => PyMemoryError::new_err(f.message),
        Kind::Write => pyo3::exceptions::PyOSError::new_err(f.message),
        Kind::Internal => PyRuntimeError::new_err(f.message),
    }
}

/// A core error as its Python exception ([`failure_to_py`]).
pub(crate) fn to_py_err(e: Error) -> PyErr {
    failure_to_py(e.into())
}

/// Result of `restore` (see `uwhl_rs.Restoration` in the stubs for fields).
#[pyclass(name = "Restoration", module = "uwhl_rs._core", frozen)]
pub struct PyRestoration {
    #[pyo3(get)]
    image: Py<PyAny>,
    #[pyo3(get)]
    radiance: Py<PyAny>,
    #[pyo3(get)]
    transmission: Py<PyAny>,
    #[pyo3(get)]
    water_type: String,
    #[pyo3(get)]
    beta_ratios: (f64, f64),
    #[pyo3(get)]
    scores: Py<PyDict>,
    #[pyo3(get)]
    excluded: Vec<String>,
    #[pyo3(get)]
    veiling_light: (f32, f32, f32),
    #[pyo3(get)]
    veiling_mask: Py<PyAny>,
    #[pyo3(get)]
    flags: Vec<String>,
    #[pyo3(get)]
    pub(crate) confidence: Option<Py<PyAny>>,
    #[pyo3(get)]
    pub(crate) veil_excess: Option<f64>,
    /// the share of the shown colour that is the input's own balance rather
    /// than the restoration (METHOD §12.5); None when nothing is blended
    #[pyo3(get)]
    pub(crate) fallback_share: Option<f64>,
    /// the sidecar's `distance` record as JSON text (METHOD §13), None
    /// without a distance
    pub(crate) distance_json: Option<String>,
    #[pyo3(get)]
    guided_radius: usize,
    #[pyo3(get)]
    guided_subsample: usize,
    #[pyo3(get)]
    timings: Py<PyDict>,
    wt: WaterType,
    shape: (usize, usize),
}

#[pymethods]
impl PyRestoration {
    /// With a distance (METHOD §13): what became of it, as a dict (the
    /// sidecar's `distance`: `coverage`, `used`, `rejected`, `water` with
    /// `beta` (1/m per channel), `veiling_light`, `nearest_type`,
    /// `type_distance`, `residual`, `pixels`, and `calibration`); None
    /// without a distance.
    #[getter]
    fn distance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match &self.distance_json {
            Some(t) => Ok(Some(py.import("json")?.call_method1("loads", (t.as_str(),))?)),
            None => Ok(None),
        }
    }

    /// The water fitted from a given distance (the `water` of
    /// [`distance`](Self::distance)), None without a distance or when no fit was made.
    #[getter]
    fn water<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match self.distance(py)? {
            Some(d) => {
                let w = d.get_item("water")?;
                Ok((!w.is_none()).then_some(w))
            }
            None => Ok(None),
        }
    }

    /// Per-channel transmissions (t_R, t_G, t_B) of the chosen type as an
    /// HxWx3 float32 array (METHOD §7).
    fn channel_transmissions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let arr = self
            .transmission
            .bind(py)
            .cast::<numpy::PyArray2<f32>>()?
            .readonly();
        let t = arr
            .as_slice()
            .map_err(|_| PyRuntimeError::new_err("transmission is not contiguous"))?;
        let wt = &self.wt;
        let [tr, tg, tb] = py.detach(|| crate::method::params::channel_transmissions(t, wt));
        let v: Vec<f32> = tr
            .iter()
            .zip(&tg)
            .zip(&tb)
            .flat_map(|((a, b), c)| [*a, *b, *c])
            .collect();
        Ok(PyArray1::from_vec(py, v)
            .reshape([self.shape.0, self.shape.1, 3])?
            .into_any())
    }

    /// Pickling (a multiprocessing pool returns restorations): the fields
    /// as a dict, for [`_restoration_from_state`].
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let d = PyDict::new(py);
        d.set_item("image", self.image.bind(py))?;
        d.set_item("radiance", self.radiance.bind(py))?;
        d.set_item("transmission", self.transmission.bind(py))?;
        d.set_item("water_type", &self.water_type)?;
        d.set_item("beta_ratios", self.beta_ratios)?;
        d.set_item("scores", self.scores.bind(py))?;
        d.set_item("excluded", &self.excluded)?;
        d.set_item("veiling_light", self.veiling_light)?;
        d.set_item("veiling_mask", self.veiling_mask.bind(py))?;
        d.set_item("flags", &self.flags)?;
        d.set_item("confidence", self.confidence.as_ref().map(|c| c.bind(py)))?;
        d.set_item("veil_excess", self.veil_excess)?;
        d.set_item("fallback_share", self.fallback_share)?;
        d.set_item("distance_json", &self.distance_json)?;
        d.set_item("guided_radius", self.guided_radius)?;
        d.set_item("guided_subsample", self.guided_subsample)?;
        d.set_item("timings", self.timings.bind(py))?;
        d.set_item("shape", self.shape)?;
        Ok((py.import("uwhl_rs._core")?.getattr("_restoration_from_state")?, (d,)))
    }

    fn __repr__(&self) -> String {
        format!(
            "Restoration(water_type={:?}, veiling_light=({:.4}, {:.4}, {:.4}), shape={}x{}, flags={:?})",
            self.water_type, self.veiling_light.0, self.veiling_light.1, self.veiling_light.2, self.shape.0, self.shape.1, self.flags
        )
    }
}

/// A restoration from the state its `__reduce__` gave (unpickling).
#[pyfunction]
fn _restoration_from_state(state: &Bound<'_, PyDict>) -> PyResult<PyRestoration> {
    let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
        state.get_item(k)?.ok_or_else(|| ParameterError::new_err(format!("a pickled Restoration without {k}")))
    };
    let opt = |k: &str| -> PyResult<Option<Bound<'_, PyAny>>> { Ok(get(k).ok().filter(|v| !v.is_none())) };
    let water_type: String = get("water_type")?.extract()?;
    let beta_ratios: (f64, f64) = get("beta_ratios")?.extract()?;
    Ok(PyRestoration {
        image: get("image")?.unbind(),
        radiance: get("radiance")?.unbind(),
        transmission: get("transmission")?.unbind(),
        wt: WaterType::new(&water_type, beta_ratios.0, beta_ratios.1).map_err(to_py_err)?,
        water_type,
        beta_ratios,
        scores: get("scores")?.cast_into::<PyDict>()?.unbind(),
        excluded: get("excluded")?.extract()?,
        veiling_light: get("veiling_light")?.extract()?,
        veiling_mask: get("veiling_mask")?.unbind(),
        flags: get("flags")?.extract()?,
        confidence: opt("confidence")?.map(Bound::unbind),
        veil_excess: opt("veil_excess")?.map(|v| v.extract()).transpose()?,
        fallback_share: opt("fallback_share")?.map(|v| v.extract()).transpose()?,
        distance_json: opt("distance_json")?.map(|v| v.extract()).transpose()?,
        guided_radius: get("guided_radius")?.extract()?,
        guided_subsample: get("guided_subsample")?.extract()?,
        timings: get("timings")?.cast_into::<PyDict>()?.unbind(),
        shape: get("shape")?.extract()?,
    })
}

/// `water_types` as given in Python: names or `(name, beta_BR, beta_BG)`
/// tuples (custom types, echoed as such in the sidecar).
pub(crate) fn parse_choices(obj: &Bound<'_, PyAny>) -> PyResult<Vec<crate::files::settings::WaterChoice>> {
    use crate::files::settings::WaterChoice;
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<pyo3::types::PyBytes>() || obj.is_instance_of::<PyTuple>() {
        let shown = obj.repr().map(|r| r.to_string()).unwrap_or_default();
        let kind = obj.get_type().name().map(|n| n.to_string()).unwrap_or_default();
        return Err(ParameterError::new_err(format!(
            "water_types must be a list of names or (name, beta_BR, beta_BG) tuples, not a {kind} ({shown}); \
             write [{shown}] for a single type"
        )));
    }
    let mut out = Vec::new();
    for item in obj
        .try_iter()
        .map_err(|_| ParameterError::new_err("water_types must be a list"))?
    {
        let item = item?;
        if let Ok(name) = item.extract::<String>() {
            out.push(WaterChoice { water_type: WaterType::by_name(&name).map_err(to_py_err)?, custom: false });
        } else if let Ok(t) = item.cast::<PyTuple>() {
            let (name, br, bg): (String, f64, f64) = t.extract().map_err(|_| {
                ParameterError::new_err(format!(
                    "water type {t} must be (name, beta_BR, beta_BG) with a str and two numbers"
                ))
            })?;
            out.push(WaterChoice { water_type: WaterType::new(&name, br, bg).map_err(to_py_err)?, custom: true });
        } else {
            return Err(ParameterError::new_err(format!(
                "water type {item} must be a name or a (name, beta_BR, beta_BG) tuple"
            )));
        }
    }
    // a name listed twice is refused here, as the binary's parser does, not by every input's restore
    for (i, c) in out.iter().enumerate() {
        if out[..i].iter().any(|o| o.water_type.name == c.water_type.name) {
            return Err(ParameterError::new_err(format!("water type {:?} is listed twice", c.water_type.name)));
        }
    }
    Ok(out)
}

/// The value of a method keyword (a row with `method: true` other than
/// `water_types`) as the option table's [`crate::files::options::Value`]:
/// integers (numpy's too, not booleans) >= 0, numbers (not booleans or
/// text), names, and R, G, B as any sequence of three numbers. A value of
/// the wrong kind is a ParameterError naming the keyword and the value.
pub(crate) fn method_value(
    s: &crate::files::options::Spec,
    v: &Bound<'_, PyAny>,
) -> PyResult<Option<crate::files::options::Value>> {
    use crate::files::options::{Kind, Value};
    let key = s.key;
    let shown = v.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    let wrong = |what: &str| ParameterError::new_err(format!("{key} must be {what}; got {shown}"));
    let is_bool = v.is_instance_of::<pyo3::types::PyBool>()
        || v.get_type().name().is_ok_and(|n| n == "bool_");
    let text = v.is_instance_of::<PyString>();
    let int = |what: &str| -> PyResult<u64> {
        if is_bool || text {
            return Err(wrong(what));
        }
        v.extract::<u64>().map_err(|_| wrong(what))
    };
    Ok(Some(match s.kind {
        Kind::WaterTypes => return Ok(None),
        Kind::Subsample if text => match v.extract::<String>()?.as_str() {
            "auto" => Value::Int(0),
            _ => return Err(wrong("an integer >= 0 or \"auto\"")),
        },
        Kind::Subsample => Value::Int(int("an integer >= 0 or \"auto\"")?),
        Kind::Int { .. } | Kind::Bytes | Kind::IntOf(_) => Value::Int(int("an integer >= 0")?),
        Kind::Float { .. } => {
            if is_bool || text {
                return Err(wrong("a number"));
            }
            Value::Float(v.extract().map_err(|_| wrong("a number"))?)
        }
        Kind::Choice(names) => {
            let list = names.iter().map(|n| format!("{n:?}")).collect::<Vec<_>>().join(", ");
            Value::Text(v.extract().map_err(|_| wrong(&format!("one of {list}")))?)
        }
        Kind::Rgb => {
            let rgb: Vec<f64> = if text { None } else { v.extract().ok() }
                .filter(|c: &Vec<f64>| c.len() == 3)
                .ok_or_else(|| wrong("3 numbers (R, G, B)"))?;
            Value::Rgb([rgb[0], rgb[1], rgb[2]])
        }
        Kind::Flag | Kind::Path | Kind::Address | Kind::KeyValue | Kind::Size => return Err(wrong("a value of this keyword")),
    }))
}

pub(crate) fn mask_slice<'a>(
    name: &str,
    m: &'a Option<PyReadonlyArray2<'a, bool>>,
    h: usize,
    w: usize,
) -> PyResult<Option<&'a [bool]>> {
    match m {
        None => Ok(None),
        Some(a) => {
            let s = a.shape();
            if s != [h, w] {
                return Err(ParameterError::new_err(format!(
                    "{name} has shape {s:?}; the image needs ({h}, {w})"
                )));
            }
            Ok(Some(a.as_slice().map_err(|_| {
                ParameterError::new_err(format!("{name} must be C-contiguous"))
            })?))
        }
    }
}

/// The method's parameters (core [`Params`]), made once from the keyword
/// arguments that `uwhl_rs.restore` and `uwhl_rs.Sequence` share (which
/// check them first) and passed to `restore_f32` or `Sequence`.
#[pyclass(name = "Params", module = "uwhl_rs._core", frozen)]
pub struct PyParams(Params);

#[pymethods]
impl PyParams {
    /// The method's keywords (the rows of the option table with `method`),
    /// each None or absent for the core's default; a value of the wrong
    /// kind is a ParameterError naming the keyword, an unknown keyword a
    /// TypeError.
    #[new]
    #[pyo3(signature = (**kwargs))]
    fn new(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        use crate::files::options::{spec, Kind};
        let mut params = Params::default();
        let Some(kwargs) = kwargs else {
            return Ok(Self(params));
        };
        for (k, v) in kwargs.iter() {
            let key: String = k.extract()?;
            let s = spec(&key).filter(|s| s.method).ok_or_else(|| {
                pyo3::exceptions::PyTypeError::new_err(format!("unexpected keyword argument {key:?}"))
            })?;
            if v.is_none() {
                continue;
            }
            if s.kind == Kind::WaterTypes {
                params.water_types = parse_choices(&v)?.into_iter().map(|c| c.water_type).collect();
                continue;
            }
            if let Some(value) = method_value(s, &v)? {
                params.set(s.key, &value).map_err(to_py_err)?;
            }
        }
        Ok(Self(params))
    }

    /// The profile and the steps used, as (keyword, name) pairs (METHOD §12).
    fn steps(&self) -> Vec<(&'static str, &'static str)> {
        self.0.steps().to_vec()
    }

    /// `(needed, max_memory)`: the working memory a restoration of an `h`
    /// x `w` image needs with these parameters, and the limit it is
    /// checked against, so that the Python layer can refuse an image from
    /// its shape before copying it. The values that need no image are
    /// checked first (`check_values`): a sphere_points out of its range is
    /// named as such, not as the memory its index would take.
    fn budget(&self, h: usize, w: usize) -> PyResult<(u64, u64)> {
        crate::method::params::check_values(&self.0).map_err(to_py_err)?;
        Ok((crate::method::params::needed_memory(h, w, false, &self.0), self.0.max_memory))
    }
}

/// The most pixels a distance map of a photo of `height` x `width` pixels
/// may have (`crate::files::depth::map_cap`): larger ones are not read.
#[pyfunction]
fn map_cap(height: u64, width: u64) -> u64 {
    crate::files::depth::map_cap(height, width)
}

/// The option table (`crate::files::options::OPTIONS`) as a list of dicts: what
/// the Python layer builds its command line and keyword defaults from.
fn options_table(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    use crate::files::options::{Default as D, Kind as K, OPTIONS};
    let list = PyList::empty(py);
    for s in OPTIONS {
        let d = PyDict::new(py);
        d.set_item("key", s.key)?;
        d.set_item("flag", s.flag)?;
        d.set_item("short", s.short.map(|c| format!("-{c}")))?;
        d.set_item("metavar", s.metavar)?;
        d.set_item("kind", s.kind.name())?;
        match s.kind {
            K::Int { min, max } => {
                d.set_item("min", min)?;
                d.set_item("max", max)?;
            }
            K::IntOf(values) => d.set_item("choices", values.to_vec())?,
            K::Float { gt, le } => {
                d.set_item("gt", gt)?;
                d.set_item("le", le)?;
            }
            K::Choice(names) => d.set_item("choices", names.to_vec())?,
            _ => {}
        }
        match s.default {
            D::None => d.set_item("default", py.None())?,
            D::Off => d.set_item("default", false)?,
            D::Int(n) => d.set_item("default", n)?,
            D::Float(x) => d.set_item("default", x)?,
            D::Name(n) => d.set_item("default", n)?,
        }
        d.set_item("help", s.help_with_default())?;
        d.set_item("group", s.group.title())?;
        d.set_item("faces", s.faces.name())?;
        d.set_item("method", s.method)?;
        list.append(d)?;
    }
    Ok(list)
}

/// Parses a command-line value of the option `key` with the core's rules
/// (the same function `uwhl-rs` uses); ValueError naming the flag.
#[pyfunction]
fn parse_option(py: Python<'_>, key: &str, text: &str) -> PyResult<Py<PyAny>> {
    use crate::files::options::{spec, Value};
    let s = spec(key).ok_or_else(|| PyValueError::new_err(format!("unknown option {key:?}")))?;
    let v = s.parse(text).map_err(PyValueError::new_err)?;
    Ok(match v {
        Value::On => true.into_pyobject(py)?.to_owned().into_any().unbind(),
        Value::Int(n) => n.into_pyobject(py)?.into_any().unbind(),
        Value::Float(x) => x.into_pyobject(py)?.into_any().unbind(),
        Value::Text(t) => t.into_pyobject(py)?.into_any().unbind(),
        Value::Rgb([r, g, b]) => (r, g, b).into_pyobject(py)?.into_any().unbind(),
        Value::Size(w, h) => (w, h).into_pyobject(py)?.into_any().unbind(),
    })
}

/// The checks of several options at once (`crate::files::options::check_combination`);
/// ValueError with the usage message.
#[pyfunction]
#[pyo3(signature = (format, bits, reuse_estimates, reuse_water_mask, linear, preprocess))]
fn check_combination(
    format: &str,
    bits: Option<u64>,
    reuse_estimates: Option<u64>,
    reuse_water_mask: bool,
    linear: bool,
    preprocess: &str,
) -> PyResult<()> {
    use crate::files::options::Names;
    crate::files::options::check_combination(format, bits, reuse_estimates, reuse_water_mask, linear, preprocess, Names::Flags)
        .map_err(PyValueError::new_err)
}

/// The range in metres along each pixel's ray to a flat seabed (METHOD
/// §13.7, `crate::method::floor::Floor::distances`): float32 (height,
/// width), NaN where a ray does not meet it; ParameterError for values out
/// of range.
#[pyfunction]
#[pyo3(signature = (height, width, altitude, fov, pitch, roll, port))]
#[allow(clippy::too_many_arguments)]
fn floor_distance<'py>(
    py: Python<'py>,
    height: usize,
    width: usize,
    altitude: f64,
    fov: f64,
    pitch: f64,
    roll: f64,
    port: &str,
) -> PyResult<Bound<'py, PyAny>> {
    use crate::method::floor::{Floor, Port};
    let port = Port::parse(port).ok_or_else(|| ParameterError::new_err(format!("port {port:?} is not flat or dome")))?;
    let floor = Floor { altitude, fov, pitch, roll, port };
    floor.check().map_err(ParameterError::new_err)?;
    if height == 0 || width == 0 || height.saturating_mul(width) > crate::files::options::DEFAULT_MAX_PIXELS as usize {
        return Err(ParameterError::new_err(format!("shape ({height}, {width}) is empty or over the largest input")));
    }
    let z = py.detach(|| floor.distances(height, width));
    Ok(numpy::PyArray1::from_vec(py, z).reshape([height, width])?.into_any())
}

/// Depth along the camera's axis turned into the range along each pixel's
/// ray (METHOD §13.7, `crate::method::floor::depth_to_range`): float32 of
/// the depth's shape; ParameterError for a field of view out of range or an
/// unknown port.
#[pyfunction]
#[pyo3(signature = (depth, fov, port))]
fn depth_to_range<'py>(py: Python<'py>, depth: numpy::PyReadonlyArray2<'py, f32>, fov: f64, port: &str) -> PyResult<Bound<'py, PyAny>> {
    use crate::method::floor::Port;
    let port = Port::parse(port).ok_or_else(|| ParameterError::new_err(format!("port {port:?} is not flat or dome")))?;
    let [h, w] = [depth.shape()[0], depth.shape()[1]];
    let mut z: Vec<f32> = depth.as_array().iter().copied().collect();
    py.detach(|| crate::method::floor::depth_to_range(&mut z, h, w, fov, port)).map_err(ParameterError::new_err)?;
    Ok(numpy::PyArray1::from_vec(py, z).reshape([h, w])?.into_any())
}

/// The usage error of an unknown short option that began `word`
/// (`crate::files::options::unknown_short_said`), as uwhl-rs says it.
#[pyfunction]
fn unknown_short_said(word: &str) -> String {
    crate::files::options::unknown_short_said(word)
}

/// `--water-type` values parsed as the binary parses them
/// (`crate::files::settings`): a table type by its name, a custom one as
/// `(name, beta_br, beta_bg)`. ParameterError with the binary's message.
#[pyfunction]
fn parse_water_types<'py>(py: Python<'py>, values: Vec<String>) -> PyResult<Bound<'py, PyList>> {
    let mut list = Vec::new();
    for v in &values {
        crate::files::settings::water_types(&mut list, v).map_err(failure_to_py)?;
    }
    let out = PyList::empty(py);
    for c in list {
        if c.custom {
            out.append((c.water_type.name, c.water_type.beta_br, c.water_type.beta_bg))?;
        } else {
            out.append(c.water_type.name)?;
        }
    }
    Ok(out)
}

/// The checks of the distance options (`crate::files::options::check_distance`);
/// ValueError with the usage message.
#[pyfunction]
#[pyo3(signature = (distance, altitude, fov, reuse_estimates, depth=false, port=false))]
fn check_distance(distance: bool, altitude: bool, fov: bool, reuse_estimates: bool, depth: bool, port: bool) -> PyResult<()> {
    use crate::files::options::Names;
    crate::files::options::check_distance(distance, altitude, fov, depth, reuse_estimates, port, Names::Flags)
        .map_err(PyValueError::new_err)
}

/// A dive's water with water types (`crate::files::options::check_water`);
/// ValueError with the usage message.
#[pyfunction]
fn check_water(water_from: bool, water_types: bool) -> PyResult<()> {
    crate::files::options::check_water(water_from, water_types, crate::files::options::Names::Flags).map_err(PyValueError::new_err)
}

/// The jobs of a batch (`crate::files::jobs::collect_jobs`, output files
/// `NAME` + each suffix): `(jobs, problems, notes)`, jobs as `(input,
/// output folder, name)`, problems as `(input, reason)`, notes the folders
/// a walk did not search (earlier runs' output folders).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn collect_jobs(
    py: Python<'_>,
    inputs: Vec<std::path::PathBuf>,
    out_dir: std::path::PathBuf,
    suffixes: Vec<String>,
) -> (Vec<(std::path::PathBuf, std::path::PathBuf, String)>, Vec<(std::path::PathBuf, String)>, Vec<String>) {
    let (jobs, problems, notes) = py.detach(|| crate::files::jobs::collect_jobs(&inputs, &out_dir, &suffixes));
    (jobs.into_iter().map(|j| (j.input, j.dir, j.name)).collect(), problems, notes)
}

/// The output names of inputs listed elsewhere (object storage), given in
/// discovery order as `(input, folder relative to the output folder)`:
/// the naming of `collect_jobs` (`crate::files::jobs::name_jobs`).
#[pyfunction]
fn name_jobs(found: Vec<(String, String)>, suffixes: Vec<String>) -> Vec<String> {
    let found: Vec<(std::path::PathBuf, std::path::PathBuf)> =
        found.into_iter().map(|(p, r)| (p.into(), r.into())).collect();
    crate::files::jobs::name_jobs(&found, &suffixes)
}

/// An input's claimed output names (`crate::files::commit::Claim`): temporaries
/// to write the outputs into, then one commit that puts them in place with
/// the sidecar last. Released (temporaries and claim removed) by
/// `release()` or when collected without a commit.
#[pyclass(name = "Claim", module = "uwhl_rs._core", frozen)]
struct PyClaim {
    inner: Mutex<Option<crate::files::commit::Claim>>,
}

impl PyClaim {
    fn with<T>(&self, f: impl FnOnce(&mut crate::files::commit::Claim) -> PyResult<T>) -> PyResult<T> {
        let mut g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        match g.as_mut() {
            Some(c) => f(c),
            None => Err(PyRuntimeError::new_err("this claim is committed or released")),
        }
    }
}

#[pymethods]
impl PyClaim {
    /// The name the outputs are written under.
    #[getter]
    fn name(&self) -> PyResult<String> {
        self.with(|c| Ok(c.name().to_string()))
    }

    /// The output paths in the order of the suffixes, the sidecar last.
    #[getter]
    fn paths(&self) -> PyResult<Vec<std::path::PathBuf>> {
        self.with(|c| Ok(c.paths().to_vec()))
    }

    /// A new empty temporary file (created exclusively) for output `index`.
    fn temp(&self, index: usize) -> PyResult<std::path::PathBuf> {
        self.with(|c| Ok(c.temp(index)?.0))
    }

    /// Marks output `index` as not written this time: the commit removes
    /// the file an earlier run left at its path (`crate::files::commit::Claim::omit`).
    fn omit(&self, index: usize) -> PyResult<()> {
        self.with(|c| {
            c.omit(index);
            Ok(())
        })
    }

    /// Puts the written temporaries (one per path) in place, sidecar last.
    fn commit(&self, py: Python<'_>, temps: Vec<std::path::PathBuf>) -> PyResult<()> {
        let claim = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take();
        let claim = claim.ok_or_else(|| PyRuntimeError::new_err("this claim is committed or released"))?;
        py.detach(|| claim.commit(&temps)).map_err(PyErr::from)
    }

    /// Gives the names up: removes the temporaries and the claim file.
    fn release(&self) {
        drop(self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take());
    }
}

/// Claims output names for an input (`crate::files::commit::claim`): returns
/// `(status, sidecar, reason, claim)` with status "claimed" (claim set),
/// "done" (its sidecar exists), "busy" (another process restores it) or
/// "in_flight" (this process restores it now), and the reason the commands
/// print for a skip (`crate::files::commit::Skip::reason`).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn claim_outputs(
    py: Python<'_>,
    dir: std::path::PathBuf,
    base: String,
    input: std::path::PathBuf,
    suffixes: Vec<String>,
    overwrite: bool,
    rename: bool,
) -> PyResult<(&'static str, std::path::PathBuf, Option<String>, Option<PyClaim>)> {
    use crate::files::commit::Resolution;
    let request = crate::files::commit::Request { dir: &dir, base: &base, input: &input, suffixes: &suffixes, overwrite, rename };
    Ok(match py.detach(|| crate::files::commit::claim(&request))? {
        Resolution::Claimed(c) => {
            let side = c.paths().last().cloned().unwrap_or_default();
            ("claimed", side, None, Some(PyClaim { inner: Mutex::new(Some(c)) }))
        }
        Resolution::Skipped(why, s) => (why.name(), s, Some(why.reason()), None),
    })
}

/// A new empty temporary file in `path`'s folder, created exclusively
/// under a short name with `path`'s extension (`crate::files::commit::create_temp_for`).
#[pyfunction]
fn create_temp(path: std::path::PathBuf) -> PyResult<std::path::PathBuf> {
    Ok(crate::files::commit::create_temp_for(&path)?.0)
}

/// Puts a written temporary in place of `path` durably (`crate::files::commit::place`).
#[pyfunction]
fn place(py: Python<'_>, tmp: std::path::PathBuf, path: std::path::PathBuf) -> PyResult<()> {
    py.detach(|| crate::files::commit::place(&tmp, &path)).map_err(PyErr::from)
}

/// The bytes the whole input needs at its peak (`crate::files::budget::Plan`):
/// decoding, `max_side`, `restore`, the outputs; the plan both commands
/// check from the header.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (height, width, decoded_bpp, decoded_is_rgb, oriented, factor, reference, masks, write_extra = 0, sphere_points = None))]
fn input_plan(
    height: usize,
    width: usize,
    decoded_bpp: u64,
    decoded_is_rgb: bool,
    oriented: bool,
    factor: usize,
    reference: bool,
    masks: u8,
    write_extra: u64,
    sphere_points: Option<usize>,
) -> u64 {
    let index = crate::method::sphere::index_bytes(sphere_points.unwrap_or(crate::method::params::DEFAULT_SPHERE_POINTS));
    crate::files::budget::Plan { height, width, decoded_bpp, decoded_is_rgb, oriented, factor, reference, masks, write_extra, index }
        .bytes()
}

/// What the process holds before its first input plus a margin
/// (`crate::kernels::memory::process_base`), measured at the first call.
#[pyfunction]
fn process_base() -> u64 {
    crate::kernels::memory::process_base()
}

/// The default memory budget (`crate::kernels::memory::default_max_memory`).
#[pyfunction]
fn default_max_memory() -> u64 {
    crate::kernels::memory::default_max_memory()
}

/// Whether the system would give `bytes` now (`crate::kernels::memory::can_allocate`).
#[pyfunction]
fn can_allocate(bytes: u64) -> bool {
    crate::kernels::memory::can_allocate(bytes)
}

/// Why the output folder cannot take outputs (something that is not a
/// folder is at its name; `crate::files::jobs::outdir_problem`), or None.
#[pyfunction]
fn outdir_problem(dir: std::path::PathBuf) -> Option<String> {
    crate::files::jobs::outdir_problem(&dir)
}

/// Whether a sidecar whose input is `given` (as its run was given it),
/// `resolved` where recorded, names the local input at `input` by name
/// (`crate::files::commit::names_input`, the rule a folder's claims use);
/// `hashed`: the sidecar records the input's SHA-256, which then decides
/// for a relative `given`.
#[pyfunction]
#[pyo3(signature = (given, resolved, hashed, input))]
fn sidecar_names_input(given: std::path::PathBuf, resolved: Option<std::path::PathBuf>, hashed: bool, input: std::path::PathBuf) -> bool {
    crate::files::commit::names_local_input(&given, resolved.as_deref(), hashed, &input)
}

/// Why a raw file built on TIFF (DNG, NEF, CR2, ARW, ...) at `path` cannot
/// be handed to LibRaw: a strip or tile table that does not cover its
/// image, which LibRaw reads past (`crate::files::exif::raw_tables`); None
/// otherwise, also when it is no TIFF or cannot be opened, which LibRaw
/// names.
#[pyfunction]
fn raw_problem(py: Python<'_>, path: std::path::PathBuf) -> Option<String> {
    py.detach(|| {
        let mut f = std::io::BufReader::new(std::fs::File::open(&path).ok()?);
        crate::files::exif::raw_tables(&mut f).err()
    })
}

/// The Jerlov type nearest to a water of attenuations `beta` (1/m, R, G, B)
/// and how near (`crate::method::distance::nearest_type`, METHOD §13).
#[pyfunction]
fn nearest_type(beta: [f32; 3]) -> (&'static str, f32) {
    crate::method::distance::nearest_type(beta)
}

/// Whether a fit could have written `beta` (1/m, R, G, B): the water
/// `--water-from` takes (`crate::method::distance::writable`, METHOD §13.6).
#[pyfunction]
fn water_writable(beta: [f64; 3]) -> bool {
    crate::method::distance::writable(beta)
}

/// A new run starts: the `--water-from` folders and the `--altitude`
/// navigation logs a run reads once are read again
/// (`crate::files::dive::forget_water_from`, `crate::files::nav::forget_logs`).
#[pyfunction]
fn new_run() {
    crate::files::dive::forget_water_from();
    crate::files::nav::forget_logs();
}

/// The outputs an earlier sidecar (its bytes) lists for the input at
/// output name `name` that an `--overwrite` may remove beside it: `name`
/// plus a suffix either command writes (`crate::files::commit::listed_outputs`).
/// Empty when the bytes are not a sidecar.
#[pyfunction]
fn listed_outputs(name: &str, sidecar: &[u8]) -> Vec<String> {
    crate::files::commit::parse_sidecar(sidecar).map(|d| crate::files::commit::listed_outputs(name, &d)).unwrap_or_default()
}

/// Whether `file` is an output of the output name `name`: `name` and a
/// suffix the commands write (`crate::files::commit::is_output_of`).
#[pyfunction]
fn is_output_of(name: &str, file: &str) -> bool {
    crate::files::commit::is_output_of(name, file)
}

/// Removes the temporaries that dead processes left in `dir`, when no
/// other run holds the output folder `gate` (`dir` itself when not given)
/// (`crate::files::jobs::remove_stale_temps`); returns how many.
#[pyfunction]
#[pyo3(signature = (dir, gate=None))]
fn remove_stale_temps(py: Python<'_>, dir: std::path::PathBuf, gate: Option<std::path::PathBuf>) -> usize {
    let gate = gate.unwrap_or_else(|| dir.clone());
    py.detach(|| crate::files::jobs::remove_stale_temps(&dir, &gate))
}

/// The `options:` part of a command's `--help` for `face` ("python" or "rust").
#[pyfunction]
fn options_help(face: &str) -> PyResult<String> {
    use crate::files::options::{help_text, Faces};
    let f = match face {
        "python" => Faces::Python,
        "rust" => Faces::Rust,
        other => return Err(PyValueError::new_err(format!("face must be python or rust, not {other:?}"))),
    };
    Ok(help_text(f, 100))
}

/// The pixels and (H, W) of an (H, W, 3) C-contiguous float32 array.
fn image_data<'a>(image: &'a PyReadonlyArray3<'a, f32>) -> PyResult<(&'a [f32], usize, usize)> {
    let shape = image.shape();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(ImageError::new_err(format!(
            "image has shape {shape:?}; expected (H, W, 3)"
        )));
    }
    let data = image
        .as_slice()
        .map_err(|_| ImageError::new_err("image must be C-contiguous"))?;
    Ok((data, shape[0], shape[1]))
}

/// Native entry point behind `uwhl_rs.restore` (which checks dtypes and
/// converts float64 to float32 first). Releases the GIL while it works.
#[pyfunction]
#[pyo3(signature = (image, params, *, water_mask=None, mask=None, distance=None))]
fn restore_f32(
    py: Python<'_>,
    image: PyReadonlyArray3<'_, f32>,
    params: &PyParams,
    water_mask: Option<PyReadonlyArray2<'_, bool>>,
    mask: Option<PyReadonlyArray2<'_, bool>>,
    distance: Option<PyReadonlyArray2<'_, f32>>,
) -> PyResult<PyRestoration> {
    let (data, h, w) = image_data(&image)?;
    let params = &params.0;
    let wm = mask_slice("water_mask", &water_mask, h, w)?;
    let mk = mask_slice("mask", &mask, h, w)?;
    let z = match &distance {
        Some(d) => {
            let shape = d.shape();
            let (zh, zw) = (shape[0], shape[1]);
            let zs = match d.as_slice() {
                Ok(s) => s.to_vec(),
                Err(_) => d.as_array().iter().copied().collect::<Vec<f32>>(),
            };
            Some((zs, zh, zw))
        }
        None => None,
    };
    let res = py
        .detach(|| {
            let img = ImageRef::new(data, h, w)?;
            let input = Input {
                image: img,
                mask: mk,
                water_mask: wm,
            };
            match &z {
                Some((z, zh, zw)) => crate::restore_at_distance(&input, z, *zh, *zw, params),
                None => restore(&input, params),
            }
        })
        .map_err(to_py_err)?;
    to_py(py, res)
}

/// A core [`Restoration`] as the Python `Restoration` (arrays handed over
/// to numpy without copying).
fn to_py(py: Python<'_>, res: Restoration) -> PyResult<PyRestoration> {
    let (h, w) = (res.height, res.width);
    let scores = PyDict::new(py);
    for (n, s) in &res.scores {
        scores.set_item(n, *s)?;
    }
    // stage names are unique (the core adds repeated laps up), so a dict
    // keeps every stage, in the order they ran
    let timings = PyDict::new(py);
    for (n, s) in &res.timings {
        timings.set_item(n.name(), *s)?;
    }
    let to3 = |v: Vec<f32>| -> PyResult<Py<PyAny>> {
        Ok(PyArray1::from_vec(py, v)
            .reshape([h, w, 3])?
            .into_any()
            .unbind())
    };
    Ok(PyRestoration {
        image: to3(res.image)?,
        radiance: to3(res.radiance)?,
        transmission: PyArray1::from_vec(py, res.transmission)
            .reshape([h, w])?
            .into_any()
            .unbind(),
        water_type: res.water_type.name.clone(),
        beta_ratios: (res.water_type.beta_br, res.water_type.beta_bg),
        scores: scores.unbind(),
        excluded: res.excluded,
        veiling_light: (
            res.veiling_light[0],
            res.veiling_light[1],
            res.veiling_light[2],
        ),
        veiling_mask: PyArray1::from_vec(py, res.veiling_mask)
            .reshape([h, w])?
            .into_any()
            .unbind(),
        flags: res.flags.iter().map(|f| f.name().to_string()).collect(),
        confidence: match res.confidence {
            Some(c) => Some(PyArray1::from_vec(py, c).reshape([h, w])?.into_any().unbind()),
            None => None,
        },
        veil_excess: res.veil_excess,
        fallback_share: res.fallback_share,
        distance_json: res
            .distance
            .as_ref()
            .map(|d| crate::files::sidecar::distance_record(d, Some("array")).to_string()),
        guided_radius: res.guided_radius,
        guided_subsample: res.guided_subsample,
        timings: timings.unbind(),
        wt: res.water_type,
        shape: (h, w),
    })
}

/// Native class behind `uwhl_rs.Sequence` (which checks the arguments
/// first): a core [`Sequence`] behind a mutex, so that calls from several
/// Python threads take turns; the GIL is released while a frame is
/// restored (and while waiting for the mutex).
#[pyclass(name = "Sequence", module = "uwhl_rs._core", frozen)]
pub struct PySequence {
    inner: Mutex<Sequence>,
}

impl PySequence {
    fn lock(&self) -> std::sync::MutexGuard<'_, Sequence> {
        // the core does not panic; a poisoned lock still holds a usable state
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[pymethods]
impl PySequence {
    #[new]
    #[pyo3(signature = (params, *, refresh_every=0, reuse_water_mask=false, scene_cut=0.0, smoothing=1.0))]
    fn new(params: &PyParams, refresh_every: usize, reuse_water_mask: bool, scene_cut: f32, smoothing: f32) -> PyResult<Self> {
        let params = params.0.clone();
        // what needs no frame is checked now: a bad value is said before the first frame
        crate::method::params::check_values(&params).map_err(to_py_err)?;
        let mut seq = Sequence::new(params);
        seq.refresh_every = refresh_every;
        seq.reuse_water_mask = reuse_water_mask;
        seq.cut_threshold = scene_cut;
        seq.smoothing = smoothing;
        Ok(Self { inner: Mutex::new(seq) })
    }

    /// Why the last frame estimated or reused ("first", "scheduled",
    /// "cut", "drift", "reused") and its colour change from the previous
    /// frame (METHOD §10).
    #[getter]
    fn last_decision(&self, py: Python<'_>) -> (&'static str, f32) {
        py.detach(|| {
            let (d, c) = self.lock().last_decision();
            (d.name(), c)
        })
    }

    /// Restores the next frame (float32 (H, W, 3), C-contiguous).
    #[pyo3(signature = (image, *, mask=None, water_mask=None))]
    fn restore(
        &self,
        py: Python<'_>,
        image: PyReadonlyArray3<'_, f32>,
        mask: Option<PyReadonlyArray2<'_, bool>>,
        water_mask: Option<PyReadonlyArray2<'_, bool>>,
    ) -> PyResult<PyRestoration> {
        let (data, h, w) = image_data(&image)?;
        let wm = mask_slice("water_mask", &water_mask, h, w)?;
        let mk = mask_slice("mask", &mask, h, w)?;
        let res = py
            .detach(|| {
                let img = ImageRef::new(data, h, w)?;
                self.lock().restore(&Input { image: img, mask: mk, water_mask: wm })
            })
            .map_err(to_py_err)?;
        to_py(py, res)
    }

    /// Forgets the estimates and frees the kept buffers.
    fn reset(&self, py: Python<'_>) {
        py.detach(|| self.lock().reset());
    }

    /// The water type the next frame reuses (None before the first frame).
    #[getter]
    fn water_type(&self, py: Python<'_>) -> Option<String> {
        py.detach(|| self.lock().estimates().map(|e| e.water_type.name.clone()))
    }

    /// The veiling light A the next frame reuses (None before the first frame).
    #[getter]
    fn veiling_light(&self, py: Python<'_>) -> Option<(f32, f32, f32)> {
        py.detach(|| self.lock().estimates().map(|e| (e.veiling_light[0], e.veiling_light[1], e.veiling_light[2])))
    }

    /// Whether the next frame runs the estimation (water type and A).
    #[getter]
    fn estimates_next(&self, py: Python<'_>) -> bool {
        py.detach(|| self.lock().estimates_next())
    }

    /// Bytes of work buffers kept between frames.
    #[getter]
    fn buffer_bytes(&self, py: Python<'_>) -> usize {
        py.detach(|| self.lock().buffer_bytes())
    }

    #[getter]
    fn refresh_every(&self, py: Python<'_>) -> usize {
        py.detach(|| self.lock().refresh_every)
    }

    #[getter]
    fn reuse_water_mask(&self, py: Python<'_>) -> bool {
        py.detach(|| self.lock().reuse_water_mask)
    }
}

/// Called in a forked child (registered by `uwhl_rs` with
/// `os.register_at_fork`): later calls use fresh thread pools.
#[pyfunction]
fn _after_fork() {
    crate::kernels::util::after_fork();
}

/// The native module `uwhl_rs._core`.
/// What follows NAME in the names of an input's outputs, in writing order,
/// without the sidecar's `.json` (`crate::files::settings::output_suffixes`).
#[pyfunction]
#[pyo3(signature = (format="jpg", contact=false))]
fn output_suffixes(format: &str, contact: bool) -> PyResult<Vec<String>> {
    let f = crate::files::settings::Format::from_name(format)
        .ok_or_else(|| ParameterError::new_err(format!("format must be one of jpg, png, tiff, not {format:?}")))?;
    Ok(crate::files::settings::output_suffixes(f, contact))
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(restore_f32, m)?)?;
    crate::python::color::register(m)?;
    crate::python::files::register(m)?;
    crate::python::outdir::register(m)?;
    m.add_class::<PyRestoration>()?;
    m.add_class::<PySequence>()?;
    m.add_class::<PyParams>()?;
    m.add_function(wrap_pyfunction!(_after_fork, m)?)?;
    #[cfg(feature = "internals")]
    crate::python::hooks::register(m)?;
    m.add("UwhlError", py.get_type::<UwhlError>())?;
    m.add("ImageError", py.get_type::<ImageError>())?;
    m.add("ParameterError", py.get_type::<ParameterError>())?;
    // each exception carries its failure kind, the name of its exit code
    // (crate::error::Kind), so that the commands read it instead of guessing
    py.get_type::<ImageError>().setattr("kind", crate::error::Kind::Input.name())?;
    py.get_type::<ParameterError>().setattr("kind", crate::error::Kind::Usage.name())?;
    m.add_function(wrap_pyfunction!(output_suffixes, m)?)?;
    let table = PyList::empty(py);
    for (n, br, bg) in JERLOV {
        table.append((n, br, bg))?;
    }
    m.add("JERLOV_TABLE", table)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("OPTIONS", options_table(py)?)?;
    m.add("FLAGS", crate::Flag::ALL.iter().map(|f| f.name()).collect::<Vec<_>>())?;
    m.add("STAGES", crate::Stage::ALL.iter().map(|s| s.name()).collect::<Vec<_>>())?;
    m.add("EXIT_CODES", crate::files::options::EXIT_CODES.to_vec())?;
    m.add("EXIT_CODES_HELP", crate::files::options::exit_code_text())?;
    // the attenuation grid a distance fit searches (METHOD §13.2): its readers take no blue outside it
    m.add("FIT_BETA_GRID", (crate::method::distance::BETA_MIN, crate::method::distance::BETA_MAX))?;
    // a distance map of more than this many times its photo's pixels (map_cap) is not read
    m.add("MAP_PER_PHOTO_PIXEL", crate::files::depth::MAP_PER_PHOTO_PIXEL)?;
    m.add_function(wrap_pyfunction!(map_cap, m)?)?;
    m.add("VIDEO_SCENE_CUT", crate::VIDEO_SCENE_CUT)?;
    m.add("VIDEO_SMOOTHING", crate::VIDEO_SMOOTHING)?;
    m.add("VIDEO_EXTENSIONS", crate::files::jobs::VIDEO_EXTENSIONS.to_vec())?;
    m.add_function(wrap_pyfunction!(parse_option, m)?)?;
    m.add_function(wrap_pyfunction!(options_help, m)?)?;
    m.add_function(wrap_pyfunction!(check_combination, m)?)?;
    m.add_function(wrap_pyfunction!(check_distance, m)?)?;
    m.add_function(wrap_pyfunction!(check_water, m)?)?;
    m.add_function(wrap_pyfunction!(parse_water_types, m)?)?;
    m.add_function(wrap_pyfunction!(unknown_short_said, m)?)?;
    m.add_function(wrap_pyfunction!(depth_to_range, m)?)?;
    m.add_function(wrap_pyfunction!(floor_distance, m)?)?;
    m.add_function(wrap_pyfunction!(collect_jobs, m)?)?;
    m.add_function(wrap_pyfunction!(name_jobs, m)?)?;
    m.add_function(wrap_pyfunction!(remove_stale_temps, m)?)?;
    m.add_function(wrap_pyfunction!(listed_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(new_run, m)?)?;
    m.add_function(wrap_pyfunction!(nearest_type, m)?)?;
    m.add_function(wrap_pyfunction!(water_writable, m)?)?;
    m.add_function(wrap_pyfunction!(_restoration_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(outdir_problem, m)?)?;
    m.add_function(wrap_pyfunction!(raw_problem, m)?)?;
    m.add_function(wrap_pyfunction!(is_output_of, m)?)?;
    m.add_function(wrap_pyfunction!(sidecar_names_input, m)?)?;
    m.add_class::<PyClaim>()?;
    m.add_function(wrap_pyfunction!(input_plan, m)?)?;
    m.add_function(wrap_pyfunction!(process_base, m)?)?;
    m.add_function(wrap_pyfunction!(default_max_memory, m)?)?;
    m.add_function(wrap_pyfunction!(can_allocate, m)?)?;
    m.add_function(wrap_pyfunction!(claim_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(create_temp, m)?)?;
    m.add_function(wrap_pyfunction!(place, m)?)?;
    m.add("IMAGE_EXTENSIONS", crate::files::jobs::IMAGE_EXTENSIONS.to_vec())?;
    m.add("RAW_EXTENSIONS", crate::files::jobs::RAW_EXTENSIONS.to_vec())?;
    Ok(())
}
