//! How one input's outputs reach the output folder, one implementation for
//! both commands (docs/OUTPUTS.md, "What a reader may find"):
//!
//! 1. [`claim`] picks the name the outputs are written under and claims it:
//!    a claim file `.uwhl-claim-HASH` made exclusively, naming the process
//!    (pid and start time) and the input, so a second process on the same folder skips what the
//!    first is restoring, and a name in use by another input (another
//!    camera's `frame.jpg`, an unrelated `x.jpg`) is never written over.
//! 2. Every output, the sidecar included, is written to an exclusive
//!    temporary file of the folder ([`Claim::temp`]); a full disk fails
//!    here, before anything of an earlier run is touched.
//! 3. [`Claim::commit`] syncs the temporaries, removes an earlier sidecar
//!    of the same input (`--overwrite`), renames the outputs into place,
//!    syncs the folder, renames the sidecar last and syncs the folder
//!    again. A sidecar therefore only ever lists files of its own run.
//!
//! A claim dropped without a commit removes its temporaries and its claim
//! file. A claim file whose process no longer runs (kill -9, power cut),
//! or whose pid another process has since (its start time differs), is
//! stale: the next run takes the name over, and when the claim named the
//! same input it replaces the outputs that run may have renamed in without
//! their sidecar (a stale claim of another input leaves the files at the
//! name alone: they are unrelated to this input). Before a commit touches
//! the folder it records in its claim, durably, the names it may leave
//! without a sidecar (the earlier run's outputs it removes, its own it
//! renames in); the run that takes a dead claim over removes those it does
//! not write itself, so a run killed mid-commit leaves nothing unlisted
//! whatever `--format` the next run asks for.
//!
//! An input is recognised as the one a sidecar names however it is given
//! now (another working directory, an absolute path, a name that is not
//! UTF-8): by path, and else by the SHA-256 of its contents the sidecar
//! records (`metadata.input_sha256`).

use std::collections::HashMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// The most names tried for one input (`NAME`, `NAME_2`, ...).
pub const MAX_NAMES: usize = 10_000;

/// Output paths claimed by this process and not yet committed or released,
/// with the input each belongs to: two inputs in flight at once (the
/// overlapped loop, `--jobs N`, a stream naming the same file twice) see
/// each other here before either has written anything.
static IN_FLIGHT: Mutex<Option<HashMap<PathBuf, PathBuf>>> = Mutex::new(None);

/// Temporary files made by this process so far (their names' counter).
static TEMPS: AtomicU64 = AtomicU64::new(0);

/// What [`claim`] found for an input.
#[derive(Debug)]
pub enum Resolution {
    /// the outputs go under this claimed name
    Claimed(Claim),
    /// not to be restored now, and the sidecar path it is (or will be) under
    Skipped(Skip, PathBuf),
}

/// Why an input is skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Skip {
    /// its sidecar exists (and `overwrite` was not asked)
    Done,
    /// another running process (its pid) restores it
    Busy(u32),
    /// this process has the same input in flight (given twice: a stream
    /// naming one file on two lines)
    InFlight,
}

impl Skip {
    /// The reason both commands print (a stream line's `skipped`).
    pub fn reason(self) -> String {
        match self {
            Skip::Done => "sidecar exists".into(),
            Skip::Busy(pid) => format!("being restored by process {pid}"),
            Skip::InFlight => "given twice: restored once".into(),
        }
    }

    /// Its name for the Python command: "done", "busy" or "in_flight".
    #[cfg_attr(not(feature = "python"), allow(dead_code))]
    pub fn name(self) -> &'static str {
        match self {
            Skip::Done => "done",
            Skip::Busy(_) => "busy",
            Skip::InFlight => "in_flight",
        }
    }
}

/// Names an input's outputs never take when they may go elsewhere: their
/// sidecar would be a file the commands write themselves at the top of an
/// output folder (`uwhl ifdo --format json` writes `ifdo.json`), so an
/// input `ifdo.jpg` is written as `ifdo_2` (in every folder, one rule).
pub const RESERVED: &[&str] = &["ifdo"];

/// What to claim.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    /// the output folder (created if missing)
    pub dir: &'a Path,
    /// the preferred name (`NAME`)
    pub base: &'a str,
    /// the input, as given; compared with sidecars' `input` after resolving links
    pub input: &'a Path,
    /// the outputs' suffixes after `NAME`, in writing order (`.jpg`, `_t.png`,
    /// ...); the sidecar `.json` comes last and is added here
    pub suffixes: &'a [String],
    /// redo an input whose sidecar exists, and replace files at its names
    pub overwrite: bool,
    /// when the name is taken by another input or by unrelated files, try
    /// `NAME_2`, `NAME_3`, ... (the commands); without, write at `NAME`
    /// whatever is there (the API's `restore_file`, whose caller chose it)
    pub rename: bool,
}

/// A claimed name: the paths to write, the claim file, the temporaries.
#[derive(Debug)]
pub struct Claim {
    dir: PathBuf,
    // read by the Python command (the binary takes the paths)
    #[cfg_attr(not(feature = "python"), allow(dead_code))]
    name: String,
    /// outputs in the order of the suffixes, the sidecar last
    paths: Vec<PathBuf>,
    claim_file: PathBuf,
    /// the claim file, open and locked (`flock`) for the claim's life
    /// (None on a file system without locks); dropped after the file is
    /// removed
    _lock: Option<File>,
    temps: Vec<PathBuf>,
    /// indices of outputs not written this time: an earlier run's file at
    /// such a path is removed on commit
    omitted: Vec<usize>,
    /// files a dead run of this input recorded it might leave without a
    /// sidecar and that this run does not write ([`read_left`]): removed on
    /// commit, as an earlier sidecar's outputs are
    orphans: Vec<PathBuf>,
}

/// FNV-1a of the name: a claim file's name stays short whatever the
/// output's length, and is the same for both commands.
fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The input as compared: links resolved when it exists.
fn input_key(p: &Path) -> PathBuf {
    fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// The largest sidecar read: a photo's is a few kilobytes, a video's
/// with a still for every frame megabytes.
pub(crate) const MAX_SIDECAR: u64 = 16 << 20;

/// The most JSON values a sidecar read may hold. Parsed, a value takes
/// some 75 bytes: a planted array of 8 million zeros (16 MiB) took 600 MB,
/// a million values take at most some 75 MB; a video's sidecar of ten
/// thousand stills holds about 60,000.
pub(crate) const MAX_SIDECAR_VALUES: usize = 1_000_000;

/// An upper bound of the values in JSON `text`: its commas, brackets and
/// braces outside strings, counted in one pass before anything is parsed.
fn json_values(text: &[u8]) -> usize {
    let (mut n, mut in_string, mut escaped) = (1usize, false, false);
    for &b in text {
        if in_string {
            match (escaped, b) {
                (true, _) => escaped = false,
                (false, b'\\') => escaped = true,
                (false, b'"') => in_string = false,
                _ => {}
            }
        } else {
            match b {
                b'"' => in_string = true,
                b',' | b'[' | b'{' => n += 1,
                _ => {}
            }
        }
    }
    n
}

/// What a sidecar says of its input: the path as given (`input`), the
/// resolved one when it records it (`input_resolved`, absolute), and the
/// SHA-256 of the input file (`metadata.input_sha256`). None if it cannot
/// be read: a regular file only (a FIFO at its name is never waited on).
fn sidecar_input(path: &Path) -> Option<(PathBuf, Option<PathBuf>, Option<String>)> {
    let v = read_sidecar(path)?;
    let input = PathBuf::from(v.get("input")?.as_str()?);
    let resolved = v.get("input_resolved").and_then(|r| r.as_str()).map(PathBuf::from).filter(|p| p.is_absolute());
    let hash = v
        .pointer("/metadata/input_sha256")
        .and_then(|h| h.as_str())
        .filter(|h| h.len() == 64 && h.bytes().all(|b| b.is_ascii_hexdigit()))
        .map(str::to_ascii_lowercase);
    Some((input, resolved, hash))
}

/// A sidecar's JSON read from `path`: a regular file of at most
/// [`MAX_SIDECAR`] bytes and [`MAX_SIDECAR_VALUES`] values (a FIFO at its
/// name is never waited on), None otherwise or when it is not JSON.
pub(crate) fn read_sidecar(path: &Path) -> Option<serde_json::Value> {
    read_sidecar_within(path, MAX_SIDECAR)
}

/// [`read_sidecar`] of a file of at most `limit` bytes (and
/// [`MAX_SIDECAR`]), read no further.
pub(crate) fn read_sidecar_within(path: &Path, limit: u64) -> Option<serde_json::Value> {
    use std::os::unix::fs::OpenOptionsExt;
    let limit = limit.min(MAX_SIDECAR);
    let f = OpenOptions::new().read(true).custom_flags(libc::O_NONBLOCK).open(path).ok()?;
    let m = f.metadata().ok()?;
    if !m.is_file() || m.len() > limit {
        return None;
    }
    let mut text = Vec::new();
    f.take(limit).read_to_end(&mut text).ok()?;
    if json_values(&text) > MAX_SIDECAR_VALUES {
        return None;
    }
    parse_sidecar(&text)
}

/// A sidecar's JSON. Python's `json` writes a name that is not UTF-8 with
/// its undecodable bytes as lone surrogate escapes (`\udce9`), which
/// serde_json refuses; those are read as U+FFFD, as the binary records them,
/// and so is a lone high half (`\ud800` with no low half after it), as the
/// Python readers read both. A pair stays one character, and an escaped
/// backslash before `u` is no escape.
pub(crate) fn parse_sidecar(text: &[u8]) -> Option<serde_json::Value> {
    if let Ok(v) = serde_json::from_slice(text) {
        return Some(v);
    }
    // the code unit of a `\uXXXX` escape at `at`
    let unit = |at: usize| -> Option<u16> {
        let e = text.get(at..at + 6)?;
        if !e.starts_with(b"\\u") {
            return None;
        }
        u16::from_str_radix(std::str::from_utf8(e.get(2..)?).ok()?, 16).ok()
    };
    let high = |u: u16| (0xD800..0xDC00).contains(&u);
    let low = |u: u16| (0xDC00..0xE000).contains(&u);
    let mut fixed = Vec::with_capacity(text.len());
    let mut i = 0;
    while let Some(&b) = text.get(i) {
        if b != b'\\' {
            fixed.push(b);
            i += 1;
            continue;
        }
        let step = match unit(i) {
            Some(u) if high(u) && unit(i + 6).is_some_and(low) => 12,
            Some(u) if high(u) || low(u) => {
                fixed.extend_from_slice(b"\\ufffd");
                i += 6;
                continue;
            }
            Some(_) => 6,
            // another escape (\\, \", \n): the backslash and what it escapes
            None => 2,
        };
        fixed.extend_from_slice(text.get(i..i + step).or_else(|| text.get(i..))?);
        i += step;
    }
    serde_json::from_slice(&fixed).ok()
}

/// The SHA-256 of a regular file, streamed (None for anything else).
fn file_sha256(p: &Path) -> Option<String> {
    use sha2::Digest;
    if !fs::metadata(p).is_ok_and(|m| m.is_file()) {
        return None;
    }
    let mut f = File::open(p).ok()?;
    let mut h = sha2::Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        match f.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => h.update(buf.get(..n)?),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return None,
        }
    }
    Some(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// Whether the sidecar at `path` is `input`'s, however the input is named
/// now (docs/OUTPUTS.md "Names already in use"): the same path as given
/// (the common rerun), the same resolved path, or, since a relative
/// `input` says nothing once the working directory changed and a name that
/// is not UTF-8 is recorded with U+FFFD, the same file contents (the
/// sidecar's `input_sha256`, computed for the input only when the names
/// do not decide). `hash` caches the input's hash over one [`claim`].
fn sidecar_is_inputs(path: &Path, input: &Path, key: &Path, hash: &mut Option<Option<String>>) -> bool {
    sidecar_match(path, input, key, hash) != Match::No
}

/// How a sidecar is an input's ([`sidecar_is_inputs`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Match {
    No,
    /// by its path or URL
    Named,
    /// by the SHA-256 of its bytes only (another file with the same bytes, or a relative path from elsewhere)
    Contents,
}

