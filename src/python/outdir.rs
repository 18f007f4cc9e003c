//! pyo3 bindings (feature "python") of [`crate::files::summary`]: the
//! Python command writes its summary.csv rows through the core's writer,
//! so both commands share the columns, the quoting, the neutralised
//! formula cells and the locking of concurrent runs (docs/OUTPUTS.md
//! "summary.csv").

use crate::files::summary::{self, Summary};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value;
use std::sync::{Mutex, PoisonError};

/// Deeper rows than this are not rows of `uwhl_rs.tasks` (they nest one level).
const MAX_DEPTH: usize = 8;

/// A row's value as JSON: text with undecodable bytes of a file name
/// (surrogate escapes) as U+FFFD, as the binary writes them; NaN as empty.
fn value(v: &Bound<'_, PyAny>, depth: usize) -> PyResult<Value> {
    if depth > MAX_DEPTH {
        return Err(PyValueError::new_err("a summary row nests too deep"));
    }
    if v.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = v.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if v.cast::<PyInt>().is_ok() {
        if let Ok(i) = v.extract::<i64>() {
            return Ok(i.into());
        }
        if let Ok(u) = v.extract::<u64>() {
            return Ok(u.into());
        }
        return Ok(Value::String(v.str()?.to_string_lossy().into_owned()));
    }
    if let Ok(f) = v.cast::<PyFloat>() {
        return Ok(serde_json::Number::from_f64(f.value()).map_or(Value::Null, Value::Number));
    }
    if let Ok(s) = v.cast::<PyString>() {
        // a file name's undecodable bytes (surrogate escapes) back to bytes
        // first, so that each is one U+FFFD, as the binary writes it
        let text = match s.extract::<std::ffi::OsString>() {
            Ok(os) => os.to_string_lossy().into_owned(),
            Err(_) => s.to_string_lossy().into_owned(),
        };
        return Ok(Value::String(text));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(Value::Object(map(d, depth + 1)?));
    }
    if v.cast::<PyList>().is_ok() || v.cast::<PyTuple>().is_ok() {
        let items: PyResult<Vec<Value>> = v.try_iter()?.map(|x| value(&x?, depth + 1)).collect();
        return Ok(Value::Array(items?));
    }
    if let Ok(p) = v.extract::<std::path::PathBuf>() {
        return Ok(Value::String(p.to_string_lossy().into_owned()));
    }
    Ok(Value::String(v.str()?.to_string_lossy().into_owned()))
}

fn map(d: &Bound<'_, PyDict>, depth: usize) -> PyResult<serde_json::Map<String, Value>> {
    let mut m = serde_json::Map::new();
    for (k, v) in d.iter() {
        let key = k.str()?.to_string_lossy().into_owned();
        m.insert(key, value(&v, depth)?);
    }
    Ok(m)
}

/// `OUTDIR/summary.csv` of a batch (`crate::files::summary::Summary`):
/// made with its first row; `add` appends one row as `uwhl_rs.tasks`
/// gives it; `error` says why it cannot be written, if so.
#[pyclass(name = "Summary", module = "uwhl_rs._core", frozen)]
struct PySummary {
    inner: Mutex<Summary>,
    path: std::path::PathBuf,
}

#[pymethods]
impl PySummary {
    /// `waiting`: called with the note to say once if another program's
    /// lock keeps the folder (`crate::files::jobs::lock_shared_waiting`);
    /// the folder is then waited for, other threads running meanwhile.
    #[new]
    #[pyo3(signature = (out_dir, waiting=None))]
    fn new(py: Python<'_>, out_dir: std::path::PathBuf, waiting: Option<Py<PyAny>>) -> Self {
        let note = crate::files::jobs::waiting_note(&out_dir);
        let s = py.detach(|| {
            Summary::create_waiting(&out_dir, &mut || {
                if let Some(w) = &waiting {
                    Python::attach(|py| {
                        let _ = w.call1(py, (note.as_str(),));
                    });
                }
            })
        });
        Self { path: s.path(), inner: Mutex::new(s) }
    }

    /// This run's inputs as its rows name them (`Summary::given`): a run
    /// that starts the file afresh keeps the earlier failed rows of others.
    /// Names of undecodable bytes (surrogate escapes) are taken as the rows
    /// write them, each such byte one U+FFFD.
    fn given(&self, inputs: Vec<std::ffi::OsString>) {
        let names = inputs.iter().map(|n| n.to_string_lossy().into_owned());
        self.inner.lock().unwrap_or_else(PoisonError::into_inner).given(names);
    }

    /// The file's path.
    #[getter]
    fn path(&self) -> std::path::PathBuf {
        self.path.clone()
    }

