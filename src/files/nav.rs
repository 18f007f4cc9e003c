//! `--altitude`: where each photo's camera was over a flat seabed (METHOD
//! §13.7, docs/OUTPUTS.md "Distance"). The altitude comes from a number
//! (every photo), from a navigation log (CSV, by file name or by time), or
//! from the photo's own XMP (the iFDO field `image-meters-above-ground`);
//! the field of view from `--fov` or the photo's EXIF lens fields.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{json, Value};

use crate::error::Failure;
use crate::method::floor::{Floor, Port};

/// Largest navigation log read, in bytes.
const MAX_LOG_BYTES: u64 = 256 << 20;

/// The most records a navigation log may hold: 50 Hz for a day, 10 Hz
/// for five, in at most about 400 MB once read.
const MAX_RECORDS: usize = 5_000_000;

/// Longest field of a log shown in a message, in characters.
const SHOWN: usize = 40;

/// A photo between two log records further apart than this (seconds) is
/// not interpolated: a gap in the log.
pub const MAX_GAP: f64 = 10.0;

/// A photo this near (seconds) to a record at the log's end, or by a gap,
/// takes that record.
pub const NEAREST: f64 = 1.0;

/// Half the diagonal of a 35 mm frame (36 x 24 mm), mm: the reference of
/// EXIF's FocalLengthIn35mmFormat.
const HALF_DIAGONAL_35MM: f64 = 21.633_307_652_783_937;

/// Where a camera was: metres above the seabed and its tilt in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// metres above the seabed
    pub altitude: f64,
    /// degrees, positive nose up
    pub pitch: f64,
    /// degrees, positive starboard down
    pub roll: f64,
}

/// One record of a log by name: where its file name lies in
/// [`ByName::text`], how long it and its stem are, its line and pose.
#[derive(Debug, Clone, Copy)]
struct Named {
    at: u32,
    len: u32,
    stem: u32,
    line: u32,
    pose: Pose,
}

/// A log's records by name, about 50 bytes each besides the names: the
/// names in one string and the records sorted by file name and by stem (a
/// map of two owned keys a record took ten times the log's size; a named
/// log of a million rows, half a gigabyte).
#[derive(Debug, Clone, Default)]
struct ByName {
    text: String,
    rows: Vec<Named>,
    /// indices into `rows`, by file name, then line
    by_file: Vec<u32>,
    /// indices into `rows` whose stem is not the whole name, by stem, then line
    by_stem: Vec<u32>,
}

impl ByName {
    fn file(&self, r: &Named) -> &str {
        self.text.get(r.at as usize..(r.at + r.len) as usize).unwrap_or("")
    }

    fn stem(&self, r: &Named) -> &str {
        self.text.get(r.at as usize..(r.at + r.stem) as usize).unwrap_or("")
    }

    fn push(&mut self, file: &str, line: usize, pose: Pose) -> Result<(), String> {
        let too_long = || "a log of more than 4 GiB of names".to_string();
        let at = u32::try_from(self.text.len()).map_err(|_| too_long())?;
        let stem = Path::new(file).file_stem().map_or(file.len(), |s| s.len()).min(file.len());
        self.text.push_str(file);
        u32::try_from(self.text.len()).map_err(|_| too_long())?;
        let line = u32::try_from(line).map_err(|_| too_long())?;
        self.rows.push(Named { at, len: file.len() as u32, stem: stem as u32, line, pose });
        Ok(())
    }

    /// Sorts the indices; the same file twice with one pose is one record,
    /// with two poses the error names the earliest line where that happens.
    fn index(&mut self) -> Result<(), String> {
        let at = |i: &u32| self.rows.get(*i as usize);
        let file = |i: &u32| at(i).map_or(("", 0), |r| (self.file(r), r.line));
        let stem = |i: &u32| at(i).map_or(("", 0), |r| (self.stem(r), r.line));
        let mut by_file: Vec<u32> = (0..self.rows.len() as u32).collect();
        by_file.sort_by(|a, b| file(a).cmp(&file(b)));
        let mut clash: Option<(u32, u32, &str)> = None;
        let mut keep: Vec<u32> = Vec::with_capacity(by_file.len());
        for i in by_file {
            let (Some(r), (name, line)) = (at(&i), file(&i)) else { continue };
            match keep.last().and_then(&at).filter(|f| self.file(f) == name) {
                Some(f) => {
                    if f.pose != r.pose && clash.is_none_or(|c| line < c.0) {
                        clash = Some((line, f.line, name));
                    }
                }
                None => keep.push(i),
            }
        }
        if let Some((line, first, name)) = clash {
            return Err(format!("line {line}: {} is also on line {first}, with another altitude or tilt", shown(name)));
        }
        let mut by_stem: Vec<u32> = keep.iter().copied().filter(|i| at(i).is_some_and(|r| r.stem < r.len)).collect();
        by_stem.sort_by(|a, b| stem(a).cmp(&stem(b)));
        by_stem.dedup_by(|b, a| stem(a).0 == stem(b).0);
        self.by_file = keep;
        self.by_stem = by_stem;
        Ok(())
    }

    /// The record of the file name `file`, else one named `stem` itself (a
    /// log of image names without extensions), else the first (in the log)
    /// whose stem is `stem` (the photo in another format); with how it
    /// matched: "name", "stem" or "stem, another extension".
    fn get(&self, file: &str, stem: &str) -> Option<(&Named, &'static str)> {
        self.first(&self.by_file, file, false)
            .map(|r| (r, "name"))
            .or_else(|| self.first(&self.by_file, stem, false).map(|r| (r, "stem")))
            .or_else(|| self.first(&self.by_stem, stem, true).map(|r| (r, "stem, another extension")))
    }

    /// The earliest record of `list` (sorted by file name, or by stem when
    /// `by_stem`, then line) whose key is `key`.
    fn first(&self, list: &[u32], key: &str, by_stem: bool) -> Option<&Named> {
        let part = |i: u32| {
            self.rows.get(i as usize).map_or("", |r| if by_stem { self.stem(r) } else { self.file(r) })
        };
        let k = list.partition_point(|&i| part(i) < key);
        list.get(k).filter(|&&i| part(i) == key).and_then(|&i| self.rows.get(i as usize))
    }

    fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

/// A navigation log: the rows by file name and by time.
#[derive(Debug, Clone, Default)]
pub struct NavLog {
    /// the file read
    pub path: PathBuf,
    /// by the file name and its stem
    by_name: ByName,
    /// (seconds, line, pose) sorted by time
    by_time: Vec<(f64, usize, Pose)>,
    /// whether the log names its photos
    named: bool,
}

/// What `--altitude` gave.
#[derive(Debug, Clone)]
pub enum AltitudeSource {
    /// one altitude for every photo, metres
    Constant(f64),
    /// each photo's XMP
    Xmp,
    /// a navigation log
    Log(Arc<NavLog>),
}

/// How the field of view was found: the horizontal angle in air across
/// the photo's width, the tangent of half the diagonal angle, or a focal
/// length in millimetres with the sensor's millimetres per pixel (and its
/// pixel size when the EXIF gives it; else the photo's).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Lens {
    Horizontal(f64),
    HalfDiagonalTan(f64),
    FocalPlane { focal: f64, mm_per_px: f64, pixels: Option<(f64, f64)> },
}