/// Whether a sidecar's input, `given` as its run was given it and
/// `resolved` where the sidecar records that, names the local input at
/// `input` (`key`: its [`input_key`]) by name, not by contents; `hashed`:
/// the sidecar records the input's SHA-256. One rule for a folder's claims
/// and for the Python batch's plan (`outdir._match`).
pub fn names_input(given: &Path, resolved: Option<&Path>, hashed: bool, input: &Path, key: &Path) -> bool {
    match resolved {
        // the resolved path, where recorded, decides by name: a relative
        // `input` equal to ours may name another file from another folder
        Some(r) => r == key,
        None if given.is_absolute() => given == input || input_key(given) == key,
        // a URL (a stored input restored into this folder) names its object
        None if given.to_str().is_some_and(|g| g.contains("://")) => given == input,
        // a relative path names a file only from the folder its run started
        // in, which the sidecar does not record (`a.png` of another dive):
        // the contents decide where the sidecar records their hash, else
        // the path as given or from here
        None => !hashed && (given == input || input_key(given) == key),
    }
}

/// [`names_input`] of the local input at `input`, its key worked out here.
pub fn names_local_input(given: &Path, resolved: Option<&Path>, hashed: bool, input: &Path) -> bool {
    names_input(given, resolved, hashed, input, &input_key(input))
}

fn sidecar_match(path: &Path, input: &Path, key: &Path, hash: &mut Option<Option<String>>) -> Match {
    let Some((given, resolved, recorded)) = sidecar_input(path) else { return Match::No };
    let named = names_input(&given, resolved.as_deref(), recorded.is_some(), input, key);
    if named {
        return Match::Named;
    }
    match recorded {
        Some(h) if hash.get_or_insert_with(|| file_sha256(input)).as_deref() == Some(h.as_str()) => Match::Contents,
        _ => Match::No,
    }
}

/// The bytes of a path (a claim file records the input's exactly, names
/// that are not UTF-8 included).
fn path_bytes(p: &Path) -> &[u8] {
    use std::os::unix::ffi::OsStrExt;
    p.as_os_str().as_bytes()
}

/// The suffixes after `NAME` of a video's outputs (the Python command's):
/// its strip and the containers it writes (python/uwhl_rs/videoencode.py
/// `CODECS`).
const VIDEO_SUFFIXES: &[&str] = &["_strip.jpg", ".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts", ".avi"];

/// Whether `suffix` follows `NAME` in some output of either command: a
/// photo's in any `--format`, with its maps and contact sheet
/// ([`output_suffixes`](crate::files::settings::output_suffixes)), or a
/// video's ([`VIDEO_SUFFIXES`]). An earlier sidecar's listed output is
/// removed by an `--overwrite` only under one of these.
fn is_output_suffix(suffix: &str) -> bool {
    use crate::files::settings::{output_suffixes, Format};
    VIDEO_SUFFIXES.contains(&suffix) || Format::ALL.iter().any(|&f| output_suffixes(f, true).iter().any(|s| s == suffix))
}

/// Whether the file name `file` is an output of the output name `name`:
/// `name` and a suffix the commands write ([`is_output_suffix`]). What an
/// `--overwrite` may remove, what a dead claim's record may name, and what
/// a sidecar NAME.json may list (the report and the iFDO refuse others).
pub fn is_output_of(name: &str, file: &str) -> bool {
    file.strip_prefix(name).is_some_and(is_output_suffix)
}

/// The names a sidecar `doc` lists under `outputs` that are `name` + an
/// output's suffix ([`is_output_of`]; sorted, once each): what an
/// `--overwrite` of the input at `name` may remove beside the sidecar, in
/// a folder or on object storage.
pub fn listed_outputs(name: &str, doc: &serde_json::Value) -> Vec<String> {
    let Some(listed) = doc.get("outputs") else { return Vec::new() };
    let mut names = Vec::new();
    collect_strings(listed, &mut names);
    names.retain(|n| is_output_of(name, n));
    names.sort();
    names.dedup();
    names
}

/// Every string in a JSON value (a sidecar's `outputs`, flat or nested).
fn collect_strings(v: &serde_json::Value, out: &mut Vec<String>) {
    match v {
        serde_json::Value::String(s) => out.push(s.clone()),
        serde_json::Value::Array(a) => a.iter().for_each(|x| collect_strings(x, out)),
        serde_json::Value::Object(o) => o.values().for_each(|x| collect_strings(x, out)),
        _ => {}
    }
}

fn in_flight<T>(f: impl FnOnce(&mut HashMap<PathBuf, PathBuf>) -> T) -> T {
    let mut g = IN_FLIGHT.lock().unwrap_or_else(PoisonError::into_inner);
    f(g.get_or_insert_with(HashMap::new))
}

/// Syncs a folder, so that the renames into it survive a power cut.
fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}

/// Whether the process is ending ([`stop_new_temps`]): no temporary is
/// created any more.
static TEMP_GATE: std::sync::RwLock<bool> = std::sync::RwLock::new(false);

/// From now on no temporary file is created ([`create_temp`] fails), once
/// those being created have been: the process is ending on a signal, and
/// what it sweeps from its folder must not be followed by a new one.
pub fn stop_new_temps() {
    *TEMP_GATE.write().unwrap_or_else(PoisonError::into_inner) = true;
}

/// Creates `.uwhl-PID-N.tmp{ext}` beside `dir`'s outputs, exclusively
/// (`O_EXCL`: a file or link planted at that name is never opened, so a
/// link cannot redirect the write), under a short name that fits whatever
/// the output's length. `ext` (e.g. `.png`) tells format-by-name writers
/// what to write.
pub fn create_temp(dir: &Path, ext: &str) -> io::Result<(PathBuf, File)> {
    // held across the creation, so that [`stop_new_temps`] waits for it
    let gate = TEMP_GATE.read().unwrap_or_else(PoisonError::into_inner);
    if *gate {
        return Err(io::Error::other("the run is ending (a signal): no new file is written"));
    }
    let pid = std::process::id();
    let mut last = None;
    for _ in 0..1000 {
        let n = TEMPS.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".uwhl-{pid}-{n}.tmp{ext}"));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| io::Error::other("no temporary name is free")))
}

/// The folder of `path` (`.` for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// The extension of `path` with its dot (`.png`), or "".
fn dotted_extension(path: &Path) -> String {
    path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default()
}

/// Puts a written temporary in place of `path` durably: syncs it, renames
/// it over `path`, syncs the folder. The temporary is removed on an error.
pub fn place(tmp: &Path, path: &Path) -> io::Result<()> {
    let r = File::open(tmp).and_then(|f| f.sync_all()).and_then(|()| fs::rename(tmp, path));
    if r.is_err() {
        let _ = fs::remove_file(tmp);
    }
    r?;
    sync_dir(folder_of(path))
}

