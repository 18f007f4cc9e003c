//! The `_stage_*` entry points of `uwhl_rs._core` (features `python` and
//! `internals`): each stage of the method on its own, as `restore` runs it,
//! for the cross-checks against the NumPy reference of
//! `tests/python/reference.py`. Release wheels are built without them.

use crate::python::{mask_slice, to_py_err, ImageError, ParameterError};
use crate::{ImageRef, WaterType};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

// ---- Stage entry points, for cross-checking against tests/python/reference.py ----
// Thin wrappers over the core's public stage functions; private API.

fn arr3<'py>(py: Python<'py>, v: Vec<f32>, h: usize, w: usize) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, v).reshape([h, w, 3])?.into_any())
}
fn arr2<'py, T: numpy::Element>(
    py: Python<'py>,
    v: Vec<T>,
    h: usize,
    w: usize,
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, v).reshape([h, w])?.into_any())
}
fn img_of<'a>(a: &'a PyReadonlyArray3<'a, f32>) -> PyResult<ImageRef<'a>> {
    let s = a.shape();
    if s.len() != 3 || s[2] != 3 {
        return Err(ImageError::new_err(format!(
            "image has shape {s:?}; expected (H, W, 3)"
        )));
    }
    let d = a
        .as_slice()
        .map_err(|_| ImageError::new_err("image must be C-contiguous"))?;
    ImageRef::new(d, s[0], s[1]).map_err(to_py_err)
}

/// An (H, W, 3) stage of the image and its mask: `f(data, mask)`.
fn rgb_stage<'py>(
    py: Python<'py>,
    image: &PyReadonlyArray3<'py, f32>,
    mask: &Option<PyReadonlyArray2<'py, bool>>,
    f: fn(&[f32], Option<&[bool]>) -> Vec<f32>,
) -> PyResult<Bound<'py, PyAny>> {
    let img = img_of(image)?;
    let m = mask_slice("mask", mask, img.height, img.width)?;
    arr3(py, f(img.data, m), img.height, img.width)
}

/// METHOD §3.1 contrast stretch (statistics over masked-in pixels).
#[pyfunction]
#[pyo3(signature = (image, mask=None))]
fn _stage_stretch<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    mask: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<Bound<'py, PyAny>> {
    rgb_stage(py, &image, &mask, crate::method::stretch::stretch_image)
}

/// METHOD §6 guide image.
#[pyfunction]
#[pyo3(signature = (image, mask=None))]
fn _stage_guide<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    mask: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<Bound<'py, PyAny>> {
    rgb_stage(py, &image, &mask, crate::method::stretch::guide_image)
}

/// Edge map: (E at working size, tau, scale, sigma).
#[pyfunction]
fn _stage_edge_map<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
) -> PyResult<(Bound<'py, PyAny>, f64, usize, f64)> {
    let img = img_of(&image)?;
    let e = crate::method::veiling::edge_map(&img);
    Ok((arr2(py, e.e, e.hs, e.ws)?, e.tau, e.scale, e.sigma))
}

/// Veiling light and water region: (A, VL, flags).
/// A, the water region and the flags of `_stage_veiling`.
type VeilingOut<'py> = ((f32, f32, f32), Bound<'py, PyAny>, Vec<String>);

#[pyfunction]
#[pyo3(signature = (image, mask=None, water_mask=None, veiling_light=None))]
fn _stage_veiling<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    mask: Option<PyReadonlyArray2<'py, bool>>,
    water_mask: Option<PyReadonlyArray2<'py, bool>>,
    veiling_light: Option<(f32, f32, f32)>,
) -> PyResult<VeilingOut<'py>> {
    let img = img_of(&image)?;
    let m = mask_slice("mask", &mask, img.height, img.width)?;
    let wm = mask_slice("water_mask", &water_mask, img.height, img.width)?;
    let v = crate::method::veiling::estimate(&img, m, wm, veiling_light.map(|(r, g, b)| [r, g, b]));
    Ok((
        (v.a[0], v.a[1], v.a[2]),
        arr2(py, v.vl, img.height, img.width)?,
        v.flags.iter().map(|f| f.name().to_string()).collect(),
    ))
}

/// Initial transmission t~ (METHOD §4, after fill and x0.9).
#[pyfunction]
#[pyo3(signature = (image, a, beta_br, beta_bg, n_points=500, mask=None))]
fn _stage_haze_lines<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    a: (f32, f32, f32),
    beta_br: f64,
    beta_bg: f64,
    n_points: usize,
    mask: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<Bound<'py, PyAny>> {
    let img = img_of(&image)?;
    let m = mask_slice("mask", &mask, img.height, img.width)?;
    let wt = WaterType::new("custom", beta_br, beta_bg).map_err(to_py_err)?;
    let idx = crate::method::sphere::SphereIndex::new(n_points).map_err(to_py_err)?;
    let t = crate::method::hazelines::initial_transmission(&img, [a.0, a.1, a.2], &wt, &idx, m);
    arr2(py, t, img.height, img.width)
}

/// Lower bound t_LB (METHOD §5).
#[pyfunction]
fn _stage_lower_bound<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    a: (f32, f32, f32),
    beta_br: f64,
    beta_bg: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let img = img_of(&image)?;
    let wt = WaterType::new("custom", beta_br, beta_bg).map_err(to_py_err)?;
    arr2(
        py,
        crate::method::hazelines::lower_bound(&img, [a.0, a.1, a.2], &wt),
        img.height,
        img.width,
    )
}