/// One photo's camera: its pose and lens, and where each came from.
#[derive(Debug, Clone)]
pub struct Camera {
    /// altitude and tilt
    pub pose: Pose,
    /// where the pose came from (the sidecar's `distance.floor.pose_from`)
    pub pose_from: Value,
    lens: Lens,
    lens_from: String,
}

impl Lens {
    /// The horizontal field of view in air across the width of a photo of
    /// `h` x `w` pixels (upright, before `--max-side`: the angle is the
    /// same after it), degrees.
    fn across(self, h: usize, w: usize) -> f64 {
        let (hf, wf) = (h as f64, w as f64);
        let across = |t: f64| 2.0 * (t * wf / (hf * hf + wf * wf).sqrt()).atan().to_degrees();
        match self {
            Lens::Horizontal(deg) => deg,
            Lens::HalfDiagonalTan(t) => across(t),
            Lens::FocalPlane { focal, mm_per_px, pixels } => {
                let (px, py) = pixels.unwrap_or((wf, hf));
                across((px * px + py * py).sqrt() * mm_per_px / 2.0 / focal)
            }
        }
    }
}

/// A photo's lens (from `--fov` or its EXIF) and where it came from: what
/// turns a depth map along the optical axis into ranges
/// (`--distance-kind depth`, METHOD §13.7).
#[derive(Debug, Clone)]
pub struct LensOf {
    lens: Lens,
    from: String,
}

impl LensOf {
    /// The lens of photo `input`: `fov` (degrees in air across the width)
    /// when given, else its EXIF; why not, when neither gives one.
    pub fn of(fov: Option<f64>, input: &Path) -> Result<LensOf, String> {
        if let Some(f) = fov {
            return Ok(LensOf { lens: Lens::Horizontal(f), from: "--fov".into() });
        }
        let carried = crate::files::metadata::read_path(input)?;
        let (lens, from) = exif_lens(&carried)?;
        Ok(LensOf { lens, from })
    }

    /// `map` (depth along the axis of a photo of `h` x `w` upright pixels)
    /// turned into ranges in place, at its own size (it has the photo's
    /// aspect ratio); the sidecar's `distance.depth`, or why not when the
    /// lens gives an angle out of range.
    pub fn to_range(&self, map: &mut crate::files::depth::DistanceMap, (h, w): (usize, usize), port: Port) -> Result<Value, String> {
        let fov = self.lens.across(h, w);
        crate::method::floor::depth_to_range(&mut map.data, map.height, map.width, fov, port)
            .map_err(|e| format!("{e} (from {})", self.from))?;
        let in_water = crate::method::floor::fov_in_water(fov, port);
        Ok(json!({"along": "axis", "fov": fov, "fov_from": self.from, "fov_in_water": in_water, "port": port.name()}))
    }
}

/// Why a photo has no lens: neither `--fov` nor the EXIF fields that give one.
const NO_LENS: &str =
    "no field of view: the photo's EXIF has neither FocalLengthIn35mmFormat nor FocalLength with FocalPlaneXResolution (give --fov)";

impl Camera {
    /// The seabed seen by this camera in a photo of `h` x `w` pixels
    /// (upright, before `--max-side`: the angle is the same after it),
    /// checked ([`Floor::check`]: a lens of the EXIF may give any angle).
    pub fn floor(&self, h: usize, w: usize, port: Port) -> Result<Floor, String> {
        let fov = self.lens.across(h, w);
        let floor = Floor { altitude: self.pose.altitude, fov, pitch: self.pose.pitch, roll: self.pose.roll, port };
        floor.check().map_err(|e| format!("{e} (field of view from {})", self.lens_from))?;
        Ok(floor)
    }

    /// The sidecar's `distance.floor` for `floor`.
    pub fn record(&self, floor: &Floor) -> Value {
        json!({
            "altitude": floor.altitude,
            "pitch": floor.pitch,
            "roll": floor.roll,
            "pose_from": self.pose_from,
            "fov": floor.fov,
            "fov_from": self.lens_from,
            "fov_in_water": floor.fov_in_water(),
            "port": floor.port.name(),
        })
    }
}

impl AltitudeSource {
    /// What the sidecar's `distance.source` says.
    pub fn label(&self) -> String {
        match self {
            AltitudeSource::Constant(h) => format!("altitude {h} m"),
            AltitudeSource::Xmp => "altitude from the photo's XMP".into(),
            AltitudeSource::Log(l) => format!("altitude from {}", l.path.display()),
        }
    }
}

/// A cell or argument as a message quotes it: in double quotes, cut after
/// `SHOWN` characters. Control and bidirectional characters stay as they
/// are here: the consoles of both commands escape them as `\xNN` and
/// `\uNNNN` (`printable`), and a sidecar's JSON escapes them.
pub(crate) fn shown(s: &str) -> String {
    let t: String = s.chars().take(SHOWN).collect();
    if s.chars().count() > SHOWN {
        format!("\"{t}...\"")
    } else {
        format!("\"{t}\"")
    }
}

/// `--altitude VALUE`: a number of metres, `xmp`, or a navigation log's
/// path (read once per run: every photo of a run sees the same log; the
/// Python command starts each run with [`forget_logs`]).
pub fn altitude_source(value: &str) -> Result<AltitudeSource, Failure> {
    if value == "xmp" {
        return Ok(AltitudeSource::Xmp);
    }
    if let Ok(h) = value.trim().parse::<f64>() {
        let max = f64::from(crate::method::distance::MAX_DISTANCE);
        if !(h.is_finite() && h > 0.0 && h <= max) {
            return Err(Failure::usage(format!("--altitude {}: an altitude is in (0, {max}] metres", shown(value))));
        }
        return Ok(AltitudeSource::Constant(h));
    }
    Ok(AltitudeSource::Log(read_log_once(Path::new(value))?))
}

/// The navigation logs read in this run.
static LOGS: crate::files::jobs::PerRun<Arc<NavLog>> = crate::files::jobs::PerRun::new();

/// A new run starts: navigation logs are read again (a Python process or a
/// Dask worker serves one run after another, and a log may have grown).
pub fn forget_logs() {
    LOGS.forget();
}

fn read_log_once(path: &Path) -> Result<Arc<NavLog>, Failure> {
    LOGS.get_or_read(path, || read_log(path).map(Arc::new))
}