/// A new exclusive temporary ([`create_temp`]) in `path`'s folder, with
/// `path`'s extension: where a single file for `path` is written first.
pub fn create_temp_for(path: &Path) -> io::Result<(PathBuf, File)> {
    create_temp(folder_of(path), &dotted_extension(path))
}

/// Writes `bytes` to `path` durably and atomically (an exclusive
/// temporary, then [`place`]). For single files written outside a claim
/// (the demo's files).
pub fn write_file(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let (tmp, mut f) = create_temp_for(path)?;
    if let Err(e) = f.write_all(bytes) {
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    drop(f);
    place(&tmp, path)
}

/// The longest file name (in bytes) the common file systems hold (ext4, XFS, APFS, NTFS).
pub const NAME_MAX: usize = 255;

/// Removes the file at `p` (a dead run's claim, an earlier run's output);
/// one already gone counts as removed.
fn remove_if_present(p: &Path) -> io::Result<()> {
    match fs::remove_file(p) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// What [`hold_claim`] found at a claim file.
enum Hold {
    /// this process holds it: the open file, locked (None where the file
    /// system has no locks), and, when it was a dead run's claim of the
    /// same input, the files that run's commit may have left without a
    /// sidecar ([`read_left`]; then its half-committed outputs are replaced)
    Mine(Option<File>, Option<Vec<String>>),
    /// a live process (its pid) holds it, for this input
    Theirs(u32, PathBuf),
}

/// The file's device and inode: one file, under whatever name.
fn identity(m: &fs::Metadata) -> (u64, u64) {
    use std::os::unix::fs::MetadataExt;
    (m.dev(), m.ino())
}

/// Takes `lock` exclusively without waiting: Some(true) taken, Some(false)
/// another open file holds it, None the file system has no locks.
fn try_lock(f: &File) -> Option<bool> {
    match f.try_lock() {
        Ok(()) => Some(true),
        Err(fs::TryLockError::WouldBlock) => Some(false),
        Err(fs::TryLockError::Error(_)) => None,
    }
}

/// The names a claim's commit recorded before it touched the folder
/// ([`Claim::commit`]: `left NAME` lines after the record): the earlier
/// run's outputs it removes and its own it renames in. A run killed in
/// between leaves them without a sidecar; the run that takes its claim
/// over removes those it does not write itself (another `--format`), and
/// only those that are its own outputs ([`is_output_of`]: a planted claim
/// naming the user's notes.txt or another input's maps removes nothing).
/// Output names are UTF-8, so a line that is not is no name of one; the
/// record is read from its start.
fn read_left(mut f: &File) -> Vec<String> {
    use std::io::Seek;
    let mut s = Vec::new();
    if f.rewind().is_err() || f.take(1 << 20).read_to_end(&mut s).is_err() {
        return Vec::new();
    }
    s.split(|&b| b == b'\n')
        .skip(4)
        .filter_map(|l| l.strip_prefix(b"left "))
        .filter_map(|n| String::from_utf8(n.to_vec()).ok())
        .collect()
}

/// The pid, the process's start time (when the claim records it) and the
/// input an open claim file names.
fn read_record(f: &File) -> Option<(u32, Option<u64>, PathBuf)> {
    use std::os::unix::ffi::OsStrExt;
    let mut s = Vec::new();
    f.take(1 << 16).read_to_end(&mut s).ok()?;
    let mut lines = s.split(|&b| b == b'\n');
    let pid = std::str::from_utf8(lines.next()?).ok()?.parse().ok()?;
    let _name = lines.next()?;
    let input = lines.next()?;
    if input.is_empty() {
        return None;
    }
    // the process's start time, after what earlier builds write and read (a claim of theirs has none)
    let start = lines.next().and_then(|l| std::str::from_utf8(l).ok()).and_then(|l| l.parse().ok());
    Some((pid, start, PathBuf::from(std::ffi::OsStr::from_bytes(input))))
}

/// How often a claim that is held but not by a live process named in it
/// (being taken over, or being written) is looked at again, 20 ms apart,
/// before the input is given up as held by another process.
const WAITS: usize = 100;

/// Of those, how many for a takeover in progress (see [`settle_claim`]).
const TAKEOVER_WAITS: usize = 5;

/// Makes `claim_file` this process's, holding `record` (which names the
/// input `key`), or says whose it is (docs/OUTPUTS.md "Names already in
/// use").
///
/// The claim appears whole and locked: it is written and `flock`ed under
/// an exclusive temporary name, then linked to its name (a link fails
/// when the name exists, so two processes never both make it). Its owner
/// keeps it open, so the lock lasts exactly as long as the owner: a claim
/// nobody holds belongs to a process that is gone (kill -9, a power cut),
/// by the kernel's word rather than a guess from pids. A taker locks the
/// dead claim before removing it, and checks it still is the file at the
/// name, so two takers never both remove one and both claim. Claims of
/// builds that took no lock, and file systems without locks, fall back
/// to the pid and start time the record holds.
fn hold_claim(dir: &Path, claim_file: &Path, record: &[u8], key: &Path) -> io::Result<Hold> {
    let (tmp, mut mine) = create_temp(dir, "")?;
    // readable by every user whatever the umask, so that another user's
    // run on a shared folder can lock it and read whose it is
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = mine.set_permissions(fs::Permissions::from_mode(0o644));
    }
    let locked = try_lock(&mine) == Some(true);
    if let Err(e) = mine.write_all(record) {
        // a full disk: no empty claim is left for later runs to wait on
        drop(mine);
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    let result = settle_claim(&tmp, mine, locked, claim_file, record, key);
    let _ = fs::remove_file(&tmp);
    result
}

/// [`hold_claim`]'s loop: `tmp` is this process's claim, written, open as
/// `mine` (locked when `locked`).
fn settle_claim(tmp: &Path, mine: File, locked: bool, claim_file: &Path, record: &[u8], key: &Path) -> io::Result<Hold> {
    use std::os::unix::fs::OpenOptionsExt;
    let own = std::process::id();
    let mut links = true;
    // a dead claim being taken over, locked until this one is in its place
    let mut _dead: Option<File> = None;
    let mut stale: Option<Vec<String>> = None;
    let mut waits = 0;
    let wait = |waits: &mut usize| -> io::Result<()> {
        *waits += 1;
        if *waits > WAITS {
            return Err(io::Error::other(format!("{} is held by another process", claim_file.display())));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
        Ok(())
    };
    let mut mine = Some(mine);
    loop {
        let made = if links {
            fs::hard_link(tmp, claim_file).map(|()| if locked { mine.take() } else { None })
        } else {
            claim_in_place(claim_file, record)
        };
        match made {
            Ok(lock) => return Ok(Hold::Mine(lock, stale)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) if links && matches!(e.raw_os_error(), Some(libc::EPERM | libc::EOPNOTSUPP | libc::ENOSYS | libc::EMLINK)) => {
                // no links on this file system: made in place, locked at once
                links = false;
                continue;
            }
            Err(e) => return Err(e),
        }
        _dead = None;
        stale = None;
        let theirs = match OpenOptions::new().read(true).custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW).open(claim_file) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => continue,
            // a link planted at the name is no claim: removed (its target untouched)
            Err(e) if e.raw_os_error() == Some(libc::ELOOP) => {
                remove_if_present(claim_file)?;
                continue;
            }
            Err(e) => {
                // a socket (or a device) at the name is no claim either
                if fs::symlink_metadata(claim_file).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
                    remove_if_present(claim_file)?;
                    continue;
                }
                return Err(io::Error::new(e.kind(), format!("cannot read the claim {}: {e}", claim_file.display())));
            }
        };
        let meta = theirs.metadata()?;
        if !meta.is_file() {
            // a folder at the name: it cannot be removed as a claim is
            remove_if_present(claim_file)?;
            continue;
        }
        let still_there = || fs::symlink_metadata(claim_file).map(|m| identity(&m) == identity(&meta)).unwrap_or(false);
        let found = read_record(&theirs);
        let held = try_lock(&theirs);
        if held == Some(false) {
            if !still_there() {
                // taken over this instant: the new claim is looked at
                continue;
            }
            // the lock says its owner runs, whatever the pid (a process of
            // another pid namespace sharing the folder); a pid that does not
            // run is a dead run's claim another process is taking over this
            // instant: looked at again briefly, for the new owner's pid. A
            // claim that cannot be read is one of a build that locks before
            // it writes, caught in between: looked at again
            let live = |&(pid, start, _): &(u32, Option<u64>, PathBuf)| {
                crate::files::jobs::process_is(pid, start) || waits >= TAKEOVER_WAITS
            };
            if let Some((pid, _, holder)) = found.filter(live) {
                return Ok(Hold::Theirs(pid, holder));
            }
            drop(theirs);
            wait(&mut waits)?;
            continue;
        }
        // nobody holds it: its owner is gone, unless it is a live process
        // of a build that takes no lock, or the file system's locks do not
        // tell (none at all; NFS's, which one process does not conflict
        // with: this process's own claim, by its start time)
        match found {
            Some((pid, start, holder)) if (pid != own || start.is_some()) && crate::files::jobs::process_is(pid, start) => {
                return Ok(Hold::Theirs(pid, holder));
            }
            // files at the name are that run's half-committed outputs only
            // when it was restoring this same input: a claim naming
            // another input says nothing of them
            Some((_, _, holder)) => stale = (holder == key).then(|| read_left(&theirs)),
            None if waits == 0 => {
                // a claim of a build that writes after it creates, being
                // written this instant, or one cut short by a crash: looked
                // at once more, then whose it was cannot be told
                drop(theirs);
                wait(&mut waits)?;
                continue;
            }
            None => {}
        }
        if !still_there() {
            continue;
        }
        remove_if_present(claim_file)?;
        _dead = Some(theirs);
    }
}

