//! `OUTDIR/summary.csv` of batch mode: one row per input, written and
//! flushed as each input is settled, so an interrupted run keeps what it
//! did. One writer for both commands: the Python command's rows come here
//! through `_core.Summary` (`uwhl_rs.outdir.SummaryWriter`), so the
//! columns, the quoting, the neutralised formulas and the locking live in
//! this file only (docs/OUTPUTS.md "summary.csv").

use serde_json::Value;
use std::fs::File;
use std::io::Write;
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
            "other_scores", "flags", "veil_excess", "fallback_share", "seconds", "taken_at", "latitude", "longitude", "altitude", "image",
            "transmission", "transmission_color", "confidence", "contact_sheet", "sidecar", "error_kind", "error", "exit_code",
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

/// The first characters that make a spreadsheet take a cell as a formula
/// (OWASP, "CSV Injection"): `=`, `+`, `-`, `@`, TAB and CR.
const FORMULA_STARTS: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];

/// A text cell made safe to open in a spreadsheet: one that begins with a
/// formula character gets a single quote in front (OWASP's advice), so
/// `=HYPERLINK(...)` in a file name is shown, never evaluated. A cell that
/// already begins with a quote followed by such a character (or by a
/// second quote) gets one too, so that [`restore_cell`] gives back every
/// text exactly. Numbers are never text cells here: `-33.5` stays a number.
pub fn neutralise(s: &str) -> String {
    let mut c = s.chars();
    let guard = match c.next() {
        Some(first) if FORMULA_STARTS.contains(&first) => true,
        Some('\'') => c.next().is_some_and(|second| second == '\'' || FORMULA_STARTS.contains(&second)),
        _ => false,
    };
    if guard {
        format!("'{s}")
    } else {
        s.to_string()
    }
}

/// The text a reader of summary.csv gets back from a cell written through
/// [`neutralise`] (the inverse: the one quote taken off).
pub fn restore_cell(s: &str) -> &str {
    let mut c = s.chars();
    match (c.next(), c.next()) {
        (Some('\''), Some(second)) if second == '\'' || FORMULA_STARTS.contains(&second) => &s[1..],
        _ => s,
    }
}

/// A cell of a row: text neutralised and quoted, numbers as JSON writes them.
fn cell(v: Option<&Value>) -> String {
    match v {
        Some(Value::String(s)) => field(&neutralise(s)),
        other => field(&text(other)),
    }
}

use crate::files::metadata::value_text as text;

/// Opens `path` for appending without following a link at its name
/// (`O_NOFOLLOW`: a link planted there fails with ELOOP, never written through).
/// `O_NONBLOCK` too: a FIFO planted there fails at once instead of
/// waiting for a reader, and anything but a regular file is refused.
fn open_append(path: &Path, create: bool) -> std::io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    let f = std::fs::OpenOptions::new()
        .append(true)
        .create(create)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)?;
    if !f.metadata()?.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    Ok(f)
}

/// A clear message for a failed open: a link named as such.
fn open_error(path: &Path, e: &std::io::Error) -> std::io::Error {
    if e.raw_os_error() == Some(libc::ELOOP) {
        std::io::Error::other(format!("cannot write {}: it is a symbolic link (not written through)", path.display()))
    } else {
        std::io::Error::new(e.kind(), format!("cannot write {}: {e}", path.display()))
    }
}

/// A file's size and modification time.
type Stamp = Option<(u64, std::time::SystemTime)>;

/// What a run found when it started: whether it was alone, and the file's [`Stamp`].
type Start = (bool, Stamp);

/// The size and modification time of the file at `path`, if there is one.
fn stamp(path: &Path) -> Stamp {
    std::fs::symlink_metadata(path).ok().and_then(|m| Some((m.len(), m.modified().ok()?)))
}

/// The summary of a batch: made with its first row (a run refused before
/// any input leaves no file), or why it could not be written.
///
/// Each row is appended in one write under an exclusive `flock` of the
/// file, opened for that row `O_APPEND | O_NOFOLLOW` (a link planted at
/// the name fails with its name, never written through), so that two runs
/// on one output folder (docs/OUTPUTS.md) give every row once, none
/// spliced. Every writer holds a shared `flock` of the output folder while
/// it runs: one that can take it exclusively is alone and starts the file
/// afresh (a new file with the header, through an exclusive temporary
/// renamed into place: whatever was at the name, a link included, is
/// replaced, its target never touched); one that cannot appends to the
/// running one's file.
pub struct Summary {
    outdir: std::path::PathBuf,
    /// the output folder, its lock held shared while the summary is in use
    presence: Option<File>,
    /// the folder remembered as held (`crate::files::jobs::outdir_moved`)
    mark: Option<crate::files::jobs::Mark>,
    /// when the run started: whether it was alone (no other run held the
    /// folder's lock), and the file's size and time then
    start: Option<Start>,
    opened: bool,
    /// the reason it cannot be written, if so
    pub error: Option<String>,
    /// it cannot be written because the output folder is read-only: on a
    /// read-only file system, or by its permissions (`chmod a-w`, an
    /// immutable file: a finished survey shared) (a rerun over an archived
    /// survey: see docs/OUTPUTS.md)
    pub read_only: bool,
    columns: Vec<String>,
    /// this run's inputs, by [`input_key`] ([`Summary::given`])
    given: Option<std::collections::HashSet<String>>,
    /// the earlier failed rows of inputs given, not yet written again
    pending: Vec<(String, String)>,
    /// what the run tells the user about the file (earlier failures not kept)
    pub notes: Vec<String>,
}