    /// What the run tells the user about the file (an earlier summary's
    /// failures not listed again, and why).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner).notes.clone()
    }

    /// Why the file cannot be written, or None.
    #[getter]
    fn error(&self) -> Option<String> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner).error.clone()
    }

    /// Whether it cannot be written because the folder is read-only.
    #[getter]
    fn read_only(&self) -> bool {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner).read_only
    }

    /// Appends one row (a dict of columns; `scores` a dict, spread over the
    /// score columns), in one locked write.
    fn add(&self, py: Python<'_>, row: &Bound<'_, PyDict>) -> PyResult<()> {
        let row = map(row, 0)?;
        let inner = &self.inner;
        py.detach(|| inner.lock().unwrap_or_else(PoisonError::into_inner).add(row));
        Ok(())
    }

    /// Closes the file (and lets the folder's lock go).
    fn close(&self) {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner).close();
    }
}

/// A summary.csv cell's text as it was before the writer neutralised a
/// formula (`crate::files::summary::restore_cell`): for readers of the file.
#[pyfunction]
fn summary_cell(cell: &str) -> String {
    summary::restore_cell(cell).to_string()
}

/// A text cell as summary.csv writes it (`crate::files::summary::neutralise`:
/// a spreadsheet formula gets a quote in front), for the other CSV files the
/// package writes (`results.csv` of `uwhl evaluate`).
#[pyfunction]
fn csv_text(cell: &str) -> String {
    summary::neutralise(cell)
}

/// What a skipped input's line says after "NAME.json exists": the options
/// the sidecar at `sidecar` recorded that differ from `current` (the
/// JSON of `FileSettings.parameters()`), by their flags, or "" when none do
/// (`crate::files::sidecar::changed_options`, as the binary says it).
#[pyfunction]
fn skipped_with_other_options(sidecar: std::path::PathBuf, current: &str) -> String {
    let Ok(now) = serde_json::from_str::<serde_json::Value>(current) else { return String::new() };
    crate::files::sidecar::changed_said(&crate::files::sidecar::changed_options(&sidecar, &now))
}

/// What an input's progress line says after its water type: a distance
/// asked for and not used, and colours that are the input's balance
/// throughout (`crate::files::sidecar::progress_said`). `flags` are the
/// sidecar's.
#[pyfunction]
fn progress_said(fallback_share: Option<f64>, flags: Vec<String>) -> String {
    let flags: Vec<&str> = flags.iter().map(String::as_str).collect();
    crate::files::sidecar::progress_said(fallback_share, &flags)
}

/// The note printed once before the inputs when a water is given with a
/// source of distance; each argument says whether that option was given
/// (`crate::files::sidecar::water_with_distance_note`).
/// The note said once when `--transfer` is given to a run that may hold no
/// video (`crate::files::sidecar::transfer_note`).
#[pyfunction]
fn transfer_note(transfer: bool, videos: bool) -> Option<String> {
    crate::files::sidecar::transfer_note(transfer, videos)
}

#[pyfunction]
fn water_with_distance_note(water_from: bool, water_type: bool, distance: bool, altitude: bool) -> Option<String> {
    crate::files::sidecar::water_with_distance_note(water_from, water_type, distance, altitude)
}

/// The columns of summary.csv, in order.
#[pyfunction]
fn summary_columns() -> Vec<String> {
    summary::columns()
}

/// The two bases a batch names an input from (`crate::files::jobs::name_bases`):
/// its stem `S`, and `S_E` with E its extension in ASCII lower case.
#[pyfunction]
fn name_bases(path: std::path::PathBuf) -> (String, String) {
    let [s, with_ext] = crate::files::jobs::name_bases(&path);
    (s, with_ext)
}

/// Adds the bindings of this file to `_core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySummary>()?;
    m.add_function(wrap_pyfunction!(summary_cell, m)?)?;
    m.add_function(wrap_pyfunction!(csv_text, m)?)?;
    m.add_function(wrap_pyfunction!(skipped_with_other_options, m)?)?;
    m.add_function(wrap_pyfunction!(progress_said, m)?)?;
    m.add_function(wrap_pyfunction!(water_with_distance_note, m)?)?;
    m.add_function(wrap_pyfunction!(transfer_note, m)?)?;
    m.add("BALANCED_SHARE", crate::method::fallback::BALANCED)?;
    m.add("EARLIER_SUMMARY_BYTES", summary::MAX_EARLIER_BYTES)?;
    m.add_function(wrap_pyfunction!(summary_columns, m)?)?;
    m.add_function(wrap_pyfunction!(name_bases, m)?)?;
    m.add("MAX_NAMES", crate::files::commit::MAX_NAMES)?;
    m.add("FAMILY_GAP", crate::files::commit::FAMILY_GAP)?;
    Ok(())
}