/// A claim file made at its name directly (a file system without links):
/// created exclusively, locked, then written.
fn claim_in_place(claim_file: &Path, record: &[u8]) -> io::Result<Option<File>> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut f = OpenOptions::new().write(true).create_new(true).mode(0o644).open(claim_file)?;
    let locked = try_lock(&f) == Some(true);
    if let Err(e) = f.write_all(record) {
        drop(f);
        let _ = fs::remove_file(claim_file);
        return Err(e);
    }
    Ok(locked.then_some(f))
}

/// The name under which an earlier run restored `req.input` into
/// `req.dir`, when a batch would have named it otherwise than `req.base`:
/// the names a batch gives an input of stem `S` and extension `E` are `S`,
/// `S_E` (when inputs of one folder share the stem) and those followed by
/// `_2`, `_3`, ... (docs/OUTPUTS.md "Names already in use"). Each sequence
/// is looked at until [`FAMILY_GAP`] names in a row have no sidecar (an
/// input that failed, or was skipped, leaves a hole). A sidecar that names
/// this input by its path decides, the planned name's first; one that
/// matches only by the bytes' hash (another file with the same bytes) is
/// taken only without `--overwrite` (skipped as done: with it, that file's
/// outputs would be written over). So a rerun whose batch gives the inputs
/// of one stem in another order, or holds more of them, skips what is
/// done instead of restoring it again under a new name.
fn earlier_name(req: &Request<'_>, key: &Path, hash: &mut Option<Option<String>>) -> Option<String> {
    req.input.file_stem()?;
    let family = crate::files::jobs::name_bases(req.input);
    // the planned name and its own sequence are the claim's to try
    if !family.iter().any(|f| req.base == f || req.base.strip_prefix(f.as_str()).is_some_and(is_counter)) {
        return None;
    }
    let planned = req.dir.join(format!("{}.json", req.base));
    if planned.exists() && sidecar_match(&planned, req.input, key, hash) == Match::Named {
        return None;
    }
    let mut by_contents = None;
    for base in &family {
        let mut missing = 0;
        for k in 1..=MAX_NAMES {
            let name = if k == 1 { base.clone() } else { format!("{base}_{k}") };
            let sidecar = req.dir.join(format!("{name}.json"));
            if !sidecar.exists() {
                missing += 1;
                if missing > FAMILY_GAP {
                    break;
                }
                continue;
            }
            missing = 0;
            if name == req.base {
                continue;
            }
            match sidecar_match(&sidecar, req.input, key, hash) {
                Match::Named => return Some(name),
                Match::Contents if by_contents.is_none() && !req.overwrite => by_contents = Some(name),
                _ => {}
            }
        }
    }
    by_contents
}

/// Names in a row without a sidecar after which [`earlier_name`] stops
/// looking along a sequence.
pub const FAMILY_GAP: usize = 16;

/// Whether `r` is `_N` with N a number of at least 2 (a name's counter).
fn is_counter(r: &str) -> bool {
    r.strip_prefix('_').is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) && n != "0" && n != "1")
}

/// Claims a name for `req.input`'s outputs (see the module documentation).
/// Tries `NAME`, then (with `rename`) `NAME_2`, ... until one is free or
/// holds this input's own sidecar. Errors: the folder cannot be created or
/// written, an output name longer than [`NAME_MAX`] bytes, or (without
/// `rename`) another process holds the name.
pub fn claim(req: &Request<'_>) -> io::Result<Resolution> {
    if let Some(why) = crate::files::jobs::outdir_moved(req.dir) {
        return Err(io::Error::other(why));
    }
    fs::create_dir_all(req.dir)?;
    let key = input_key(req.input);
    let own = std::process::id();
    let started = crate::files::jobs::process_start(own).map(|t| format!("{t}\n")).unwrap_or_default();
    // the input's SHA-256 once computed (only when a sidecar's names do not decide)
    let mut hash: Option<Option<String>> = None;
    // an earlier run may have named it otherwise (its batch held other
    // inputs of its stem, or in another order): its sidecar there decides
    let start = if req.rename {
        earlier_name(req, &key, &mut hash).unwrap_or_else(|| req.base.to_string())
    } else {
        req.base.to_string()
    };
    let tries = if req.rename { MAX_NAMES } else { 1 };
    for k in 1..=tries {
        let name = if k == 1 { start.clone() } else { format!("{start}_{k}") };
        if req.rename && RESERVED.contains(&name.as_str()) {
            continue;
        }
        // a name the file system cannot hold fails here, before the input is decoded and restored
        if let Some(long) = req.suffixes.iter().map(|s| format!("{name}{s}")).find(|f| f.len() > NAME_MAX) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidFilename,
                format!("the output name {long} is {} bytes, more than the {NAME_MAX} a file name may have", long.len()),
            ));
        }
        let mut paths: Vec<PathBuf> = req.suffixes.iter().map(|s| req.dir.join(format!("{name}{s}"))).collect();
        let sidecar = req.dir.join(format!("{name}.json"));
        paths.push(sidecar.clone());
        // inputs in flight in this process
        let busy_here = in_flight(|m| {
            paths.iter().find_map(|p| m.get(p)).map(|owner| *owner == key)
        });
        match busy_here {
            Some(true) => return Ok(Resolution::Skipped(Skip::InFlight, sidecar)),
            Some(false) if req.rename => continue,
            Some(false) => return Err(io::Error::other(format!("{} is being written by this process", sidecar.display()))),
            None => {}
        }
        // the claim file, made first, so that no other process decides on
        // this name while it is looked at
        let claim_file = req.dir.join(format!(".uwhl-claim-{:016x}", name_hash(&name)));
        let mut record = format!("{own}\n{name}\n").into_bytes();
        record.extend_from_slice(path_bytes(&key));
        record.push(b'\n');
        record.extend_from_slice(started.as_bytes());
        let (lock, stale) = match hold_claim(req.dir, &claim_file, &record, &key) {
            Ok(Hold::Mine(lock, left)) => (lock, left),
            Ok(Hold::Theirs(pid, holder)) => {
                if holder == key {
                    let why = if pid == own { Skip::InFlight } else { Skip::Busy(pid) };
                    return Ok(Resolution::Skipped(why, sidecar));
                }
                if !req.rename {
                    return Err(io::Error::other(format!("{} is being written by process {pid}", sidecar.display())));
                }
                continue;
            }
            // a folder that cannot be written (a read-only mount of a
            // finished survey, a full disk, a dead run's claim that cannot
            // be removed): an input whose sidecar is here is done all the
            // same, one whose name holds another's sidecar looks on;
            // anything else cannot be written (never retried: a claim that
            // cannot be removed would be met again, for ever)
            Err(failed) => {
                if sidecar.exists() {
                    if sidecar_is_inputs(&sidecar, req.input, &key, &mut hash) {
                        if !req.overwrite {
                            return Ok(Resolution::Skipped(Skip::Done, sidecar));
                        }
                    } else if req.rename {
                        continue;
                    }
                }
                return Err(failed);
            }
        };
        // None: this name is taken; Some(skip): the input is skipped
        let give_up: Option<Option<Skip>> = if sidecar.exists() {
            let mine = sidecar_is_inputs(&sidecar, req.input, &key, &mut hash);
            if mine && !req.overwrite {
                Some(Some(Skip::Done))
            } else if !mine && req.rename {
                // another input's outputs (another camera's frame.jpg): never replaced
                Some(None)
            } else {
                None
            }
        } else if req.rename && stale.is_none() && paths.iter().any(|p| fs::symlink_metadata(p).is_ok()) {
            // unrelated files at this name, not left by a killed run of this
            // input: never replaced, --overwrite or not (it redoes this
            // input's own outputs, found by its sidecar at a later name)
            Some(None)
        } else {
            None
        };
        if let Some(skip) = give_up {
            // the claim file goes before its lock, so that nobody finds it
            // unlocked while it is still this input's
            let _ = fs::remove_file(&claim_file);
            drop(lock);
            match skip {
                Some(why) => return Ok(Resolution::Skipped(why, sidecar)),
                None => continue,
            }
        }
        in_flight(|m| {
            for p in &paths {
                m.insert(p.clone(), key.clone());
            }
        });
        // a dead claim is as hostile as a sidecar: only this name's outputs
        // (NAME and a suffix the commands write) are ever taken from it
        let orphans = stale
            .unwrap_or_default()
            .into_iter()
            .filter(|n| is_output_of(&name, n))
            .map(|n| req.dir.join(n))
            .filter(|p| !paths.contains(p))
            .collect();
        return Ok(Resolution::Claimed(Claim {
            dir: req.dir.to_path_buf(),
            name,
            paths,
            claim_file,
            _lock: lock,
            temps: Vec::new(),
            omitted: Vec::new(),
            orphans,
        }));
    }
    Err(io::Error::other(format!("no free output name for {} in {}", req.base, req.dir.display())))
}