/// Squared Mahalanobis distances and matting weights (METHOD §5), or None.
#[pyfunction]
fn _stage_matting<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    vl: PyReadonlyArray2<'py, bool>,
) -> PyResult<Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)>> {
    let img = img_of(&image)?;
    let v = Some(vl);
    let vs = mask_slice("vl", &v, img.height, img.width)?.unwrap_or(&[]);
    match (
        crate::method::matting::mahalanobis_sq(&img, vs),
        crate::method::matting::matting_weights(&img, vs),
    ) {
        (Some(d), Some(w)) => {
            Ok(Some((
                arr2(py, d, img.height, img.width)?,
                arr2(py, w, img.height, img.width)?,
            )))
        }
        _ => Ok(None),
    }
}

/// Color guided filter (METHOD §6).
#[pyfunction]
fn _stage_guided<'py>(
    py: Python<'py>,
    guide: PyReadonlyArray3<'py, f32>,
    p: PyReadonlyArray2<'py, f32>,
    r: usize,
    eps: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let g = img_of(&guide)?;
    let ps = p
        .as_slice()
        .map_err(|_| ParameterError::new_err("p must be C-contiguous"))?;
    if p.shape() != [g.height, g.width] {
        return Err(ParameterError::new_err(
            "p must have the guide's height and width",
        ));
    }
    let gs = crate::method::guided::GuideStats::new(g.data.to_vec(), g.height, g.width, r, eps);
    arr2(py, gs.filter(ps), g.height, g.width)
}

/// Recovery (METHOD §7): (J after the artifact clamp, clamped t_B).
#[pyfunction]
#[pyo3(signature = (image, a, t, beta_br, beta_bg, mask=None))]
fn _stage_recover<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    a: (f32, f32, f32),
    t: PyReadonlyArray2<'py, f32>,
    beta_br: f64,
    beta_bg: f64,
    mask: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let img = img_of(&image)?;
    let m = mask_slice("mask", &mask, img.height, img.width)?;
    let ts = t
        .as_slice()
        .map_err(|_| ParameterError::new_err("t must be C-contiguous"))?;
    if ts.len() != img.len() {
        return Err(ParameterError::new_err(
            "t must have the image's height and width",
        ));
    }
    let wt = WaterType::new("custom", beta_br, beta_bg).map_err(to_py_err)?;
    let (j, tb) = crate::method::recover::recover(&img, [a.0, a.1, a.2], ts, &wt, m);
    Ok((
        arr3(py, j, img.height, img.width)?,
        arr2(py, tb, img.height, img.width)?,
    ))
}

/// Display stretch (METHOD §8), limits from masked-in pixels.
#[pyfunction]
#[pyo3(signature = (j, mask=None))]
fn _stage_display_stretch<'py>(
    py: Python<'py>,
    j: PyReadonlyArray3<'py, f32>,
    mask: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = j.shape();
    if s.len() != 3 || s[2] != 3 {
        return Err(ImageError::new_err(format!(
            "J has shape {s:?}; expected (H, W, 3)"
        )));
    }
    let m = mask_slice("mask", &mask, s[0], s[1])?;
    let d = j
        .as_slice()
        .map_err(|_| ImageError::new_err("J must be C-contiguous"))?;
    arr3(py, crate::method::recover::display_stretch(d, m), s[0], s[1])
}

/// Chart fill (METHOD §6, last paragraph).
#[pyfunction]
fn _stage_chart_fill<'py>(
    py: Python<'py>,
    q: PyReadonlyArray2<'py, f32>,
    mask: PyReadonlyArray2<'py, bool>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = q.shape();
    let (h, w) = (s[0], s[1]);
    let mut v = q
        .as_slice()
        .map_err(|_| ParameterError::new_err("q must be C-contiguous"))?
        .to_vec();
    let m = Some(mask);
    let ms = mask_slice("mask", &m, h, w)?.unwrap_or(&[]);
    crate::method::guided::chart_fill(&mut v, ms, h, w);
    arr2(py, v, h, w)
}

/// Fibonacci sphere points (as stored, f32) and the index's nearest point per row of u.
#[pyfunction]
fn _stage_sphere<'py>(
    py: Python<'py>,
    n: usize,
    u: numpy::PyReadonlyArray2<'py, f32>,
) -> PyResult<(Bound<'py, PyAny>, Vec<usize>)> {
    let idx = crate::method::sphere::SphereIndex::new(n).map_err(to_py_err)?;
    let pts: Vec<f32> = idx.points().iter().flat_map(|p| *p).collect();
    let us = u
        .as_slice()
        .map_err(|_| ParameterError::new_err("u must be C-contiguous"))?;
    let near: Vec<usize> = us
        .chunks_exact(3)
        .map(|c| idx.nearest(&[c[0], c[1], c[2]]))
        .collect();
    Ok((
        PyArray1::from_vec(py, pts).reshape([n, 3])?.into_any(),
        near,
    ))
}


/// Adds the stage entry points to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_stage_stretch, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_guide, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_edge_map, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_veiling, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_haze_lines, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_lower_bound, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_matting, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_guided, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_recover, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_display_stretch, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_chart_fill, m)?)?;
    m.add_function(wrap_pyfunction!(_stage_sphere, m)?)?;
    Ok(())
}
