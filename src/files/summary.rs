//! `OUTDIR/summary.csv` of batch mode: one row per input, written and
//! flushed as each input is settled, so an interrupted run keeps what it
//! did. The columns and rows are those of the Python command
//! (`uwhl_rs/summary.py`, docs/OUTPUTS.md "summary.csv").

use serde_json::Value;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// The file's name in OUTDIR.
pub const FILE_NAME: &str = "summary.csv";

/// The Jerlov types, one score column each (custom types go to `other_scores`).
const TYPES: [&str; 10] = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"];

/// The columns, in order (as `uwhl_rs.summary.CSV_COLUMNS`).
pub fn columns() -> Vec<String> {
    let mut c: Vec<String> = ["input", "status", "water_type", "A_R", "A_G", "A_B"].map(String::from).to_vec();
    c.extend(TYPES.iter().map(|t| format!("score_{t}")));
    c.extend(
        [
            "other_scores", "flags", "seconds", "taken_at", "latitude", "longitude", "altitude", "image",
            "transmission", "transmission_color", "contact_sheet", "sidecar", "error_kind", "error", "exit_code",
        ]
        .map(String::from),
    );
    c
}

/// A field as the Python csv module writes it: quoted when it holds a
/// comma, a quote or a line break, quotes doubled.
fn field(s: &str) -> String {
    if s.contains([',', '"', '\r', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

use crate::files::metadata::value_text as text;

/// The summary of a batch: made with its first row (a run refused before
/// any input leaves no file), or why it could not be written.
pub struct Summary {
    outdir: std::path::PathBuf,
    out: Option<BufWriter<File>>,
    opened: bool,
    /// the reason it cannot be written, if so
    pub error: Option<String>,
    columns: Vec<String>,
}

impl Summary {
    /// The summary of a batch into `outdir/summary.csv` (started afresh).
    pub fn create(outdir: &Path) -> Self {
        Self { outdir: outdir.to_path_buf(), out: None, opened: false, error: None, columns: columns() }
    }

    fn open(&mut self) {
        self.opened = true;
        let path = self.outdir.join(FILE_NAME);
        let header = self.columns.join(",");
        let opened = std::fs::create_dir_all(&self.outdir).and_then(|()| File::create(&path)).and_then(|f| {
            let mut w = BufWriter::new(f);
            w.write_all(header.as_bytes())?;
            w.write_all(b"\r\n")?;
            w.flush()?;
            Ok(w)
        });
        match opened {
            Ok(w) => self.out = Some(w),
            Err(e) => self.error = Some(format!("cannot write {}: {e}", path.display())),
        }
    }

    fn write(&mut self, row: &serde_json::Map<String, Value>) {
        if !self.opened {
            self.open();
        }
        let Some(w) = self.out.as_mut() else { return };
        let line: Vec<String> = self.columns.iter().map(|c| field(&text(row.get(c)))).collect();
        let ok = w.write_all(line.join(",").as_bytes()).and_then(|()| w.write_all(b"\r\n")).and_then(|()| w.flush());
        if let Err(e) = ok {
            self.error = Some(format!("cannot write {FILE_NAME}: {e}"));
            self.out = None;
        }
    }

    /// A restored input: its sidecar `side`, its outputs in `dir`.
    pub fn done(&mut self, input: &Path, side: &Value, dir: &Path) {
        let mut row = fields_from_sidecar(side, dir);
        row.insert("input".into(), Value::String(input.to_string_lossy().into_owned()));
        row.insert("status".into(), "done".into());
        if let Some(s) = side.pointer("/seconds/total") {
            row.insert("seconds".into(), s.clone());
        }
        // NAME.json beside NAME + the image's extension
        if let Some(image) = side.pointer("/outputs/image").and_then(Value::as_str) {
            row.insert("sidecar".into(), Value::String(path_text(&dir.join(Path::new(image).with_extension("json")))));
        }
        row.insert("exit_code".into(), 0.into());
        self.write(&row);
    }

    /// An input not restored: its sidecar (read for the fields when it is
    /// there) and why.
    pub fn skipped(&mut self, input: &Path, sidecar: &Path, note: &str) {
        let side = std::fs::read(sidecar).ok().and_then(|b| serde_json::from_slice::<Value>(&b).ok());
        let dir = sidecar.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut row = side.map(|s| fields_from_sidecar(&s, &dir)).unwrap_or_default();
        row.insert("input".into(), Value::String(input.to_string_lossy().into_owned()));
        row.insert("status".into(), "skipped".into());
        row.insert("sidecar".into(), Value::String(sidecar.to_string_lossy().into_owned()));
        row.insert("error".into(), note.into());
        row.insert("exit_code".into(), 0.into());
        self.write(&row);
    }

    /// An input that failed: the kind of docs/CLI.md, the message, the exit code.
    pub fn failed(&mut self, input: &Path, kind: &str, message: &str, code: u8) {
        let mut row = serde_json::Map::new();
        row.insert("input".into(), Value::String(input.to_string_lossy().into_owned()));
        row.insert("status".into(), "failed".into());
        row.insert("error_kind".into(), kind.into());
        row.insert("error".into(), message.into());
        row.insert("exit_code".into(), code.into());
        self.write(&row);
    }
}

/// What a row takes from a sidecar (as `uwhl_rs.summary.row_fields_from_sidecar`).
fn fields_from_sidecar(side: &Value, dir: &Path) -> serde_json::Map<String, Value> {
    let mut row = serde_json::Map::new();
    let get = |p: &str| side.pointer(p).cloned().unwrap_or(Value::Null);
    row.insert("water_type".into(), get("/water_type"));
    for (i, c) in ["A_R", "A_G", "A_B"].iter().enumerate() {
        row.insert((*c).into(), get(&format!("/veiling_light/{i}")));
    }
    let mut other = serde_json::Map::new();
    if let Some(scores) = side.get("scores").and_then(Value::as_object) {
        for (t, v) in scores {
            if TYPES.contains(&t.as_str()) {
                row.insert(format!("score_{t}"), v.clone());
            } else {
                other.insert(t.clone(), v.clone());
            }
        }
    }
    if !other.is_empty() {
        row.insert("other_scores".into(), Value::String(Value::Object(other).to_string()));
    }
    let flags: Vec<String> = side
        .get("flags")
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|f| text(Some(f))).collect())
        .unwrap_or_default();
    row.insert("flags".into(), flags.join(",").into());
    row.insert("taken_at".into(), get("/metadata/taken_at"));
    for k in ["latitude", "longitude", "altitude"] {
        row.insert(k.into(), get(&format!("/metadata/gps/{k}")));
    }
    if let Some(outs) = side.get("outputs").and_then(Value::as_object) {
        for (role, name) in outs {
            if let Some(n) = name.as_str() {
                row.insert(role.clone(), Value::String(path_text(&dir.join(n))));
            }
        }
    }
    row
}

fn path_text(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_as_python_csv_quotes_them() {
        assert_eq!(field("plain"), "plain");
        assert_eq!(field("a,b"), "\"a,b\"");
        assert_eq!(field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(field("two\nlines"), "\"two\nlines\"");
    }

    #[test]
    fn a_sidecar_gives_its_row() {
        let side = serde_json::json!({"water_type": "3C", "veiling_light": [0.1, 0.2, 0.3],
            "scores": {"3C": 0.5, "mine": 0.7}, "flags": ["a", "b"], "outputs": {"image": "x.jpg"},
            "metadata": {"taken_at": "2026-11-30T10:15:42", "gps": {"latitude": -33.5, "longitude": 151.0, "altitude": null}}});
        let row = fields_from_sidecar(&side, Path::new("/o"));
        assert_eq!(text(row.get("score_3C")), "0.5");
        assert_eq!(text(row.get("other_scores")), "{\"mine\":0.7}");
        assert_eq!(text(row.get("flags")), "a,b");
        assert_eq!(text(row.get("image")), "/o/x.jpg");
        assert_eq!(text(row.get("latitude")), "-33.5");
        assert_eq!(text(row.get("altitude")), "");
    }
}