impl Claim {
    /// The name the outputs are written under.
    #[cfg_attr(not(feature = "python"), allow(dead_code))]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The output paths in the order of the request's suffixes, the sidecar last.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// A new exclusive temporary file for output `index` (see [`create_temp`]).
    pub fn temp(&mut self, index: usize) -> io::Result<(PathBuf, File)> {
        let ext = self.paths.get(index).map(|p| dotted_extension(p)).unwrap_or_default();
        let (tmp, f) = create_temp(&self.dir, &ext)?;
        self.temps.push(tmp.clone());
        Ok((tmp, f))
    }

    /// Marks output `index` (not the sidecar) as not written by this run:
    /// [`Claim::commit`] then takes no temporary for it and removes the
    /// file an earlier run left at its path, so the folder never holds an
    /// output that belongs to another restoration.
    pub fn omit(&mut self, index: usize) {
        if index + 1 < self.paths.len() && !self.omitted.contains(&index) {
            self.omitted.push(index);
        }
    }

    /// Nothing is written this time: the files an earlier run left at
    /// every path (the sidecar first) are removed, so the folder holds no
    /// output of another restoration under these names.
    pub fn clear(self) -> io::Result<()> {
        let Some((sidecar, outputs)) = self.paths.split_last() else {
            return Ok(());
        };
        let earlier = self.earlier_outputs();
        for p in std::iter::once(sidecar).chain(outputs) {
            remove_if_present(p)?;
        }
        for p in &earlier {
            let _ = remove_if_present(p);
        }
        sync_dir(&self.dir)
    }

    /// The outputs the sidecar now at this name lists that this run does
    /// not write at all (another `--format`, a contact sheet not asked for
    /// again, another codec): removed with that sidecar, so a sidecar never
    /// stands beside an earlier run's image it does not list. Only names
    /// `NAME` + an output's suffix ([`listed_outputs`]) in this folder are taken from
    /// the sidecar (a hostile one names nothing else), and none that is
    /// itself another input's output (`NAME_sheet.png` when
    /// `NAME_sheet.json` is there).
    fn earlier_outputs(&self) -> Vec<PathBuf> {
        let Some(sidecar) = self.paths.last() else { return Vec::new() };
        let listed = read_sidecar(sidecar).map(|doc| listed_outputs(&self.name, &doc)).unwrap_or_default();
        listed
            .into_iter()
            .map(|n| self.dir.join(n))
            .chain(self.orphans.iter().cloned())
            .filter(|p| {
                !self.paths.contains(p)
                    && fs::symlink_metadata(p).is_ok_and(|m| m.is_file())
                    && (p.with_extension("json") == *sidecar || !p.with_extension("json").exists())
            })
            .collect()
    }