/// Reads a navigation log (a regular file of at most 256 MiB, UTF-8 CSV);
/// a malformed one is a usage error naming its line and column.
pub fn read_log(path: &Path) -> Result<NavLog, Failure> {
    let bad = |why: String| Failure::usage(format!("--altitude {}: {why}", path.display()));
    crate::files::jobs::regular_file(path).map_err(bad)?;
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    if size > MAX_LOG_BYTES {
        return Err(bad(format!("{size} bytes, over the {MAX_LOG_BYTES} a navigation log may have")));
    }
    let bytes = std::fs::read(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let mut text = String::from_utf8(bytes).map_err(|e| bad(format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))?;
    // lines ended by CR alone (classic Mac OS, some loggers' exports) are lines
    if !text.contains('\n') && text.contains('\r') {
        text = text.replace('\r', "\n");
    }
    let mut log = parse_log(&text).map_err(bad)?;
    log.path = path.to_path_buf();
    Ok(log)
}

/// Most fields a line of a navigation log may have: vehicle logs have tens
/// to a few hundred columns. A line of a quarter of a gigabyte of commas
/// would otherwise be held as that many strings (24 bytes each, 6 GB).
const MAX_FIELDS: usize = 4096;

/// The fields of one CSV line: commas (or the header's delimiter), double
/// quotes around a field that holds one, `""` for a quote inside.
fn fields(line: &str, delim: char) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    let mut was_quoted = false;
    while let Some(c) = chars.next() {
        if quoted {
            if c == '"' {
                if chars.peek() == Some(&'"') {
                    cur.push('"');
                    chars.next();
                } else {
                    quoted = false;
                }
            } else {
                cur.push(c);
            }
        } else if c == '"' && cur.trim().is_empty() && !was_quoted {
            quoted = true;
            was_quoted = true;
            cur.clear();
        } else if c == delim {
            if out.len() + 1 >= MAX_FIELDS {
                return Err(format!("more than {MAX_FIELDS} fields: not a navigation log's line"));
            }
            out.push(std::mem::take(&mut cur).trim().to_string());
            was_quoted = false;
        } else {
            cur.push(c);
        }
    }
    if quoted {
        return Err("a quote is not closed".into());
    }
    out.push(cur.trim().to_string());
    Ok(out)
}

/// The header names of each column role.
const ALTITUDE_NAMES: &[&str] = &["altitude", "alt", "altitude_m", "image-meters-above-ground", "meters_above_ground"];
const FILE_NAMES: &[&str] = &["file", "filename", "file_name", "image", "image-filename", "name", "photo"];
const TIME_NAMES: &[&str] = &["time", "timestamp", "datetime", "date_time", "image-datetime", "utc"];
const PITCH_NAMES: &[&str] = &["pitch", "pitch_deg"];
const ROLL_NAMES: &[&str] = &["roll", "roll_deg"];

/// Largest |seconds since 1970| a log's time may be (about the year 5138):
/// a larger number is no time of a dive.
const MAX_SECONDS: f64 = 1e11;

/// The column of each role, from the header's names (case, spaces,
/// dashes and underscores ignored).
fn column(header: &[String], names: &[&str]) -> Option<usize> {
    column_from(header, names, 0)
}

/// The first column from index `from` on named one of `names`.
fn column_from(header: &[String], names: &[&str], from: usize) -> Option<usize> {
    let norm = |s: &str| s.chars().filter(|c| c.is_alphanumeric()).flat_map(char::to_lowercase).collect::<String>();
    header.iter().enumerate().skip(from).find(|(_, h)| names.iter().any(|n| norm(h) == norm(n))).map(|(i, _)| i)
}

/// Whether a line of a log holds fields (the header or a record): not
/// blank, not a `#` comment.
fn holds_fields(line: &str) -> bool {
    !line.trim().is_empty() && !line.trim_start().starts_with('#')
}

/// Parses a navigation log: a header naming its columns, then one row per
/// record. Columns: `altitude` (metres above the seabed; also `alt`,
/// `altitude_m`, `image-meters-above-ground`), a file name (`file`,
/// `filename`, `image`, `image-filename`, `name`) or a time (`time`,
/// `timestamp`, `datetime`, `image-datetime`: ISO 8601, or seconds since
/// 1970), and optionally `pitch` and `roll` in degrees. Blank lines and
/// lines starting with `#` are skipped.
pub fn parse_log(text: &str) -> Result<NavLog, String> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_start_matches('\u{feff}')));
    let (head_no, head) = lines
        .by_ref()
        .find(|(_, l)| holds_fields(l))
        .ok_or("no header line (the first line names the columns)")?;
    let delim = [',', ';', '\t'].into_iter().max_by_key(|d| head.matches(*d).count()).unwrap_or(',');
    let header = fields(head, delim).map_err(|e| format!("line {head_no}: {e}"))?;
    let alt = column(&header, ALTITUDE_NAMES)
        .ok_or_else(|| format!("line {head_no}: no altitude column (expected a column named altitude)"))?;
    let name = column(&header, FILE_NAMES);
    let time = column(&header, TIME_NAMES);
    if name.is_none() && time.is_none() {
        return Err(format!("line {head_no}: no file-name or time column (expected a column named file or time)"));
    }
    let pitch = column(&header, PITCH_NAMES);
    let roll = column(&header, ROLL_NAMES);
    for (role, col, names) in [("altitude", Some(alt), ALTITUDE_NAMES), ("file-name", name, FILE_NAMES), ("time", time, TIME_NAMES),
                               ("pitch", pitch, PITCH_NAMES), ("roll", roll, ROLL_NAMES)] {
        if let Some(first) = col {
            if let Some(second) = column_from(&header, names, first + 1) {
                return Err(format!(
                    "line {head_no}: two {role} columns, {} (column {}) and {} (column {}): keep one",
                    shown(header.get(first).map_or("", String::as_str)), first + 1,
                    shown(header.get(second).map_or("", String::as_str)), second + 1
                ));
            }
        }
    }
    // each record is held twice over (by name and stem, or by time): a log of
    // millions of 4-byte lines would take ten times its size in memory
    let records = text.lines().filter(|l| holds_fields(l)).count().saturating_sub(1);
    if records > MAX_RECORDS {
        return Err(format!("{records} records, over the {MAX_RECORDS} a navigation log may have: give the dive's part of it"));
    }
    let mut log = NavLog { named: name.is_some(), ..NavLog::default() };
    if name.is_none() {
        log.by_time.reserve_exact(records);
    }
    let max = f64::from(crate::method::distance::MAX_DISTANCE);
    for (no, line) in lines {
        if !holds_fields(line) {
            continue;
        }
        let row = fields(line, delim).map_err(|e| format!("line {no}: {e}"))?;
        // a value beyond the header's columns has no name: a delimiter
        // inside a value, or columns shifted (empty ones, as a trailing
        // delimiter leaves, say nothing)
        if row.iter().skip(header.len()).any(|f| !f.trim().is_empty()) {
            return Err(format!("line {no}: {} fields, the header (line {head_no}) names {}", row.len(), header.len()));
        }
        let cell = |col: usize, what: &str| -> Result<&str, String> {
            row.get(col).map(String::as_str).filter(|s| !s.is_empty()).ok_or_else(|| {
                format!("line {no}, column {} ({what}): empty or missing", col + 1)
            })
        };
        let number = |col: usize, what: &str, lo: f64, hi: f64| -> Result<f64, String> {
            let s = cell(col, what)?;
            let v: f64 = s.parse().map_err(|_| format!("line {no}, column {} ({what}): {} is not a number", col + 1, shown(s)))?;
            if !(v.is_finite() && v > lo && v <= hi) {
                return Err(format!("line {no}, column {} ({what}): {} is not in ({lo}, {hi}]", col + 1, crate::error::shown_number(v)));
            }
            Ok(v)
        };
        let tilt = |col: Option<usize>, what: &str| -> Result<f64, String> {
            let lim = crate::method::floor::MAX_TILT;
            col.map_or(Ok(0.0), |c| {
                let s = cell(c, what)?;
                let v: f64 = s.parse().map_err(|_| format!("line {no}, column {} ({what}): {} is not a number", c + 1, shown(s)))?;
                if v.abs() <= lim {
                    Ok(v)
                } else {
                    Err(format!("line {no}, column {} ({what}): {} is not in [-{lim}, {lim}]", c + 1, crate::error::shown_number(v)))
                }
            })
        };
        let pose = Pose { altitude: number(alt, "altitude", 0.0, max)?, pitch: tilt(pitch, "pitch")?, roll: tilt(roll, "roll")? };
        if let Some(c) = name {
            let n = cell(c, "file name")?;
            // a path in the log names the file by its last part
            let file = n.rsplit(['/', '\\']).next().unwrap_or(n);
            log.by_name.push(file, no, pose)?;
        }
        if let (Some(c), None) = (time, name) {
            let s = cell(c, "time")?;
            let t = parse_time(s).ok_or_else(|| {
                format!("line {no}, column {} (time): {} is not an ISO 8601 time nor seconds since 1970 (within {MAX_SECONDS:e})", c + 1, shown(s))
            })?;
            log.by_time.push((t, no, pose));
        }
    }
    if log.by_name.is_empty() && log.by_time.is_empty() {
        return Err("no records after the header".into());
    }
    // the same record logged twice is one record; two that disagree are refused
    log.by_name.index()?;
    log.by_time.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    // two records of one time that disagree: which one the photo of that
    // time had is unknown (the same record twice is harmless)
    for w in log.by_time.windows(2) {
        if let [(t0, l0, p0), (t1, l1, p1)] = w {
            if t0 == t1 && p0 != p1 {
                return Err(format!("line {l1}: the time of line {l0} again, with another altitude, pitch or roll"));
            }
        }
    }
    Ok(log)
}