impl Drop for Summary {
    fn drop(&mut self) {
        self.close();
    }
}

impl Summary {
    /// The summary of a batch into `outdir/summary.csv` (started afresh).
    /// The folder's shared lock is taken now, when the run starts, so that
    /// a run starting later and writing its first row sooner does not take
    /// itself for alone and start the file afresh over this run's rows.
    pub fn create(outdir: &Path) -> Self {
        Self::create_waiting(outdir, &mut || {})
    }

    /// [`Summary::create`], calling `waiting` once if another program's
    /// lock keeps the folder (`crate::files::jobs::lock_shared_waiting`).
    pub fn create_waiting(outdir: &Path, waiting: &mut dyn FnMut()) -> Self {
        let mut start = None;
        let presence = File::open(outdir).ok().filter(|f| {
            // exclusive if no other run holds it, then (a conversion) shared
            let alone = f.try_lock().is_ok();
            start = Some((alone, stamp(&outdir.join(FILE_NAME))));
            crate::files::jobs::lock_shared_waiting(f, waiting)
        });
        let start = presence.as_ref().and(start);
        let mark = presence.as_ref().map(|f| crate::files::jobs::Mark::new(outdir, f));
        Self {
            outdir: outdir.to_path_buf(),
            presence,
            mark,
            start,
            opened: false,
            error: None,
            read_only: false,
            columns: columns(),
            given: None,
            pending: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// This run's inputs, as its rows' `input` cells will name them. A run
    /// that starts the file afresh then keeps the earlier file's failed
    /// rows ([`earlier_failures`]): those of other inputs at once, those of
    /// its own inputs when it ends, unless it wrote a row for them (an
    /// interrupted run loses none). A folder restored in several runs lists
    /// each failure until a run restores or retries that input. Without
    /// it nothing is kept.
    pub fn given<I: IntoIterator<Item = String>>(&mut self, inputs: I) {
        self.given = Some(inputs.into_iter().map(|n| input_key(&n)).collect());
    }

    /// The path of the file.
    pub fn path(&self) -> std::path::PathBuf {
        self.outdir.join(FILE_NAME)
    }

    fn fail(&mut self, e: &std::io::Error) {
        self.read_only = matches!(e.kind(), std::io::ErrorKind::ReadOnlyFilesystem | std::io::ErrorKind::PermissionDenied);
        self.error = Some(e.to_string());
    }

    fn open(&mut self) {
        self.opened = true;
        let held = self.presence.take().zip(self.start);
        match self.try_open(held) {
            Ok(presence) => self.presence = Some(presence),
            Err(e) => self.fail(&e),
        }
    }

    /// `held`: the folder, its shared lock taken when the run started, and
    /// what the run found then. The file starts afresh when the run was
    /// alone at its start and nobody wrote the file since (a run that
    /// started later and finished sooner wrote its rows there: they stay).
    fn try_open(&mut self, held: Option<(File, Start)>) -> std::io::Result<File> {
        let path = self.path();
        let fail = |e: std::io::Error| std::io::Error::new(e.kind(), format!("cannot write {}: {e}", path.display()));
        std::fs::create_dir_all(&self.outdir).map_err(fail)?;
        let header = format!("{}\r\n", self.columns.join(","));
        let presence = match held {
            Some((f, (alone, then))) => {
                if !(alone && stamp(&path) == then) {
                    return Ok(f);
                }
                // alone since the start: converted to exclusive (it fails
                // if a run that started since holds its shared lock)
                match f.try_lock() {
                    Ok(()) => {}
                    Err(std::fs::TryLockError::WouldBlock) => return Ok(f),
                    Err(std::fs::TryLockError::Error(e)) => return Err(fail(e)),
                }
                f.unlock().map_err(fail)?;
                f
            }
            None => File::open(&self.outdir).map_err(fail)?,
        };
        match presence.try_lock() {
            // alone: a new file. A run starting while this one takes the
            // shared lock below (the exclusive one is let go first) may
            // think itself alone too and replace the file: it holds the
            // header only then, and rows open the file anew, so none is lost
            Ok(()) => {
                let earlier = self.given.as_ref().map(|g| earlier_failures(&path, g, &self.columns)).unwrap_or_default();
                let (tmp, mut t) = crate::files::commit::create_temp_for(&path).map_err(fail)?;
                let written = t.write_all(header.as_bytes()).and_then(|()| t.write_all(earlier.kept.as_bytes())).and_then(|()| t.sync_all());
                drop(t);
                if let Err(e) = written.and_then(|()| std::fs::rename(&tmp, &path)) {
                    let _ = std::fs::remove_file(&tmp);
                    return Err(fail(e));
                }
                self.pending = earlier.pending;
                self.notes.extend(earlier.note);
                presence.unlock().map_err(fail)?;
                // (another program's long exclusive lock: the run goes on without its hold)
                crate::files::jobs::lock_shared_within(&presence);
            }
            // another run writes the file: its rows and this run's go in it
            // (a missing file is made by the first row, with the header)
            Err(std::fs::TryLockError::WouldBlock) => {
                crate::files::jobs::lock_shared_within(&presence);
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(fail(e)),
        }
        Ok(presence)
    }

    /// Appends one row: its columns taken from `row` by name (missing ones
    /// empty), text neutralised ([`neutralise`]) and quoted, in one write
    /// under the file's lock.
    pub fn write(&mut self, row: &serde_json::Map<String, Value>) {
        if let Some(why) = crate::files::jobs::outdir_moved(&self.path()) {
            self.fail(&std::io::Error::other(why));
            self.opened = true;
            self.presence = None;
            return;
        }
        if !self.opened {
            self.open();
        }
        if self.presence.is_none() {
            return;
        }
        let mut line: String = self.columns.iter().map(|c| cell(row.get(c))).collect::<Vec<_>>().join(",");
        line.push_str("\r\n");
        if !self.pending.is_empty() {
            // this input's own row now stands for it: its earlier failure is not written again
            let key = input_key(&text(row.get("input")));
            self.pending.retain(|(k, _)| *k != key);
        }
        self.append(line);
    }

    /// Appends `line` (whole rows, CRLF-ended) in one write under the file's lock.
    fn append(&mut self, mut line: String) {
        let path = self.path();
        let header = &self.columns;
        let ok = open_append(&path, true).map_err(|e| open_error(&path, &e)).and_then(|f| {
            f.lock()?;
            // removed while the batch runs: made again, with its header
            let r = f.metadata().and_then(|m| {
                if m.len() == 0 {
                    line.insert_str(0, &format!("{}\r\n", header.join(",")));
                }
                let w = (&f).write_all(line.as_bytes());
                if w.is_err() {
                    // a full disk cut the row: what was written of it goes
                    // (under the lock, nobody appended since), so that the
                    // file holds whole rows only
                    let _ = f.set_len(m.len());
                }
                w
            });
            let _ = f.unlock();
            r
        });
        if let Err(e) = ok {
            self.fail(&e);
            self.presence = None;
        }
    }

    /// Appends a row given as the Python command's rows are (`uwhl_rs.tasks`):
    /// `scores` (an object) spread over the score columns and
    /// `other_scores`, `flags` (a list) joined with commas; a skipped row
    /// without the fields gets them from its sidecar (a local file).
    #[cfg_attr(not(feature = "python"), allow(dead_code))]
    pub fn add(&mut self, mut row: serde_json::Map<String, Value>) {
        if let Some(Value::Object(scores)) = row.remove("scores") {
            spread_scores(&scores, &mut row);
        }
        if let Some(Value::Array(flags)) = row.get("flags") {
            let joined: Vec<String> = flags.iter().map(|f| text(Some(f))).collect();
            row.insert("flags".into(), joined.join(",").into());
        }
        let skipped = row.get("status").and_then(Value::as_str) == Some("skipped");
        if skipped && row.get("water_type").is_none_or(Value::is_null) {
            if let Some(sidecar) = row.get("sidecar").and_then(Value::as_str).map(std::path::PathBuf::from) {
                if let Some(side) = crate::files::commit::read_sidecar(&sidecar) {
                    let dir = sidecar.parent().map(Path::to_path_buf).unwrap_or_default();
                    for (k, v) in fields_from_sidecar(&side, &dir) {
                        if row.get(&k).is_none_or(Value::is_null) {
                            row.insert(k, v);
                        }
                    }
                }
            }
        }
        self.write(&row);
    }

    /// Closes the file and lets the folder's lock go (also when dropped),
    /// after the earlier failures of inputs this run was given and did not
    /// settle (it was interrupted) are written again.
    pub fn close(&mut self) {
        let pending = std::mem::take(&mut self.pending);
        if !pending.is_empty() && self.presence.is_some() {
            self.append(pending.into_iter().map(|(_, line)| line).collect());
        }
        self.presence = None;
        self.mark = None;
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
        let side = crate::files::commit::read_sidecar(sidecar);
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
    if let Some(scores) = side.get("scores").and_then(Value::as_object) {
        spread_scores(scores, &mut row);
    }
    let flags: Vec<String> = side
        .get("flags")
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|f| text(Some(f))).collect())
        .unwrap_or_default();
    row.insert("flags".into(), flags.join(",").into());
    row.insert("veil_excess".into(), get("/veil_excess"));
    row.insert("fallback_share".into(), get("/fallback_share"));
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

/// The Jerlov types' scores in their columns, the others (custom types) as
/// JSON in `other_scores`.
fn spread_scores(scores: &serde_json::Map<String, Value>, row: &mut serde_json::Map<String, Value>) {
    let mut other = serde_json::Map::new();
    for (t, v) in scores {
        if TYPES.contains(&t.as_str()) {
            row.insert(format!("score_{t}"), v.clone());
        } else {
            other.insert(t.clone(), v.clone());
        }
    }
    if !other.is_empty() {
        row.insert("other_scores".into(), Value::String(Value::Object(other).to_string()));
    }
}

fn path_text(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// The largest earlier summary read for its failed rows (larger: none kept, said).
pub const MAX_EARLIER_BYTES: u64 = 64 << 20;
/// A field or a record longer than these is no row of ours (as the report reads it).
const MAX_FIELD_BYTES: usize = 128 << 10;
const MAX_RECORD_BYTES: usize = 1 << 20;
/// The most earlier failures kept (the latest ones), so that a planted
/// file of tiny failed rows cannot make the new summary many times larger.
const MAX_KEPT: usize = 100_000;

/// The records of a CSV stream as this writer and Python's csv module
/// write them (fields quoted when needed, quotes doubled; CRLF, LF or CR
/// ends), one at a time with the byte offset where each starts; a record
/// that is no row of ours (an unclosed quote, text after a closing quote,
/// bytes that are not UTF-8, a field or record over the limits) comes as
/// None, and the reading goes on at the next line end.
struct Records<R> {
    inner: R,
    at: u64,
}

impl<R: std::io::BufRead> Records<R> {
    fn new(inner: R) -> Self {
        Self { inner, at: 0 }
    }

    fn byte(&mut self) -> Option<u8> {
        let b = *self.inner.fill_buf().ok()?.first()?;
        self.inner.consume(1);
        self.at += 1;
        Some(b)
    }

    fn peek(&mut self) -> Option<u8> {
        self.inner.fill_buf().ok()?.first().copied()
    }

    /// The next record and where it starts; None at the end.
    fn next_record(&mut self) -> Option<(u64, Option<Vec<String>>)> {
        let start = self.at;
        let first = self.byte()?;
        let (mut fields, mut cur): (Vec<Vec<u8>>, Vec<u8>) = (Vec::new(), Vec::new());
        let (mut quoted, mut closed, mut bad, mut size) = (false, false, false, 0usize);
        let mut b = Some(first);
        while let Some(c) = b {
            size += 1;
            bad |= cur.len() > MAX_FIELD_BYTES || size > MAX_RECORD_BYTES;
            if bad {
                // no row of ours: skipped to the next line end
                if c == b'\n' || (c == b'\r' && !quoted) {
                    if c == b'\r' && self.peek() == Some(b'\n') {
                        self.byte();
                    }
                    break;
                }
                b = self.byte();
                continue;
            }
            if quoted {
                match c {
                    b'"' if self.peek() == Some(b'"') => {
                        self.byte();
                        cur.push(b'"');
                    }
                    b'"' => (quoted, closed) = (false, true),
                    _ => cur.push(c),
                }
            } else {
                match c {
                    b'"' if cur.is_empty() && !closed => quoted = true,
                    b',' => {
                        fields.push(std::mem::take(&mut cur));
                        closed = false;
                    }
                    b'\r' | b'\n' => {
                        if c == b'\r' && self.peek() == Some(b'\n') {
                            self.byte();
                        }
                        break;
                    }
                    _ if closed => bad = true,
                    _ => cur.push(c),
                }
            }
            b = self.byte();
        }
        if quoted {
            bad = true;
        }
        fields.push(cur);
        let record = (!bad).then(|| fields.into_iter().map(String::from_utf8).collect::<Result<Vec<_>, _>>().ok()).flatten();
        Some((start, record))
    }
}

/// The name an input's row is matched by across runs and both commands:
/// a URL as written; a path made absolute (from the current folder) and
/// its `.` and `..` parts and doubled slashes taken out, as text
/// (`./cam/a.jpg`, `cam//a.jpg` and `/abs/cam/a.jpg` are one input).
pub fn input_key(name: &str) -> String {
    if name.contains("://") {
        return name.to_string();
    }
    let p = Path::new(name);
    let abs = if p.is_absolute() { p.to_path_buf() } else { std::env::current_dir().unwrap_or_default().join(p) };
    let mut out = std::path::PathBuf::new();
    for c in abs.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out.to_string_lossy().into_owned()
}

/// What a run keeps of the earlier summary it replaces ([`earlier_failures`]).
#[derive(Debug, Default)]
struct Earlier {
    /// lines to write after the header: the failed rows of inputs not given
    kept: String,
    /// the failed rows of inputs given: written when the run ends unless it
    /// wrote a row for that input (an interrupted run loses none), by key
    pending: Vec<(String, String)>,
    /// what the user is told (a file not read, failures left out)
    note: Option<String>,
}

/// A kept row's cells moved under `columns` by name: a text cell is
/// neutralised again ([`neutralise`] of [`restore_cell`]: the same bytes
/// for a cell of ours, a planted formula made safe); a number stays as
/// written. CRLF-ended.
fn kept_line(head: &[String], row: &[String], columns: &[String]) -> String {
    let cells: Vec<String> = columns
        .iter()
        .map(|c| {
            let v = head.iter().position(|h| h == c).and_then(|k| row.get(k)).map_or("", String::as_str);
            if v.parse::<f64>().is_ok_and(f64::is_finite) {
                field(v)
            } else {
                field(&neutralise(restore_cell(v)))
            }
        })
        .collect();
    let mut line = cells.join(",");
    line.push_str("\r\n");
    line
}

/// The earlier summary at `path`, read for its failures: every input whose
/// last row failed is kept ([`Earlier`]), the latest [`MAX_KEPT`] of them.
/// The file is read twice as a stream (its records' input keys, hashed
/// with a random key, and offsets; then the kept records), so memory
/// follows the number of rows, 16 bytes each, never the file's text.
/// Nothing is kept from a file that is not regular (a link at the name is
/// not followed), is over [`MAX_EARLIER_BYTES`], or has no `input` and
/// `status` columns; a record that is no row of ours is passed over.
fn earlier_failures(path: &Path, given: &std::collections::HashSet<String>, columns: &[String]) -> Earlier {
    use std::hash::BuildHasher;
    use std::io::{BufReader, Seek};
    use std::os::unix::fs::OpenOptionsExt;
    let Ok(f) = std::fs::OpenOptions::new().read(true).custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK).open(path) else {
        return Earlier::default();
    };
    let Ok(meta) = f.metadata() else { return Earlier::default() };
    if !meta.is_file() {
        return Earlier::default();
    }
    let not_kept = |why: String| Earlier { note: Some(format!("the earlier {FILE_NAME} {why}: its failures are not listed again")), ..Earlier::default() };
    if meta.len() > MAX_EARLIER_BYTES {
        return not_kept(format!("is over {} MiB", MAX_EARLIER_BYTES >> 20));
    }
    let mut records = Records::new(BufReader::new(&f));
    let head = match records.next_record() {
        Some((_, Some(mut h))) => {
            if let Some(first) = h.first_mut() {
                *first = first.trim_start_matches('\u{feff}').to_string();
            }
            h
        }
        _ => return not_kept("has no header".into()),
    };
    let at = |name: &str| head.iter().position(|h| h == name);
    let (Some(input), Some(status)) = (at("input"), at("status")) else {
        return not_kept("is not a summary of ours (no input and status columns)".into());
    };
    let hasher = std::collections::hash_map::RandomState::new();
    // (key hash, record offset, failed), 16 bytes a row
    let mut rows: Vec<(u64, u32, bool)> = Vec::new();
    while let Some((offset, record)) = records.next_record() {
        let Some(r) = record.filter(|r| r.len() == head.len()) else { continue };
        let (Some(name), Some(state), Ok(offset)) = (r.get(input), r.get(status), u32::try_from(offset)) else { continue };
        rows.push((hasher.hash_one(input_key(restore_cell(name))), offset, state == "failed"));
    }
    // each input's last row decides: a failure restored since is not kept
    rows.sort_unstable_by_key(|&(h, o, _)| (h, o));
    let mut last: Vec<u32> = rows
        .iter()
        .enumerate()
        .filter(|&(i, &(h, _, failed))| failed && rows.get(i + 1).is_none_or(|n| n.0 != h))
        .map(|(_, &(_, o, _))| o)
        .collect();
    drop(rows);
    last.sort_unstable();
    let mut out = Earlier::default();
    if last.len() > MAX_KEPT {
        out.note = Some(format!(
            "the earlier {FILE_NAME} lists {} failures: the latest {MAX_KEPT} are listed again",
            last.len()
        ));
        last.drain(..last.len() - MAX_KEPT);
    }
    let mut reader = BufReader::new(&f);
    for o in last {
        if reader.seek(std::io::SeekFrom::Start(u64::from(o))).is_err() {
            break;
        }
        let mut one = Records::new(&mut reader);
        let Some((_, Some(r))) = one.next_record() else { continue };
        let key = input_key(restore_cell(r.get(input).map_or("", String::as_str)));
        let line = kept_line(&head, &r, columns);
        if given.contains(&key) {
            out.pending.push((key, line));
        } else {
            out.kept.push_str(&line);
        }
    }
    out
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_read_only_by_mount_or_by_permissions_is_read_only() {
        use std::io::{Error, ErrorKind};
        let mut s = Summary { outdir: std::path::PathBuf::from("/o"), presence: None, mark: None, start: None, opened: false, error: None, read_only: false, columns: columns(), given: None, pending: Vec::new(), notes: Vec::new() };
        for (kind, want) in [(ErrorKind::ReadOnlyFilesystem, true), (ErrorKind::PermissionDenied, true), (ErrorKind::StorageFull, false)] {
            s.fail(&Error::from(kind));
            assert_eq!(s.read_only, want, "{kind:?}");
        }
        // EPERM (an immutable file) is a permission too
        s.fail(&Error::from_raw_os_error(1));
        assert!(s.read_only);
    }

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

    fn folder(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("uwhl-summary-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn formula_cells_are_neutralised_and_given_back_exactly() {
        for (given, written) in [
            ("=HYPERLINK(\"http://x\")", "'=HYPERLINK(\"http://x\")"),
            ("+1", "'+1"),
            ("-2", "'-2"),
            ("@SUM(A1)", "'@SUM(A1)"),
            ("\tx", "'\tx"),
            ("\rx", "'\rx"),
            ("'=x", "''=x"),
            ("''", "'''"),
            ("'a", "'a"),
            ("'", "'"),
            ("a=b", "a=b"),
            ("", ""),
        ] {
            assert_eq!(neutralise(given), written, "{given:?}");
            assert_eq!(restore_cell(written), given, "{written:?}");
        }
        // numbers stay numbers, text is neutralised
        assert_eq!(cell(Some(&serde_json::json!(-33.5))), "-33.5");
        assert_eq!(cell(Some(&serde_json::json!("-33.5"))), "'-33.5");
        assert_eq!(cell(Some(&serde_json::json!("=1,2"))), "\"'=1,2\"");
    }

    #[test]
    fn a_link_at_summary_csv_is_replaced_never_written_through() {
        let d = folder("link");
        let victim = d.join("victim.txt");
        std::fs::write(&victim, b"keep").unwrap();
        let out = d.join("out");
        std::fs::create_dir_all(&out).unwrap();
        std::os::unix::fs::symlink(&victim, out.join(FILE_NAME)).unwrap();
        let mut s = Summary::create(&out);
        s.failed(Path::new("a.jpg"), "unreadable_input", "bad", 3);
        s.close();
        assert!(s.error.is_none(), "{:?}", s.error);
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
        let m = std::fs::symlink_metadata(out.join(FILE_NAME)).unwrap();
        assert!(m.is_file());
        let text = std::fs::read_to_string(out.join(FILE_NAME)).unwrap();
        assert!(text.starts_with("input,status,") && text.contains("a.jpg,failed"), "{text}");
        // a link planted while another run writes (the file is joined, not
        // replaced): refused with its name, not written through
        let mut first = Summary::create(&out);
        first.failed(Path::new("b.jpg"), "unreadable_input", "bad", 3);
        std::fs::remove_file(out.join(FILE_NAME)).unwrap();
        std::os::unix::fs::symlink(&victim, out.join(FILE_NAME)).unwrap();
        let mut second = Summary::create(&out);
        second.failed(Path::new("c.jpg"), "unreadable_input", "bad", 3);
        assert!(second.error.as_deref().is_some_and(|e| e.contains("symbolic link")), "{:?}", second.error);
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
        // a FIFO planted there: refused at once, not waited on
        std::fs::remove_file(out.join(FILE_NAME)).unwrap();
        assert!(std::process::Command::new("mkfifo").arg(out.join(FILE_NAME)).status().unwrap().success());
        let mut third = Summary::create(&out);
        third.failed(Path::new("d.jpg"), "unreadable_input", "bad", 3);
        assert!(third.error.as_deref().is_some_and(|e| e.contains("summary.csv")), "{:?}", third.error);
        drop(first);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_run_that_started_first_keeps_the_rows_of_one_that_finished_first() {
        // the slow run holds the folder from its start: the quick one joins
        // the file; when the slow one writes its first row, after the quick
        // one finished, the file is not started afresh over the quick rows
        let d = folder("late-first-row");
        let out = d.join("out");
        std::fs::create_dir_all(&out).unwrap();
        let mut old = Summary::create(&out);
        old.failed(Path::new("old"), "internal", "x", 6);
        old.close();
        let mut slow = Summary::create(&out);
        let mut quick = Summary::create(&out);
        quick.failed(Path::new("quick"), "internal", "x", 6);
        quick.close();
        slow.failed(Path::new("slow"), "internal", "x", 6);
        slow.close();
        let text = std::fs::read_to_string(out.join(FILE_NAME)).unwrap();
        let inputs: Vec<&str> = text.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
        assert!(inputs.contains(&"quick") && inputs.contains(&"slow"), "{text}");
        assert_eq!(text.lines().filter(|l| l.starts_with("input,")).count(), 1, "{text}");
        // a run alone from start to first row still starts the file afresh
        let mut next = Summary::create(&out);
        next.failed(Path::new("again"), "internal", "x", 6);
        next.close();
        assert_eq!(std::fs::read_to_string(out.join(FILE_NAME)).unwrap().lines().count(), 2);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn concurrent_writers_give_every_row_once_and_a_later_run_starts_afresh() {
        let d = folder("concurrent");
        let out = d.join("out");
        // the first writer is open before the others start: they join its file
        let mut first = Summary::create(&out);
        first.failed(Path::new("first"), "internal", "x", 6);
        let threads: Vec<_> = (0..4)
            .map(|t| {
                let out = out.clone();
                std::thread::spawn(move || {
                    let mut s = Summary::create(&out);
                    for k in 0..200 {
                        let long = format!("{t}-{k}-{}", "y".repeat(3000));
                        s.failed(Path::new(&format!("in{t}_{k}")), "internal", &long, 6);
                    }
                    assert!(s.error.is_none(), "{:?}", s.error);
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        first.close();
        let text = std::fs::read_to_string(out.join(FILE_NAME)).unwrap();
        let lines: Vec<&str> = text.split("\r\n").filter(|l| !l.is_empty()).collect();
        assert_eq!(lines[0], columns().join(","));
        assert_eq!(lines.iter().filter(|l| l.starts_with("input,")).count(), 1);
        let mut inputs: Vec<&str> = lines[1..].iter().map(|l| l.split(',').next().unwrap()).collect();
        assert_eq!(inputs.len(), 801);
        inputs.sort_unstable();
        inputs.dedup();
        assert_eq!(inputs.len(), 801);
        for l in &lines[1..] {
            assert_eq!(l.split(',').count(), columns().len(), "{}", &l[..40.min(l.len())]);
        }
        // alone again: the next run's file has its own rows only
        let mut next = Summary::create(&out);
        next.failed(Path::new("again"), "internal", "x", 6);
        next.close();
        let text = std::fs::read_to_string(out.join(FILE_NAME)).unwrap();
        assert_eq!(text.lines().count(), 2, "{text}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_python_row_is_spread_and_a_skipped_one_filled_from_its_sidecar() {
        let d = folder("add");
        let side = serde_json::json!({"water_type": "3C", "veiling_light": [0.1, 0.2, 0.3],
            "scores": {"3C": 0.5}, "flags": ["f"], "outputs": {"image": "a.jpg"}});
        std::fs::write(d.join("a.json"), side.to_string()).unwrap();
        let mut s = Summary::create(&d);
        let row = |v: Value| v.as_object().cloned().unwrap();
        s.add(row(serde_json::json!({"input": "b.jpg", "status": "done", "water_type": "II",
            "scores": {"II": 0.25, "mine": 1.0}, "flags": "x,y", "exit_code": 0})));
        s.add(row(serde_json::json!({"input": "a.jpg", "status": "skipped", "water_type": null,
            "sidecar": d.join("a.json"), "error": "already done", "exit_code": 0})));
        s.close();
        let text = std::fs::read_to_string(d.join(FILE_NAME)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let col = |line: &str, name: &str| {
            let k = columns().iter().position(|c| c == name).unwrap();
            line.split(',').nth(k).unwrap_or_default().to_string()
        };
        assert_eq!(col(lines[1], "score_II"), "0.25");
        assert_eq!(col(lines[1], "water_type"), "II");
        assert!(lines[1].contains("\"{\"\"mine\"\":1.0}\""), "{}", lines[1]);
        assert_eq!(col(lines[2], "water_type"), "3C");
        assert_eq!(col(lines[2], "score_3C"), "0.5");
        assert_eq!(col(lines[2], "image"), d.join("a.jpg").display().to_string());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_fifo_at_a_skipped_inputs_sidecar_is_not_waited_on() {
        let d = folder("fifo");
        let fifo = d.join("a.json");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        assert!(crate::files::commit::read_sidecar(&fifo).is_none());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_run_given_other_inputs_keeps_the_earlier_failures_and_only_those() {
        let d = folder("carry");
        let path = d.join(FILE_NAME);
        let given = |names: &[&str]| names.iter().map(|n| n.to_string()).collect::<Vec<_>>();
        let read = || records(&std::fs::read_to_string(&path).unwrap());
        // run 1: a done, "=bad, x.jpg" failed (a formula and a comma), c failed then done
        let mut s = Summary::create(&d);
        s.given(given(&["a", "=bad, x.jpg", "c"]));
        let side = serde_json::json!({"water_type": "II", "veiling_light": [-0.5, 0.2, 0.3]});
        s.done(Path::new("a"), &side, &d);
        s.failed(Path::new("=bad, x.jpg"), "unreadable_input", "cannot decode \"it\"\nat all", 3);
        s.failed(Path::new("c"), "internal", "x", 6);
        s.done(Path::new("c"), &side, &d);
        s.close();
        let first = std::fs::read_to_string(&path).unwrap();
        let bad_row = first.split("\r\n").find(|l| l.starts_with("\"'=bad")).unwrap().to_string();
        // run 2 is given b only: the earlier failure of "=bad, x.jpg" stays, byte for byte, then b's row
        let mut s = Summary::create(&d);
        s.given(given(&["b"]));
        s.failed(Path::new("b"), "unreadable_input", "no", 3);
        s.close();
        let text = std::fs::read_to_string(&path).unwrap();
        let rows = read();
        assert_eq!(rows.len(), 3, "{text}");
        assert_eq!(rows[0], columns());
        assert!(text.contains(&format!("\r\n{bad_row}\r\n")), "{text}");
        assert_eq!(restore_cell(&rows[1][0]), "=bad, x.jpg");
        assert_eq!(rows[1][columns().iter().position(|c| c == "error").unwrap()], "cannot decode \"it\"\nat all");
        assert_eq!(rows[2][0], "b");
        // run 3 is given the failed input again, spelled otherwise: its old row goes, its new one stays
        let mut s = Summary::create(&d);
        s.given(given(&["./=bad, x.jpg"]));
        s.failed(Path::new("./=bad, x.jpg"), "unreadable_input", "again", 3);
        s.close();
        let rows = read();
        assert_eq!(rows.len(), 3, "b's failure kept, one row for =bad");
        assert_eq!((rows[1][0].as_str(), restore_cell(&rows[2][0])), ("b", "./=bad, x.jpg"));
        // run 4 is given b and stops before settling it (interrupted): b's failure is written again at the end
        let mut s = Summary::create(&d);
        s.given(given(&["b", "e"]));
        s.failed(Path::new("e"), "internal", "x", 6);
        drop(s);
        let rows = read();
        let names: Vec<&str> = rows[1..].iter().map(|r| r[0].as_str()).collect();
        assert_eq!(names, ["./=bad, x.jpg", "e", "b"], "{rows:?}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn what_is_not_a_summary_of_ours_keeps_nothing_and_says_so() {
        let d = folder("planted");
        let path = d.join(FILE_NAME);
        let none = std::collections::HashSet::new();
        // a formula in a failed row is neutralised; a number stays a number; a BOM and CR-only ends are read
        let mut head = columns();
        head.truncate(4);
        std::fs::write(&path, format!("\u{feff}{}\r=HYPERLINK(1),failed,-2,-33.5\r", head.join(","))).unwrap();
        let e = earlier_failures(&path, &none, &columns());
        assert!(e.kept.starts_with("'=HYPERLINK(1),failed,-2,-33.5,") && e.note.is_none(), "{e:?}");
        // a record that is no row of ours is passed over, the others kept
        std::fs::write(&path, b"input,status\r\n\"x\"z,failed\r\n\xff\xfe,failed\r\ny,failed\r\n").unwrap();
        let e = earlier_failures(&path, &none, &columns());
        assert!(e.kept.starts_with("y,failed,"), "{e:?}");
        // no status column, or over the size: nothing, and a note
        std::fs::write(&path, "input,state\r\nx,failed\r\n").unwrap();
        let e = earlier_failures(&path, &none, &columns());
        assert!(e.kept.is_empty() && e.note.unwrap().contains("not a summary of ours"));
        let f = std::fs::File::create(&path).unwrap();
        f.set_len(MAX_EARLIER_BYTES + 1).unwrap();
        let e = earlier_failures(&path, &none, &columns());
        assert!(e.kept.is_empty() && e.note.unwrap().contains("over 64 MiB"));
        // a link at the name is not followed
        std::fs::write(d.join("elsewhere.csv"), "input,status\r\nx,failed\r\n").unwrap();
        std::fs::remove_file(&path).unwrap();
        std::os::unix::fs::symlink(d.join("elsewhere.csv"), &path).unwrap();
        let e = earlier_failures(&path, &none, &columns());
        assert!(e.kept.is_empty() && e.note.is_none());
        // more failures than MAX_KEPT: the latest ones, said
        let rows: String = (0..MAX_KEPT + 3).map(|k| format!("in{k},failed\n")).collect();
        std::fs::write(d.join("many.csv"), format!("input,status\n{rows}")).unwrap();
        let e = earlier_failures(&d.join("many.csv"), &none, &["input".to_string()]);
        assert_eq!(e.kept.lines().count(), MAX_KEPT);
        assert!(e.kept.starts_with("in3\r\n") && e.note.unwrap().contains(&format!("lists {} failures", MAX_KEPT + 3)));
        // without given, a run keeps nothing (the Dask batch's scratch summary)
        std::fs::remove_file(&path).unwrap();
        std::fs::write(&path, "input,status\r\nx,failed\r\n").unwrap();
        let mut s = Summary::create(&d);
        s.failed(Path::new("z"), "internal", "x", 6);
        s.close();
        assert_eq!(std::fs::read_to_string(&path).unwrap().lines().count(), 2);
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// Every record of `text`, each a row of ours.
    fn records(text: &str) -> Vec<Vec<String>> {
        let mut r = Records::new(text.as_bytes());
        std::iter::from_fn(|| r.next_record()).map(|(_, rec)| rec.unwrap()).collect()
    }

    #[test]
    fn records_read_what_the_writer_writes_and_name_inputs_alike() {
        let cells = ["plain", "a,b", "say \"hi\"", "two\r\nlines", "", "'=x"];
        let line: Vec<String> = cells.iter().map(|c| field(c)).collect();
        let text = format!("{}\r\n{}\n", line.join(","), line.join(","));
        assert_eq!(records(&text), vec![cells.map(String::from).to_vec(); 2]);
        let mut bad = Records::new(&b"\"a\"b,c\r\nok\r\n"[..]);
        assert_eq!(bad.next_record().unwrap().1, None, "text after a closing quote");
        assert_eq!(bad.next_record().unwrap(), (8, Some(vec!["ok".to_string()])));
        let long = format!("{}\r\nok\r\n", "x".repeat(MAX_FIELD_BYTES + 2));
        let mut r = Records::new(long.as_bytes());
        assert_eq!(r.next_record().unwrap().1, None);
        assert_eq!(r.next_record().unwrap().1, Some(vec!["ok".to_string()]));
        assert_eq!(input_key("./cam//a.jpg"), input_key("cam/x/../a.jpg"));
        assert_eq!(input_key("/d/cam/./a.jpg"), "/d/cam/a.jpg");
        assert_eq!(input_key("s3://b/x/../a.jpg"), "s3://b/x/../a.jpg");
    }
}