    /// Appends `left NAME` to the claim file for each of `paths` (all in
    /// the claim's folder) and syncs it ([`read_left`]).
    fn record_left<'a>(&self, paths: impl Iterator<Item = &'a PathBuf>) -> io::Result<()> {
        use std::os::unix::ffi::OsStrExt;
        use std::os::unix::fs::OpenOptionsExt;
        let mut text = Vec::new();
        for name in paths.filter_map(|p| p.file_name()) {
            text.extend_from_slice(b"\nleft ");
            text.extend_from_slice(name.as_bytes());
        }
        let mut f = OpenOptions::new().append(true).custom_flags(libc::O_NOFOLLOW).open(&self.claim_file)?;
        f.write_all(&text)?;
        f.sync_data()
    }

    /// Puts the written temporaries (one per path not omitted, in the
    /// order of [`Claim::paths`], each made by [`Claim::temp`]) in place:
    /// syncs them, removes an earlier sidecar, removes the omitted outputs'
    /// old files, renames the outputs, syncs the folder, renames the
    /// sidecar, syncs the folder. On an error the outputs renamed so far
    /// are removed (there is no sidecar then, so the next run redoes the
    /// input).
    pub fn commit(self, temps: &[PathBuf]) -> io::Result<()> {
        if temps.len() + self.omitted.len() != self.paths.len() || !temps.iter().all(|t| self.temps.contains(t)) {
            return Err(io::Error::other("commit needs one temporary of this claim per output"));
        }
        if let Some(why) = self.paths.last().and_then(|p| p.parent()).and_then(crate::files::jobs::outdir_moved) {
            return Err(io::Error::other(why));
        }
        for t in temps {
            File::open(t)?.sync_all()?;
        }
        let Some((sidecar, outputs)) = self.paths.split_last() else {
            return Err(io::Error::other("a claim without outputs"));
        };
        let Some((sidecar_tmp, output_temps)) = temps.split_last() else {
            return Err(io::Error::other("a claim without outputs"));
        };
        let earlier = self.earlier_outputs();
        // what a kill from here on may leave without a sidecar, made
        // durable first: the run that takes this claim over removes it
        self.record_left(earlier.iter().chain(outputs.iter()))?;
        let removed = match fs::remove_file(sidecar) {
            Ok(()) => true,
            Err(e) if e.kind() == io::ErrorKind::NotFound => false,
            Err(e) => return Err(e),
        };
        // best effort: a file that cannot be removed (immutable, a
        // read-only bind) stays beside the new sidecar, unlisted, rather
        // than failing the input with its old outputs left without a
        // sidecar. Without an earlier sidecar these are a dead run's
        // leftovers ([`read_left`])
        for p in &earlier {
            let _ = remove_if_present(p);
        }
        if removed || !earlier.is_empty() {
            sync_dir(&self.dir)?
        }
        let written: Vec<&PathBuf> = outputs
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.omitted.contains(i))
            .map(|(_, p)| p)
            .collect();
        for p in self.omitted.iter().filter_map(|&i| outputs.get(i)) {
            remove_if_present(p)?;
        }
        let mut renamed = Vec::new();
        let result = (|| {
            for (t, p) in output_temps.iter().zip(written) {
                fs::rename(t, p)?;
                renamed.push(p.clone());
            }
            sync_dir(&self.dir)?;
            fs::rename(sidecar_tmp, sidecar)?;
            sync_dir(&self.dir)
        })();
        if result.is_err() {
            for p in &renamed {
                let _ = fs::remove_file(p);
            }
        }
        result
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        for t in &self.temps {
            let _ = fs::remove_file(t);
        }
        let _ = fs::remove_file(&self.claim_file);
        in_flight(|m| {
            for p in &self.paths {
                m.remove(p);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("uwhl-commit-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    fn suffixes() -> Vec<String> {
        vec![".png".into(), "_t.png".into()]
    }

    fn write_all(c: &mut Claim, sidecar: &str) -> Vec<PathBuf> {
        let n = c.paths().len();
        (0..n)
            .map(|i| {
                let (t, mut f) = c.temp(i).unwrap();
                let body = if i + 1 == n { sidecar.to_string() } else { format!("output {i}") };
                f.write_all(body.as_bytes()).unwrap();
                t
            })
            .collect()
    }

    fn claimed(r: Resolution) -> Claim {
        match r {
            Resolution::Claimed(c) => c,
            other => panic!("not claimed: {other:?}"),
        }
    }

    fn request<'a>(dir: &'a Path, base: &'a str, input: &'a Path, s: &'a [String], overwrite: bool) -> Request<'a> {
        Request { dir, base, input, suffixes: s, overwrite, rename: true }
    }

    #[test]
    fn the_suffixes_an_overwrite_may_remove_are_the_commands_outputs_only() {
        for s in [".jpg", ".png", ".tif", "_t.png", "_t_color.png", "_confidence.png", "_sheet.png", "_strip.jpg"] {
            assert!(is_output_suffix(s), "{s}");
        }
        for s in [".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts", ".avi"] {
            assert!(is_output_suffix(s), "{s}");
        }
        for s in ["", ".json", "_2.jpg", "_notes.txt", ".tiff", ".webm", "_t.jpg", "/../x.png"] {
            assert!(!is_output_suffix(s), "{s}");
        }
    }

    #[test]
    fn an_overwrite_in_another_format_removes_the_earlier_runs_image_its_sidecar_listed() {
        let d = folder("reformat");
        fs::create_dir(d.join("in")).unwrap();
        let a = d.join("in").join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        let jpg: Vec<String> = vec![".jpg".into(), "_t.png".into(), "_sheet.png".into()];
        let png: Vec<String> = vec![".png".into(), "_t.png".into()];
        let mut first = claimed(claim(&request(&d, "a", &a, &jpg, false)).unwrap());
        // the earlier sidecar lists its files, some of them hostile names
        let side = format!(
            "{{\"input\": \"{}\", \"outputs\": {{\"image\": \"a.jpg\", \"transmission\": \"a_t.png\", \"sheet\": \"a_sheet.png\", \
             \"x\": [\"../a.jpg\", \"a\", \"a_/../b.png\", \"b.png\", \".a.png\", \"a_notes.txt\", \"a_2.jpg\", \"a_t_color.png\"]}}}}",
            a.display()
        );
        let temps = write_all(&mut first, &side);
        first.commit(&temps).unwrap();
        fs::write(d.join("b.png"), b"the user's").unwrap();
        fs::write(d.join("a"), b"the user's too").unwrap();
        fs::write(d.join("a_notes.txt"), b"the user's notes").unwrap();
        // other inputs' outputs: a_2 (a second input named a), and the
        // image of an input named a_t_color (its sidecar a_t_color.json)
        fs::write(d.join("a_2.jpg"), b"another input's").unwrap();
        fs::write(d.join("a_t_color.png"), b"input a_t_color's image").unwrap();
        fs::write(d.join("a_t_color.json"), b"{}").unwrap();
        fs::write(d.parent().unwrap().join("a.jpg"), b"outside").ok();
        // the same input again, --overwrite, as PNG without a sheet
        let mut again = claimed(claim(&request(&d, "a", &a, &png, true)).unwrap());
        let temps = write_all(&mut again, &format!("{{\"input\": \"{}\"}}", a.display()));
        again.commit(&temps).unwrap();
        let mut left: Vec<String> = fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        left.sort();
        assert_eq!(left, ["a", "a.json", "a.png", "a_2.jpg", "a_notes.txt", "a_t.png", "a_t_color.json", "a_t_color.png", "b.png", "in"], "{left:?}");
        assert_eq!(fs::read(d.join("b.png")).unwrap(), b"the user's");
        let _ = fs::remove_file(d.parent().unwrap().join("a.jpg"));
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn an_omitted_output_is_not_written_and_an_old_file_at_its_path_goes() {
        let d = folder("omit");
        let s = suffixes();
        let a = d.join("a.jpg");
        let mut first = claimed(claim(&request(&d, "a", &a, &s, true)).unwrap());
        let side = format!("{{\"input\": \"{}\"}}", a.display());
        let temps = write_all(&mut first, &side);
        first.commit(&temps).unwrap();
        assert_eq!(fs::read_to_string(d.join("a_t.png")).unwrap(), "output 1");
        // a rerun that makes no second output: a_t.png of the first run goes
        let mut again = claimed(claim(&request(&d, "a", &a, &s, true)).unwrap());
        again.omit(1);
        // the sidecar cannot be omitted
        again.omit(2);
        let (t0, mut f0) = again.temp(0).unwrap();
        f0.write_all(b"new image").unwrap();
        let (t2, mut f2) = again.temp(2).unwrap();
        f2.write_all(side.as_bytes()).unwrap();
        // one temporary too few (the omitted output's index is not the sidecar's)
        let mut short = claimed(claim(&request(&d, "b", &d.join("b.jpg"), &s, true)).unwrap());
        short.omit(1);
        let (tb, _) = short.temp(0).unwrap();
        assert!(short.commit(&[tb]).is_err());
        again.commit(&[t0, t2]).unwrap();
        assert_eq!(fs::read_to_string(d.join("a.png")).unwrap(), "new image");
        assert!(!d.join("a_t.png").exists());
        assert_eq!(fs::read_to_string(d.join("a.json")).unwrap(), side);
    }

    #[test]
    fn a_committed_input_is_done_another_input_with_the_same_name_goes_elsewhere() {
        let d = folder("names");
        let s = suffixes();
        let (a, b) = (d.join("camA-frame.jpg"), d.join("camB-frame.jpg"));
        let mut c = claimed(claim(&request(&d, "frame", &a, &s, false)).unwrap());
        let side = format!("{{\"input\": \"{}\"}}", a.display());
        let temps = write_all(&mut c, &side);
        c.commit(&temps).unwrap();
        assert_eq!(fs::read_to_string(d.join("frame.png")).unwrap(), "output 0");
        // the same input again: done
        assert!(matches!(claim(&request(&d, "frame", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::Done, p) if p == d.join("frame.json")));
        // another camera's frame.jpg: never over camA's, even with overwrite
        for overwrite in [false, true] {
            let c = claimed(claim(&request(&d, "frame", &b, &s, overwrite)).unwrap());
            assert_eq!(c.name(), "frame_2");
        }
        // no claim file or temporary is left
        let left: Vec<_> = fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(left.len(), 3, "{left:?}");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn in_flight_inputs_see_each_other_and_unrelated_files_are_kept() {
        let d = folder("flight");
        let s = suffixes();
        let a = d.join("a.jpg");
        let first = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        // the same input while the first is in flight: not restored twice
        assert!(matches!(claim(&request(&d, "a", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::InFlight, _)));
        // another input whose outputs would share a path (a_t.jpg as png: a_t.png)
        let s2 = vec!["_t.png".into()];
        let other = claimed(claim(&request(&d, "a", &d.join("b.jpg"), &s2, false)).unwrap());
        assert_eq!(other.name(), "a_2");
        drop((first, other));
        // an unrelated file with an output's name: kept without overwrite
        fs::write(d.join("x_t.png"), b"mine").unwrap();
        let c = claimed(claim(&request(&d, "x", &d.join("x.jpg"), &s, false)).unwrap());
        assert_eq!(c.name(), "x_2");
        drop(c);
        // --overwrite redoes this input's own outputs, never unrelated files
        let c = claimed(claim(&request(&d, "x", &d.join("x.jpg"), &s, true)).unwrap());
        assert_eq!(c.name(), "x_2");
        drop(c);
        assert_eq!(fs::read(d.join("x_t.png")).unwrap(), b"mine");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_live_claim_of_another_process_makes_the_input_busy_a_dead_or_reused_one_is_taken_over() {
        let d = folder("busy");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"").unwrap();
        let key = input_key(&a);
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("a")));
        // pid 1 runs on every Linux system
        fs::write(&claim_file, format!("1\na\n{}\n", key.display())).unwrap();
        assert!(matches!(claim(&request(&d, "a", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::Busy(1), _)));
        // pid 1 with the start time it has: busy; with another (the pid of a killed run, reused
        // since by another process, here pid 1): taken over, as a dead process's
        let start = crate::files::jobs::process_start(1).expect("/proc/1/stat");
        fs::write(&claim_file, format!("1\na\n{}\n{start}\n", key.display())).unwrap();
        assert!(matches!(claim(&request(&d, "a", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::Busy(1), _)));
        fs::write(&claim_file, format!("1\na\n{}\n{}\n", key.display(), start + 1)).unwrap();
        let c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(c.name(), "a");
        drop(c);
        // a dead process left its claim and one renamed output: taken over, replaced
        fs::write(&claim_file, format!("4194399\na\n{}\n", key.display())).unwrap();
        fs::write(d.join("a.png"), b"half of a killed run").unwrap();
        let mut c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(c.name(), "a");
        let temps = write_all(&mut c, "{}");
        c.commit(&temps).unwrap();
        assert_eq!(fs::read_to_string(d.join("a.png")).unwrap(), "output 0");
        assert!(!claim_file.exists());
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn temporaries_are_created_exclusively_under_short_names() {
        let d = folder("tmpnames");
        // links planted at the next temporary names point outside the folder
        let victim = d.join("victim");
        fs::write(&victim, b"keep").unwrap();
        let next = TEMPS.load(Ordering::Relaxed);
        for k in next..next + 5 {
            std::os::unix::fs::symlink(&victim, d.join(format!(".uwhl-{}-{k}.tmp.png", std::process::id()))).unwrap();
        }
        // an output name of 250 bytes: its temporary's name still fits
        let long = d.join(format!("{}.png", "x".repeat(246)));
        write_file(&long, b"data").unwrap();
        assert_eq!(fs::read(&long).unwrap(), b"data");
        assert_eq!(fs::read(&victim).unwrap(), b"keep");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_earlier_run_whole() {
        let d = folder("fail");
        let s = suffixes();
        let a = d.join("a.jpg");
        let side = format!("{{\"input\": \"{}\"}}", a.display());
        let mut c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        let temps = write_all(&mut c, &side);
        c.commit(&temps).unwrap();
        // an overwrite whose second output cannot be written (full disk):
        // dropped before commit, nothing of the first run changes
        let mut c = claimed(claim(&request(&d, "a", &a, &s, true)).unwrap());
        let (_t, mut f) = c.temp(0).unwrap();
        f.write_all(b"new").unwrap();
        drop(c);
        assert_eq!(fs::read_to_string(d.join("a.png")).unwrap(), "output 0");
        assert_eq!(fs::read_to_string(d.join("a.json")).unwrap(), side);
        assert_eq!(fs::read_dir(&d).unwrap().count(), 3);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_python_sidecar_with_a_lone_surrogate_is_read_with_u_fffd() {
        let v = parse_sidecar(br#"{"input": "caf\udce9.png", "x": "\ud83d\ude00\udc80"}"#).unwrap();
        assert_eq!(v["input"], "caf\u{fffd}.png");
        assert_eq!(v["x"], "\u{1f600}\u{fffd}");
        // a lone high half, one at the end, a low half of the DD-DF range, and
        // a backslash escaped before a u: text, no escape
        let v = parse_sidecar(br#"{"a": "x\udce9\ud800.png", "b": "\uD83D", "c": "\udfff\ud83d\udc1f", "d": "\\udc80\udc80"}"#).unwrap();
        assert_eq!(v["a"], "x\u{fffd}\u{fffd}.png");
        assert_eq!(v["b"], "\u{fffd}");
        assert_eq!(v["c"], "\u{fffd}\u{1f41f}");
        assert_eq!(v["d"], "\\udc80\u{fffd}");
        // JSON that is broken otherwise stays unread
        assert!(parse_sidecar(br#"{"a": "\ud800"#).is_none());
    }

    #[test]
    fn a_sidecar_of_too_many_values_is_not_read_and_a_long_videos_is() {
        // a planted array of 8 million zeros (16 MiB) parsed to about 600 MB
        let d = folder("bigside");
        let p = d.join("a.json");
        let body = |n: usize| format!("{{\"input\": \"a.jpg\", \"pad\": [{}0]}}", "0,".repeat(n));
        fs::write(&p, body(MAX_SIDECAR_VALUES)).unwrap();
        assert!(read_sidecar(&p).is_none());
        fs::write(&p, body(MAX_SIDECAR_VALUES - 10)).unwrap();
        assert_eq!(read_sidecar(&p).unwrap()["input"], "a.jpg");
        // commas, brackets and braces inside strings are no values
        let words = format!("{{\"input\": \"a.jpg\", \"note\": \"{}\\\",\"}}", ",[{".repeat(MAX_SIDECAR_VALUES));
        fs::write(&p, &words).unwrap();
        assert_eq!(read_sidecar(&p).unwrap()["input"], "a.jpg");
        // a video's sidecar with a still for each of 20,000 frames (some 2.6 MB) is read
        let still = r#"{"frame": 123456, "time": 4115.2, "image": "dive_01h08m35.200s.jpg", "sidecar": "dive_01h08m35.200s.json"}"#;
        let video = format!("{{\"input\": \"dive.mp4\", \"video\": {{\"stills\": [{}]}}}}", vec![still; 20_000].join(", "));
        assert!(video.len() > 2 << 20);
        fs::write(&p, &video).unwrap();
        assert_eq!(read_sidecar(&p).unwrap()["input"], "dive.mp4");
        fs::remove_dir_all(&d).unwrap();
    }

    fn sha256_of(p: &Path) -> String {
        file_sha256(p).unwrap()
    }

    #[test]
    fn a_rerun_recognises_the_input_however_it_is_named_now() {
        use std::os::unix::ffi::OsStrExt;
        let d = folder("rename");
        let s = suffixes();
        let out = d.join("out");
        // the first run was elsewhere: its relative input does not resolve from here
        let a = d.join("a.jpg");
        fs::write(&a, b"photo a").unwrap();
        let side = serde_json::json!({"input": "survey/in/a.jpg", "metadata": {"input_sha256": sha256_of(&a)}});
        let mut c = claimed(claim(&request(&out, "a", &a, &s, false)).unwrap());
        let temps = write_all(&mut c, &side.to_string());
        c.commit(&temps).unwrap();
        assert!(matches!(claim(&request(&out, "a", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::Done, _)));
        // another file of the same name and a sidecar naming it relatively: not ours
        let b = d.join("other").join("a.jpg");
        fs::create_dir_all(b.parent().unwrap()).unwrap();
        fs::write(&b, b"photo b").unwrap();
        let c = claimed(claim(&request(&out, "a", &b, &s, false)).unwrap());
        assert_eq!(c.name(), "a_2");
        drop(c);
        // a name that is not UTF-8, recorded with U+FFFD
        let raw = d.join(std::ffi::OsStr::from_bytes(b"caf\xe9.jpg"));
        fs::write(&raw, b"photo c").unwrap();
        let side = serde_json::json!({"input": d.join("caf\u{fffd}.jpg"), "metadata": {"input_sha256": sha256_of(&raw)}});
        let mut c = claimed(claim(&request(&out, "caf\u{fffd}", &raw, &s, false)).unwrap());
        let temps = write_all(&mut c, &side.to_string());
        c.commit(&temps).unwrap();
        assert!(matches!(claim(&request(&out, "caf\u{fffd}", &raw, &s, false)).unwrap(), Resolution::Skipped(Skip::Done, _)));
        // a recorded resolved path decides over an equal relative one
        let side = serde_json::json!({"input": "a.jpg", "input_resolved": input_key(&b)});
        fs::write(out.join("r.json"), side.to_string()).unwrap();
        let c = claimed(claim(&request(&out, "r", Path::new("a.jpg"), &s, false)).unwrap());
        assert_eq!(c.name(), "r_2");
        drop(c);
        // the same relative name in another dive (each run started in its
        // own folder): the recorded hash is the other dive's photo's
        let here = std::env::current_dir().unwrap();
        let up: PathBuf = here.components().skip(1).map(|_| "..").collect();
        let rel = up.join(b.strip_prefix("/").unwrap());
        assert!(rel.is_relative() && rel.is_file());
        let side = serde_json::json!({"input": rel, "metadata": {"input_sha256": sha256_of(&a)}});
        fs::write(out.join("dive.json"), side.to_string()).unwrap();
        let c = claimed(claim(&request(&out, "dive", &rel, &s, false)).unwrap());
        assert_eq!(c.name(), "dive_2");
        drop(c);
        // and its own photo under that relative name is recognised by its hash
        let side = serde_json::json!({"input": rel, "metadata": {"input_sha256": sha256_of(&b)}});
        fs::write(out.join("dive.json"), side.to_string()).unwrap();
        assert!(matches!(claim(&request(&out, "dive", &rel, &s, false)).unwrap(), Resolution::Skipped(Skip::Done, _)));
        // a stored input restored into the folder: its URL names it, not a hash of a local file of that name
        let url = Path::new("s3://bucket/dive/u.png");
        let side = serde_json::json!({"input": url, "metadata": {"input_sha256": sha256_of(&a)}});
        fs::write(out.join("u.json"), side.to_string()).unwrap();
        assert!(matches!(claim(&request(&out, "u", url, &s, false)).unwrap(), Resolution::Skipped(Skip::Done, _)));
        let c = claimed(claim(&request(&out, "u", Path::new("s3://bucket/other/u.png"), &s, false)).unwrap());
        assert_eq!(c.name(), "u_2");
        drop(c);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_rerun_finds_the_input_under_the_name_another_batch_gave_it() {
        let d = folder("family");
        let s = suffixes();
        let (a, b) = (d.join("d1").join("a.png"), d.join("d2").join("a.png"));
        for (p, bytes) in [(&a, b"one".as_slice()), (&b, b"two".as_slice())] {
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(p, bytes).unwrap();
        }
        let out = d.join("out");
        fs::create_dir_all(&out).unwrap();
        // a batch of both named them a_png and a_png_2
        for (name, p) in [("a_png", &a), ("a_png_2", &b)] {
            let side = serde_json::json!({"input": p, "input_resolved": input_key(p)});
            fs::write(out.join(format!("{name}.json")), side.to_string()).unwrap();
        }
        // alone, or first in a batch, each is planned as `a` or `a_png`
        let got = claim(&request(&out, "a", &b, &s, false)).unwrap();
        assert!(matches!(got, Resolution::Skipped(Skip::Done, ref p) if p.ends_with("a_png_2.json")), "{got:?}");
        let got = claim(&request(&out, "a_png", &b, &s, false)).unwrap();
        assert!(matches!(got, Resolution::Skipped(Skip::Done, ref p) if p.ends_with("a_png_2.json")), "{got:?}");
        let got = claim(&request(&out, "a_png_2", &a, &s, false)).unwrap();
        assert!(matches!(got, Resolution::Skipped(Skip::Done, ref p) if p.ends_with("a_png.json")), "{got:?}");
        // a third input of that stem is another: the next free name
        let c = d.join("d3").join("a.png");
        fs::create_dir_all(c.parent().unwrap()).unwrap();
        fs::write(&c, b"three").unwrap();
        let got = claimed(claim(&request(&out, "a_png", &c, &s, false)).unwrap());
        assert_eq!(got.name(), "a_png_3");
        drop(got);
        // a hole in the sequence (an input that failed): looked past
        let side = serde_json::json!({"input": &c, "input_resolved": input_key(&c)});
        fs::write(out.join("a_png_5.json"), side.to_string()).unwrap();
        let got = claim(&request(&out, "a", &c, &s, false)).unwrap();
        assert!(matches!(got, Resolution::Skipped(Skip::Done, ref p) if p.ends_with("a_png_5.json")), "{got:?}");
        // the same bytes as d1's photo, elsewhere: done by its contents, but
        // never redone over d1's outputs with --overwrite
        let e = d.join("d4").join("a.png");
        fs::create_dir_all(e.parent().unwrap()).unwrap();
        fs::write(&e, b"one").unwrap();
        let side = serde_json::json!({"input": &a, "input_resolved": input_key(&a), "metadata": {"input_sha256": sha256_of(&a)}});
        fs::write(out.join("a_png.json"), side.to_string()).unwrap();
        let got = claim(&request(&out, "a_png_6", &e, &s, false)).unwrap();
        assert!(matches!(got, Resolution::Skipped(Skip::Done, ref p) if p.ends_with("a_png.json")), "{got:?}");
        let got = claimed(claim(&request(&out, "a_png_6", &e, &s, true)).unwrap());
        assert_eq!(got.name(), "a_png_6");
        drop(got);
        // an input whose planned name holds its own sidecar by path stays there
        let side = serde_json::json!({"input": &e, "input_resolved": input_key(&e), "metadata": {"input_sha256": sha256_of(&e)}});
        fs::write(out.join("a_png_6.json"), side.to_string()).unwrap();
        let got = claim(&request(&out, "a_png_6", &e, &s, true)).unwrap();
        assert!(matches!(got, Resolution::Claimed(ref c) if c.name() == "a_png_6"), "{got:?}");
        drop(got);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn overwrite_redoes_the_inputs_own_name_and_keeps_foreign_files() {
        let d = folder("overwrite");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        // foreign files at a's names: a_t.png, and a.json that is no sidecar of a
        fs::write(d.join("a_t.png"), b"foreign png").unwrap();
        let first = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(first.name(), "a_2");
        let mut first = first;
        let side = serde_json::json!({"input": a, "metadata": {"input_sha256": sha256_of(&a)}}).to_string();
        let temps = write_all(&mut first, &side);
        first.commit(&temps).unwrap();
        fs::write(d.join("a.json"), b"{\"note\": \"not a sidecar of a\"}").unwrap();
        for _ in 0..2 {
            let c = claimed(claim(&request(&d, "a", &a, &s, true)).unwrap());
            assert_eq!(c.name(), "a_2");
        }
        assert_eq!(fs::read(d.join("a_t.png")).unwrap(), b"foreign png");
        assert_eq!(fs::read(d.join("a.json")).unwrap(), b"{\"note\": \"not a sidecar of a\"}");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_stale_claim_of_another_input_does_not_hand_over_the_users_files() {
        let d = folder("stale-other");
        let s = suffixes();
        let x = d.join("x.jpg");
        fs::write(&x, b"photo").unwrap();
        fs::write(d.join("x_t.png"), b"the user's own").unwrap();
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("x")));
        fs::write(&claim_file, format!("4194399\nx\n{}\n", d.join("elsewhere.jpg").display())).unwrap();
        let c = claimed(claim(&request(&d, "x", &x, &s, false)).unwrap());
        assert_eq!(c.name(), "x_2");
        drop(c);
        assert_eq!(fs::read(d.join("x_t.png")).unwrap(), b"the user's own");
        // the same stale claim naming this input: its run's half-commit is replaced
        fs::write(&claim_file, format!("4194399\nx\n{}\n", input_key(&x).display())).unwrap();
        let c = claimed(claim(&request(&d, "x", &x, &s, false)).unwrap());
        assert_eq!(c.name(), "x");
        drop(c);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_dead_runs_recorded_leftovers_go_when_its_claim_is_taken_over() {
        // a run of a.jpg with --format png killed mid-commit: its a.png and
        // a_t.png are in place, its sidecar is not, and its claim names what
        // it may have left. The rerun (jpg: .jpg, _t.png) takes the name over
        // and removes a.png, which it does not write; a name that leaves the
        // folder is never followed
        let d = folder("left");
        let s: Vec<String> = vec![".jpg".into(), "_t.png".into()];
        let a = d.join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        fs::write(d.join("a.png"), b"dead run's image").unwrap();
        fs::write(d.join("a_t.png"), b"dead run's map").unwrap();
        // the user's own and another input's files, named by the dead claim too
        for n in ["notes.txt", "b_t.png", "ab.png", ".uwhl-claim-0"] {
            fs::write(d.join(n), b"not this input's").unwrap();
        }
        let outside = d.parent().unwrap().join(format!("uwhl-left-outside-{}.png", std::process::id()));
        fs::write(&outside, b"not the folder's").unwrap();
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("a")));
        let dead = |holder: &Path| {
            let mut r = format!("4194399\na\n{}\n", holder.display()).into_bytes();
            for n in ["a.png", "a_t.png", "a.json", "../", "..", "", "notes.txt", "b_t.png", "ab.png", ".uwhl-claim-0"] {
                r.extend_from_slice(format!("\nleft {n}").as_bytes());
            }
            r.extend_from_slice(format!("\nleft ../{}", outside.file_name().unwrap().to_string_lossy()).as_bytes());
            r
        };
        // a dead claim of another input: its names are not this input's to remove
        fs::write(&claim_file, dead(&d.join("other.jpg"))).unwrap();
        let c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(c.name(), "a_2");
        drop(c);
        assert!(d.join("a.png").exists());
        // a dead claim of this input
        fs::write(&claim_file, dead(&input_key(&a))).unwrap();
        let mut c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(c.name(), "a");
        let side = serde_json::json!({"input": a, "outputs": {"image": "a.jpg", "transmission": "a_t.png"}}).to_string();
        let temps = write_all(&mut c, &side);
        c.commit(&temps).unwrap();
        assert!(!d.join("a.png").exists(), "the dead run's image in another format stays unlisted");
        assert!(d.join("a.jpg").exists() && d.join("a.json").exists());
        assert_ne!(fs::read(d.join("a_t.png")).unwrap(), b"dead run's map");
        assert_eq!(fs::read(&outside).unwrap(), b"not the folder's");
        for n in ["notes.txt", "b_t.png", "ab.png", ".uwhl-claim-0"] {
            assert_eq!(fs::read(d.join(n)).unwrap(), b"not this input's", "{n}");
        }
        fs::remove_file(&outside).unwrap();
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_commit_records_what_it_may_leave_before_it_touches_the_folder() {
        let d = folder("record-left");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        let c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        let paths = c.paths().to_vec();
        c.record_left(paths.iter()).unwrap();
        let names = read_left(&File::open(d.join(format!(".uwhl-claim-{:016x}", name_hash("a")))).unwrap());
        assert_eq!(names, vec!["a.png", "a_t.png", "a.json"]);
        // the record's own lines still say whose it is
        let f = File::open(d.join(format!(".uwhl-claim-{:016x}", name_hash("a")))).unwrap();
        assert_eq!(read_record(&f).map(|r| (r.0, r.2)), Some((std::process::id(), input_key(&a))));
        drop(c);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn takers_of_a_dead_runs_claim_racing_each_other_claim_it_once() {
        // several takers over one planted dead claim: were each to see it
        // dead, remove it and make its own, two would both restore the
        // input (a claim file is locked by its owner for its life: a dead
        // owner's lock is gone by the kernel's word, a live one's is not)
        let d = folder("stale-race");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        let key = input_key(&a);
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("a")));
        for round in 0..40 {
            fs::write(&claim_file, format!("4194399\na\n{}\n", key.display())).unwrap();
            let gate = std::sync::Arc::new(std::sync::Barrier::new(6));
            let takers: Vec<_> = (0..6)
                .map(|_| {
                    let (dd, aa, ss, gate) = (d.clone(), a.clone(), s.clone(), gate.clone());
                    std::thread::spawn(move || {
                        gate.wait();
                        claim(&Request { dir: &dd, base: "a", input: &aa, suffixes: &ss, overwrite: false, rename: true })
                    })
                })
                .collect();
            let got: Vec<_> = takers.into_iter().map(|t| t.join().unwrap().unwrap()).collect();
            let claimed: Vec<_> = got.iter().filter(|r| matches!(r, Resolution::Claimed(_))).collect();
            assert_eq!(claimed.len(), 1, "round {round}: {got:?}");
            for r in &got {
                match r {
                    Resolution::Claimed(c) => assert_eq!(c.name(), "a"),
                    Resolution::Skipped(Skip::Busy(_) | Skip::InFlight, _) => {}
                    other => panic!("round {round}: {other:?}"),
                }
            }
            drop(got);
            assert!(!claim_file.exists(), "round {round}: the winner's claim outlived it");
        }
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_claim_held_but_not_yet_readable_is_not_taken_for_abandoned() {
        // a claim its owner has locked but not yet written (an owner that
        // stalled between the two): busy, however long it stays empty
        let d = folder("held-empty");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"photo").unwrap();
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("a")));
        let held = File::create(&claim_file).unwrap();
        held.try_lock().unwrap();
        let r = claim(&request(&d, "a", &a, &s, false));
        assert!(claim_file.exists() && fs::read(&claim_file).unwrap().is_empty());
        assert!(r.is_err() || matches!(r, Ok(Resolution::Skipped(Skip::Busy(_), _))), "{r:?}");
        // once its owner is gone (the lock with it), it is taken over
        drop(held);
        let c = claimed(claim(&request(&d, "a", &a, &s, false)).unwrap());
        assert_eq!(c.name(), "a");
        drop(c);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_socket_at_the_claim_name_is_no_claim_and_a_claim_is_readable_by_all() {
        let d = folder("sock-claim");
        let s = suffixes();
        let x = d.join("x.jpg");
        fs::write(&x, b"photo").unwrap();
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("x")));
        let _sock = std::os::unix::net::UnixListener::bind(&claim_file).unwrap();
        let c = claimed(claim(&request(&d, "x", &x, &s, false)).unwrap());
        use std::os::unix::fs::PermissionsExt;
        // whatever the umask: another user's run can read and lock it
        assert_eq!(fs::metadata(&claim_file).unwrap().permissions().mode() & 0o777, 0o644);
        drop(c);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_dead_runs_claim_that_cannot_be_removed_fails_the_input_once() {
        // a claim that cannot be removed (here a folder at its name; on a
        // read-only mount, a dead run's file) was retried for ever: the run
        // spun at full CPU. Now the input fails (or is skipped, done) at once.
        let d = folder("stuck-claim");
        let s = suffixes();
        let x = d.join("x.jpg");
        fs::write(&x, b"photo").unwrap();
        fs::create_dir(d.join(format!(".uwhl-claim-{:016x}", name_hash("x")))).unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let (dd, xx, ss) = (d.clone(), x.clone(), s.clone());
        std::thread::spawn(move || {
            let r = claim(&Request { dir: &dd, base: "x", input: &xx, suffixes: &ss, overwrite: false, rename: false });
            let _ = tx.send(r.map(|_| ()).map_err(|e| e.kind()));
        });
        let got = rx.recv_timeout(std::time::Duration::from_secs(20)).expect("the claim never returned");
        assert!(got.is_err(), "{got:?}");
        fs::remove_dir_all(&d).unwrap();
    }
}