/// Days from 1970-01-01 to a civil date (proleptic Gregorian).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Seconds since 1970-01-01 UTC of `YYYY-MM-DD[T ]HH:MM:SS[.fff][Z|+HH:MM]`
/// (dashes or colons in the date, as EXIF writes it), or a plain number of
/// seconds. A time without an offset is taken as UTC.
pub fn parse_time(s: &str) -> Option<f64> {
    let s = s.trim();
    if let Ok(v) = s.parse::<f64>() {
        return (v.is_finite() && v.abs() <= MAX_SECONDS).then_some(v);
    }
    let b = s.as_bytes();
    let num = |a: usize, n: usize| -> Option<i64> {
        let part = b.get(a..a + n)?;
        part.iter().all(u8::is_ascii_digit).then(|| part.iter().fold(0i64, |v, c| v * 10 + i64::from(c - b'0')))
    };
    let (y, mo, d) = (num(0, 4)?, num(5, 2)?, num(8, 2)?);
    if !matches!(b.get(4), Some(b'-' | b':')) || b.get(7) != b.get(4) || !matches!(b.get(10), Some(b'T' | b' ')) {
        return None;
    }
    let (hh, mm, ss) = (num(11, 2)?, num(14, 2)?, num(17, 2)?);
    if b.get(13) != Some(&b':') || b.get(16) != Some(&b':') {
        return None;
    }
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days = [31, if leap { 29 } else { 28 }, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31];
    let month_days = usize::try_from(mo - 1).ok().and_then(|i| days.get(i).copied())?;
    if !(1..=month_days).contains(&d) || hh > 23 || mm > 59 || ss > 60 {
        return None;
    }
    let mut t = (days_from_civil(y, mo, d) * 86_400 + hh * 3600 + mm * 60 + ss) as f64;
    let mut rest = s.get(19..)?;
    if let Some(frac) = rest.strip_prefix('.') {
        let digits = frac.bytes().take_while(u8::is_ascii_digit).count();
        if digits == 0 {
            return None;
        }
        t += format!("0.{}", frac.get(..digits)?).parse::<f64>().ok()?;
        rest = frac.get(digits..)?;
    }
    match rest.as_bytes() {
        [] | [b'Z'] => {}
        [sign @ (b'+' | b'-'), h1, h2, b':', m1, m2] if [h1, h2, m1, m2].iter().all(|c| c.is_ascii_digit()) => {
            let (oh, om) = (i64::from(h1 - b'0') * 10 + i64::from(h2 - b'0'), i64::from(m1 - b'0') * 10 + i64::from(m2 - b'0'));
            // ISO 8601: an offset within +-23:59
            if oh > 23 || om > 59 {
                return None;
            }
            let off = oh * 3600 + om * 60;
            t -= if *sign == b'+' { off } else { -off } as f64;
        }
        _ => return None,
    }
    Some(t)
}

impl NavLog {
    /// The pose of the photo `input` (by its file name or stem when the
    /// log names files, else by `taken`, seconds since 1970), and where it
    /// came from; why not when the log has none for it.
    pub fn pose(&self, input: &Path, taken: Option<(f64, &str)>) -> Result<(Pose, Value), String> {
        let file = input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let stem = input.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if self.named {
            // a name that is not UTF-8 has no spelling a text log can give: read
            // lossily, two photos differing in one stray byte took one row
            if input.file_name().is_some_and(|n| n.to_str().is_none()) {
                return Err(format!("{} names its photos, and {} is not UTF-8 text: no row can name it", self.path.display(), shown(&file)));
            }
            return match self.by_name.get(&file, &stem) {
                Some((r, how)) => Ok((r.pose, json!({"log": self.path.to_string_lossy(), "line": r.line, "matched": how}))),
                None => Err(format!("{} has no row for {}", self.path.display(), shown(&file))),
            };
        }
        let Some((t, iso)) = taken else {
            return Err(format!(
                "{} is matched by time and the photo has no time (EXIF DateTimeOriginal)",
                self.path.display()
            ));
        };
        let rows = &self.by_time;
        let after = rows.partition_point(|r| r.0 < t);
        let prev = after.checked_sub(1).and_then(|i| rows.get(i));
        let next = rows.get(after);
        let from = |lines: Vec<usize>, how: &str, gap: f64| {
            json!({"log": self.path.to_string_lossy(), "line": lines, "matched": how, "taken_at": iso, "seconds_from_record": gap})
        };
        if let (Some(a), Some(b)) = (prev, next) {
            if b.0 - a.0 <= MAX_GAP {
                let k = if b.0 > a.0 { (t - a.0) / (b.0 - a.0) } else { 0.0 };
                let mix = |x: f64, y: f64| x + (y - x) * k;
                let p = Pose { altitude: mix(a.2.altitude, b.2.altitude), pitch: mix(a.2.pitch, b.2.pitch), roll: mix(a.2.roll, b.2.roll) };
                return Ok((p, from(vec![a.1, b.1], "time, interpolated", (t - a.0).min(b.0 - t))));
            }
        }
        let nearest = [prev, next].into_iter().flatten().min_by(|x, y| (x.0 - t).abs().total_cmp(&(y.0 - t).abs()));
        match nearest {
            Some(r) if (r.0 - t).abs() <= NEAREST => Ok((r.2, from(vec![r.1], "time, nearest", (r.0 - t).abs()))),
            Some(r) => Err(format!(
                "{} has no record within {NEAREST} s of the photo's time {iso} (the nearest, line {}, is {:.1} s away)",
                self.path.display(),
                r.1,
                (r.0 - t).abs()
            )),
            None => Err(format!("{} has no records", self.path.display())),
        }
    }
}

/// The iFDO field `image-meters-above-ground` in an XMP packet, as an
/// attribute (`...:image-meters-above-ground="2.4"`) or an element
/// (`<...:image-meters-above-ground>2.4</...>`).
pub fn xmp_altitude(xmp: &str) -> Option<f64> {
    // every value must be the same number: a packet that gives the field
    // twice, differently, says nothing sure (a log that does is refused too)
    let text = without_comments(xmp);
    // (an element's closing tag reads as an empty value)
    let mut values = xmp_altitude_values(&text).filter(|v| !v.trim().is_empty()).take(64).map(|v| v.trim().parse::<f64>().ok());
    let first = values.next()??;
    values.all(|v| v == Some(first)).then_some(first)
}

/// `xmp` with its XML comments (`<!-- ... -->`, an unclosed one to the
/// end) taken out: a commented-out field is no field.
fn without_comments(xmp: &str) -> std::borrow::Cow<'_, str> {
    if !xmp.contains("<!--") {
        return std::borrow::Cow::Borrowed(xmp);
    }
    let (mut out, mut rest) = (String::with_capacity(xmp.len()), xmp);
    while let Some(i) = rest.find("<!--") {
        out.push_str(rest.get(..i).unwrap_or(""));
        rest = rest.get(i + 4..).and_then(|r| r.find("-->").and_then(|j| r.get(j + 3..))).unwrap_or("");
    }
    out.push_str(rest);
    std::borrow::Cow::Owned(out)
}

/// The values of `image-meters-above-ground` in an XMP packet as text,
/// numbers or not, joined by " and " (at most four): what a photo whose
/// [`xmp_altitude`] is None says instead of one.
fn xmp_altitude_text(xmp: &str) -> Option<String> {
    let text = without_comments(xmp);
    let values: Vec<String> = xmp_altitude_values(&text).map(str::trim).filter(|v| !v.is_empty()).take(4).map(str::to_string).collect();
    (!values.is_empty()).then(|| values.join(" and "))
}

/// Every value of the iFDO field `image-meters-above-ground` in an XMP
/// packet, attribute or element, in order: the name whole (after a
/// namespace's `:`, a tag's `<` or a space), not the end of another
/// (`not-image-meters-above-ground`).
fn xmp_altitude_values(xmp: &str) -> impl Iterator<Item = &str> {
    const KEY: &str = "image-meters-above-ground";
    let mut rest = xmp;
    std::iter::from_fn(move || loop {
        let i = rest.find(KEY)?;
        let whole = rest.get(..i).and_then(|b| b.chars().next_back()).is_none_or(|c| c == ':' || c == '<' || c.is_whitespace());
        let after = rest.get(i + KEY.len()..)?;
        rest = after;
        if !whole {
            continue;
        }
        let value = if let Some(v) = after.trim_start().strip_prefix('=') {
            let v = v.trim_start();
            v.chars().next().filter(|c| *c == '"' || *c == '\'').and_then(|q| v.get(1..).and_then(|t| t.split(q).next()))
        } else if let Some(v) = after.strip_prefix('>') {
            v.split('<').next()
        } else {
            None
        };
        if value.is_some() {
            return value;
        }
    })
}

/// The lens of a photo from its EXIF: FocalLengthIn35mmFormat, else
/// FocalLength with FocalPlaneXResolution and its unit (the sensor's
/// pixel diagonal from ExifImageWidth and ExifImageHeight, read before
/// they are dropped from what is carried: `carried.exif_size`; else the
/// photo's).
fn exif_lens(carried: &crate::files::metadata::Carried) -> Result<(Lens, String), String> {
    use little_exif::exif_tag::ExifTag;
    let m = carried.exif.as_ref().ok_or(NO_LENS.to_string())?;
    let (mut f35, mut focal, mut res, mut unit) = (None, None, None, None);
    let ratio = |v: &[little_exif::rational::uR64]| {
        v.first().filter(|r| r.denominator != 0).map(|r| f64::from(r.nominator) / f64::from(r.denominator))
    };
    for ifd in m.get_ifds() {
        for tag in ifd.get_tags() {
            match tag {
                ExifTag::FocalLengthIn35mmFormat(v) => f35 = v.first().copied().filter(|f| *f > 0).map(f64::from),
                ExifTag::FocalLength(v) => focal = ratio(v),
                ExifTag::FocalPlaneXResolution(v) => res = ratio(v),
                ExifTag::FocalPlaneResolutionUnit(v) => unit = v.first().copied(),
                _ => {}
            }
        }
    }
    if let Some(f) = f35 {
        return Ok((Lens::HalfDiagonalTan(HALF_DIAGONAL_35MM / f), format!("EXIF FocalLengthIn35mmFormat {f} mm")));
    }
    // the fields are there but say nothing usable: named, so that the user
    // knows to give --fov rather than to look for missing metadata
    let no_lens = |why: String| format!("no field of view: {why} (give --fov)");
    let (Some(focal), Some(res)) = (focal, res) else { return Err(NO_LENS.to_string()) };
    let mm_per_unit = match unit {
        Some(2) => 25.4,
        Some(3) => 10.0,
        Some(4) => 1.0,
        Some(5) => 1e-3,
        Some(u) => return Err(no_lens(format!("the EXIF FocalPlaneResolutionUnit {u} is no unit (2 inch, 3 cm, 4 mm, 5 um)"))),
        None => return Err(no_lens("the EXIF has FocalPlaneXResolution without FocalPlaneResolutionUnit".into())),
    };
    if !(focal.is_finite() && focal > 0.0) {
        return Err(no_lens(format!("the EXIF FocalLength is {}", crate::error::shown_number(focal))));
    }
    if !(res.is_finite() && res > 0.0) {
        return Err(no_lens(format!("the EXIF FocalPlaneXResolution is {}", crate::error::shown_number(res))));
    }
    let pixels = carried.exif_size.map(|(w, h)| (f64::from(w), f64::from(h)));
    let lens = Lens::FocalPlane { focal, mm_per_px: mm_per_unit / res, pixels };
    Ok((lens, format!("EXIF FocalLength {focal} mm and FocalPlaneXResolution {res} per {mm_per_unit} mm")))
}

/// The camera of photo `input`: the pose from `source`, the lens from
/// `fov` (degrees in air across the width) or the photo's EXIF. Why not,
/// when either is missing (the photo is then restored without distance
/// and flagged `distance_missing`).
pub fn camera_for(source: &AltitudeSource, fov: Option<f64>, input: &Path) -> Result<Camera, String> {
    let needs_file = fov.is_none() || matches!(source, AltitudeSource::Xmp)
        || matches!(source, AltitudeSource::Log(l) if !l.named);
    let carried = if needs_file {
        Some(crate::files::metadata::read_path(input)?)
    } else {
        None
    };
    let exif = carried.as_ref().and_then(|c| c.exif.as_ref());
    let (pose, pose_from) = match source {
        AltitudeSource::Constant(a) => (Pose { altitude: *a, pitch: 0.0, roll: 0.0 }, json!("--altitude")),
        AltitudeSource::Xmp => {
            let xmp = carried.as_ref().and_then(|c| c.xmp.as_deref());
            let a = xmp.and_then(xmp_altitude).ok_or_else(|| match xmp.and_then(xmp_altitude_text) {
                Some(t) if t.contains(" and ") => {
                    format!("the photo's XMP gives image-meters-above-ground (the iFDO field) more than once, {}: which is its altitude is not known", shown(&t))
                }
                Some(t) => format!("the photo's XMP image-meters-above-ground (the iFDO field) is {}: not a number", shown(&t)),
                None => "the photo's XMP has no image-meters-above-ground (the iFDO field)".to_string(),
            })?;
            (Pose { altitude: a, pitch: 0.0, roll: 0.0 }, json!("xmp"))
        }
        AltitudeSource::Log(log) => {
            let iso = exif.and_then(crate::files::metadata::taken_at);
            let taken = iso.as_deref().and_then(|s| parse_time(s).map(|t| (t, s)));
            // by time, an offset that cannot be read would place the photo
            // on UTC's clock: hours from its records, matched all the same
            if let Some(off) = exif.and_then(crate::files::metadata::unread_offset).filter(|_| !log.named) {
                return Err(format!(
                    "{} is matched by time and the photo's EXIF OffsetTimeOriginal {} is not an offset (+HH:MM): \
                     its time cannot be placed on the log's clock",
                    log.path.display(),
                    shown(&off)
                ));
            }
            if taken.is_none() && !log.named {
                // a time that is there but cannot be read is named, not called missing
                let raw = exif.and_then(crate::files::metadata::time_tag);
                let why = match (iso.as_deref(), raw) {
                    (Some(t), _) => format!("the photo's time {} cannot be read (EXIF DateTimeOriginal, OffsetTimeOriginal)", shown(t)),
                    (None, Some(r)) => format!("the photo's EXIF time {} is not a date and time", shown(&r)),
                    (None, None) => "the photo has no time (EXIF DateTimeOriginal)".to_string(),
                };
                return Err(format!("{} is matched by time and {why}", log.path.display()));
            }
            log.pose(input, taken)?
        }
    };
    let (lens, lens_from) = match fov {
        Some(f) => (Lens::Horizontal(f), "--fov".to_string()),
        None => carried.as_ref().ok_or(NO_LENS.to_string()).and_then(exif_lens)?,
    };
    let max = f64::from(crate::method::distance::MAX_DISTANCE);
    if !(pose.altitude.is_finite() && pose.altitude > 0.0 && pose.altitude <= max) {
        return Err(format!("altitude {} m is not in (0, {max}]", crate::error::shown_number(pose.altitude)));
    }
    Ok(Camera { pose, pose_from, lens, lens_from })
}

/// The distance map of photo `input` seen as a flat seabed (`--altitude`),
/// at `hp` x `wp` (its processed size; `h` x `w` upright before
/// `--max-side`), with the sidecar's `distance.floor`; why not, as text.
pub fn floor_map(
    camera: &Camera,
    port: Port,
    (h, w): (usize, usize),
    (hp, wp): (usize, usize),
) -> Result<(crate::files::depth::DistanceMap, Value), String> {
    let floor = camera.floor(h, w, port)?;
    let data = floor.distances(hp, wp);
    Ok((crate::files::depth::DistanceMap { data, height: hp, width: wp, out_of_range: 0 }, camera.record(&floor)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_in_iso_8601_and_exif_forms_and_offsets() {
        // 2026-11-30 is day 20787 after 1970-01-01 (hand count: 56 years with 14 leap days = 20454, plus 333 days)
        let day = 20_787.0 * 86_400.0;
        assert_eq!(parse_time("2026-11-30T00:00:00"), Some(day));
        assert_eq!(parse_time("2026:11:30 10:15:42"), Some(day + 36_942.0));
        assert_eq!(parse_time("2026-11-30T10:15:42.5Z"), Some(day + 36_942.5));
        assert_eq!(parse_time("2026-11-30T10:15:42+10:00"), Some(day + 36_942.0 - 36_000.0));
        assert_eq!(parse_time("1764497742.25"), Some(1_764_497_742.25));
        assert_eq!(parse_time("2026-11-30T10:15:42-23:59"), Some(day + 36_942.0 + 86_340.0));
        for bad in ["2026-13-01T00:00:00", "2026-02-30T00:00:00", "2026-11-30", "noon", "2026-11-30T10:15:42+1", "", "2026-11-30T10:15:42.", "NaN",
                    "2026-11-30T10:15:40+99:00", "2026-11-30T10:15:40+10:60", "1e300", "-1e12"] {
            assert_eq!(parse_time(bad), None, "{bad}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_photo_whose_name_is_not_utf8_takes_no_row() {
        use std::os::unix::ffi::OsStrExt;
        let log = parse_log("file,altitude\nq\u{FFFD}.png,2.0\n").unwrap();
        let name = std::ffi::OsStr::from_bytes(b"q\xfe.png");
        let e = log.pose(Path::new(name), None).unwrap_err();
        assert!(e.contains("is not UTF-8 text"), "{e}");
    }

    #[test]
    fn a_line_of_thousands_of_fields_is_refused_by_its_number() {
        let wide = format!("file,altitude{}\na.png,2.0\n", ",".repeat(5000));
        let e = parse_log(&wide).unwrap_err();
        assert!(e.starts_with("line 1: more than 4096 fields"), "{e}");
        let wide = format!("# a comment\nfile,altitude\na.png,2.0{}\n", ",".repeat(250_000));
        let e = parse_log(&wide).unwrap_err();
        assert!(e.starts_with("line 3: more than 4096 fields"), "{e}");
        // a wide log within the bound is read
        let ok = format!("file,altitude{}\na.png,2.0{}\n", ",x".repeat(4000), ",1".repeat(4000));
        assert_eq!(parse_log(&ok).unwrap().pose(Path::new("a.png"), None).unwrap().0.altitude, 2.0);
    }

    #[test]
    fn a_log_by_name_matches_the_file_or_its_stem() {
        let log = parse_log("file,altitude,pitch,roll\n\"dives/a.jpg\",2.5,3,-1\nb.png,4,0,0\n").unwrap();
        let (p, from) = log.pose(Path::new("/x/a.jpg"), None).unwrap();
        assert_eq!(p, Pose { altitude: 2.5, pitch: 3.0, roll: -1.0 });
        assert_eq!(from["line"], 2);
        // the stem: the same photo converted to another format
        assert_eq!(log.pose(Path::new("b.tif"), None).unwrap().0.altitude, 4.0);
        let e = log.pose(Path::new("c.jpg"), None).unwrap_err();
        assert!(e.contains("no row for \"c.jpg\""), "{e}");
        // a log of image names without extensions
        let log = parse_log("image,altitude\nIMG_0001,3.5\nIMG_0002.x,4\n").unwrap();
        assert_eq!(log.pose(Path::new("IMG_0001.JPG"), None).unwrap().0.altitude, 3.5);
        assert_eq!(log.pose(Path::new("IMG_0002.x.tif"), None).unwrap().0.altitude, 4.0);
        assert!(log.pose(Path::new("IMG_0001x.jpg"), None).is_err());
    }

    #[test]
    fn by_name_the_file_wins_then_the_earliest_stem_and_clashes_name_their_first_line() {
        let log = parse_log("file,altitude\nd.png,5\nd.jpg,6\nd,7\ne.jpg,1\ne.jpg,1\n").unwrap();
        let alt = |name: &str| log.pose(Path::new(name), None).map(|(p, from)| (p.altitude, from["line"].clone()));
        assert_eq!(alt("d.jpg"), Ok((6.0, json!(3))));
        assert_eq!(alt("d"), Ok((7.0, json!(4))));
        // the bare stem's row before another extension's
        assert_eq!(alt("d.tif"), Ok((7.0, json!(4))));
        // by stem: the first of d.png and d.jpg in the log
        let log2 = parse_log("file,altitude\nd.png,5\nd.jpg,6\n").unwrap();
        assert_eq!(log2.pose(Path::new("d.tif"), None).map(|(p, from)| (p.altitude, from["line"].clone(), from["matched"].clone())),
                   Ok((5.0, json!(2), json!("stem, another extension"))));
        // the same record twice is one record: its first line
        assert_eq!(alt("e.jpg"), Ok((1.0, json!(5))));
        // of two clashes, the one the log reaches first is named
        let e = parse_log("file,altitude\nz.jpg,1\na.jpg,1\nz.jpg,2\na.jpg,3\n").unwrap_err();
        assert_eq!(e, "line 4: \"z.jpg\" is also on line 2, with another altitude or tilt");
    }

    #[test]
    fn a_log_by_time_interpolates_between_records_and_not_across_gaps() {
        let log = parse_log(
            "time;altitude;pitch\n2026-11-30T10:00:00Z;2;0\n2026-11-30T10:00:04Z;4;8\n2026-11-30T10:05:00Z;3;0\n",
        )
        .unwrap();
        let t0 = parse_time("2026-11-30T10:00:00Z").unwrap();
        let (p, from) = log.pose(Path::new("a.jpg"), Some((t0 + 1.0, "x"))).unwrap();
        // a quarter of the way from line 2 to line 3
        assert!((p.altitude - 2.5).abs() < 1e-12 && (p.pitch - 2.0).abs() < 1e-12);
        assert_eq!(from["line"], json!([2, 3]));
        // 296 s between lines 3 and 4: no interpolation; 0.5 s after line 3 takes it
        assert_eq!(log.pose(Path::new("a.jpg"), Some((t0 + 4.5, "x"))).unwrap().0.altitude, 4.0);
        let e = log.pose(Path::new("a.jpg"), Some((t0 + 60.0, "x"))).unwrap_err();
        assert!(e.contains("nearest, line 3, is 56.0 s away"), "{e}");
        // before the log's start
        assert!(log.pose(Path::new("a.jpg"), Some((t0 - 30.0, "x"))).is_err());
        let e = log.pose(Path::new("a.jpg"), None).unwrap_err();
        assert!(e.contains("no time"), "{e}");
    }

    #[test]
    fn a_malformed_log_names_its_line_and_column() {
        for (text, want) in [
            ("", "no header"),
            ("file,depth\na.jpg,3\n", "no altitude column"),
            ("altitude,pitch\n3,0\n", "no file-name or time column"),
            ("file,altitude\na.jpg,abc\n", "line 2, column 2 (altitude): \"abc\" is not a number"),
            ("file,altitude\n# note\n\na.jpg,2\nb.jpg,-1\n", "line 5, column 2 (altitude): -1 is not in"),
            ("file,altitude\na.jpg,1e9\n", "line 2, column 2 (altitude)"),
            ("file,altitude\na.jpg\n", "line 2, column 2 (altitude): empty or missing"),
            ("file,altitude,pitch\na.jpg,2,120\n", "line 2, column 3 (pitch)"),
            ("time,altitude\nyesterday,2\n", "line 2, column 1 (time)"),
            ("file,altitude\n\"a.jpg,2\n", "line 2: a quote is not closed"),
            ("file,altitude\na.jpg,2\na.jpg,3\n", "line 3: \"a.jpg\" is also on line 2"),
            ("file,altitude\n", "no records"),
            ("time,altitude\n1e300,2\n", "line 2, column 1 (time): \"1e300\" is not an ISO 8601 time"),
            ("time,altitude\n100,2\n100,2\n100,9\n", "line 4: the time of line 3 again, with another altitude"),
            ("file,altitude,alt\na.jpg,2,3\n", "line 1: two altitude columns, \"altitude\" (column 2) and \"alt\" (column 3)"),
            ("time,file,utc,altitude\n1,a,2,3\n", "two time columns"),
            ("file,altitude\na.jpg,1e300\n", "1.000000e300 is not in"),
            ("file,altitude\na.jpg,\u{1b}[31m2\n", "\"\u{1b}[31m2\" is not a number"),
            ("file,altitude,pitch\na.jpg,2,89.5\n", "line 2, column 3 (pitch): 89.5 is not in [-89, 89]"),
            ("file,altitude,roll\na.jpg,2,1e400\n", "line 2, column 3 (roll): inf is not in [-89, 89]"),
            ("file,altitude,roll\na.jpg,2,nan\n", "line 2, column 3 (roll): NaN is not in [-89, 89]"),
            ("file,altitude\na.jpg,2,3,4\n", "line 2: 4 fields, the header (line 1) names 2"),
            ("file,altitude\na.jpg,2,,\nb.jpg,2,,x\n", "line 3: 4 fields, the header (line 1) names 2"),
        ] {
            let e = parse_log(text).unwrap_err();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn a_log_of_more_records_than_memory_should_hold_is_refused_before_parsing() {
        let rows = |n: usize| format!("time,altitude\n# a comment is no record\n{}", "1,1\n".repeat(n));
        let e = parse_log(&rows(MAX_RECORDS + 1)).unwrap_err();
        assert!(e.starts_with(&format!("{} records, over the {MAX_RECORDS}", MAX_RECORDS + 1)), "{e}");
        assert_eq!(parse_log(&rows(MAX_RECORDS)).unwrap().by_time.len(), MAX_RECORDS);
    }

    #[test]
    fn the_same_record_twice_is_one_record() {
        // a trailing delimiter leaves an empty field under no name: taken
        assert!(parse_log("file,altitude\na.jpg,2,\nb.jpg,3,\n").is_ok());
        let log = parse_log("file,altitude,pitch\na.jpg,2,40\na.jpg,2,40\nb.jpg,3,0\n").unwrap();
        let (p, from) = log.pose(Path::new("a.jpg"), None).unwrap();
        assert_eq!((p.altitude, from["line"].clone()), (2.0, json!(2)));
    }

    #[test]
    fn the_xmp_field_as_attribute_or_element() {
        // a field that is there but no number is shown as it is, not called missing
        assert_eq!(xmp_altitude_text(r#"<a ifdo:image-meters-above-ground="two"/>"#).as_deref(), Some("two"));
        assert_eq!(xmp_altitude(r#"<a ifdo:image-meters-above-ground="two"/>"#), None);
        assert_eq!(xmp_altitude(r#"<rdf:Description ifdo:image-meters-above-ground="2.75"/>"#), Some(2.75));
        assert_eq!(xmp_altitude("<ifdo:image-meters-above-ground> 3 </ifdo:image-meters-above-ground>"), Some(3.0));
        assert_eq!(xmp_altitude("<x:image-meters-above-ground-note>n</x><a image-meters-above-ground='1.5'/>"), Some(1.5));
        assert_eq!(xmp_altitude("<x/>"), None);
        // a field commented out, or the end of another name, is no field
        assert_eq!(xmp_altitude(r#"<!-- ifdo:image-meters-above-ground="7" --><a ifdo:image-meters-above-ground="2"/>"#), Some(2.0));
        assert_eq!(xmp_altitude(r#"<a ifdo:not-image-meters-above-ground="9" ifdo:image-meters-above-ground="4"/>"#), Some(4.0));
        assert_eq!(xmp_altitude(r#"<a ifdo:not-image-meters-above-ground="9"/>"#), None);
        // given twice: the same number is that number; two others, or text beside a number, none
        assert_eq!(xmp_altitude(r#"<a ifdo:image-meters-above-ground="3.0"/><b ifdo:image-meters-above-ground="3"/>"#), Some(3.0));
        let two = r#"<a ifdo:image-meters-above-ground="abc"/><b ifdo:image-meters-above-ground="3.0"/>"#;
        assert_eq!(xmp_altitude(two), None);
        assert_eq!(xmp_altitude_text(two).as_deref(), Some("abc and 3.0"));
        assert_eq!(xmp_altitude(r#"<a ifdo:image-meters-above-ground="2"/><b ifdo:image-meters-above-ground="3"/>"#), None);
        assert_eq!(xmp_altitude(r#"<a/><!-- ifdo:image-meters-above-ground="7" "#), None);
    }

    #[test]
    fn a_35mm_equivalent_focal_length_gives_the_angle_across_the_width() {
        // 24 mm equivalent on a 3:2 photo: its width is the 36 mm frame's, 2 atan(18/24) = 73.74 degrees
        let cam = Camera { pose: Pose { altitude: 2.0, pitch: 0.0, roll: 0.0 }, pose_from: json!(null), lens: Lens::HalfDiagonalTan(HALF_DIAGONAL_35MM / 24.0), lens_from: String::new() };
        let fl = cam.floor(2000, 3000, Port::Flat).unwrap();
        assert!((fl.fov - 73.7398).abs() < 1e-3, "{}", fl.fov);
        // upright after a 90-degree turn the width is the short side: 2 atan(12/24) = 53.13 degrees
        assert!((cam.floor(3000, 2000, Port::Flat).unwrap().fov - 53.1301).abs() < 1e-3);
        // 8.8 mm on a sensor of 4 um pixels, 3000 x 2000: 12 mm wide, 2 atan(6/8.8) = 68.574 degrees
        let fp = Camera { lens: Lens::FocalPlane { focal: 8.8, mm_per_px: 0.004, pixels: None }, ..cam.clone() };
        assert!((fp.floor(2000, 3000, Port::Flat).unwrap().fov - 68.5738).abs() < 1e-3);
        // a photo resized after capture keeps the EXIF's own pixel size
        let resized = Camera { lens: Lens::FocalPlane { focal: 8.8, mm_per_px: 0.004, pixels: Some((3000.0, 2000.0)) }, ..cam.clone() };
        assert!((resized.floor(200, 300, Port::Flat).unwrap().fov - 68.5738).abs() < 1e-3);
        // an absurd EXIF focal length: refused by name
        let wide = Camera { lens: Lens::HalfDiagonalTan(1e6), lens_from: "EXIF x".into(), ..cam };
        assert!(wide.floor(2000, 3000, Port::Flat).unwrap_err().contains("field of view from EXIF x"));
    }

    #[test]
    fn a_resized_photo_takes_its_sensor_size_from_the_exif_it_was_written_with() {
        use little_exif::{exif_tag::ExifTag, metadata::Metadata, rational::uR64, filetype::FileExtension};
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpg).encode(&[90u8; 40 * 30 * 3], 40, 30, image::ExtendedColorType::Rgb8).unwrap();
        let mut m = Metadata::new();
        m.set_tag(ExifTag::FocalLength(vec![uR64 { nominator: 45, denominator: 10 }]));
        m.set_tag(ExifTag::FocalPlaneXResolution(vec![uR64 { nominator: 625, denominator: 1 }]));
        m.set_tag(ExifTag::FocalPlaneResolutionUnit(vec![4]));
        m.set_tag(ExifTag::ExifImageWidth(vec![4000]));
        m.set_tag(ExifTag::ExifImageHeight(vec![3000]));
        m.write_to_vec(&mut jpg, FileExtension::JPEG).unwrap();
        let p = std::env::temp_dir().join(format!("uwhl-nav-lens-{}.jpg", std::process::id()));
        std::fs::write(&p, &jpg).unwrap();
        let lens = LensOf::of(None, &p).unwrap();
        std::fs::remove_file(&p).unwrap();
        // 4000 x 3000 pixels of 1.6 um: an 8 mm diagonal; 4.5 mm: 2 atan(4 / 4.5 x 4/5) = 70.834 degrees across a 4:3 photo
        let fov = lens.lens.across(30, 40);
        assert!((fov - 70.834).abs() < 1e-3, "{fov} ({})", lens.from);
    }

    #[test]
    fn altitude_values_are_checked() {
        assert!(matches!(altitude_source("2.5").unwrap(), AltitudeSource::Constant(h) if h == 2.5));
        assert!(matches!(altitude_source("xmp").unwrap(), AltitudeSource::Xmp));
        for bad in ["0", "-3", "1e9", "inf"] {
            assert!(altitude_source(bad).unwrap_err().message.contains("an altitude is in"), "{bad}");
        }
        let e = altitude_source("/nonexistent/nav.csv").unwrap_err();
        assert!(e.message.contains("--altitude /nonexistent/nav.csv: no such file"), "{}", e.message);
    }
}
