//! Discovery and naming of a batch's inputs, one implementation for both
//! commands (docs/CLI.md, docs/OUTPUTS.md): files as given, folders walked
//! recursively in name order, the output folder never searched, the same
//! file taken once, and output names that never collide. `uwhl restore`
//! expands its glob patterns, then calls this through `uwhl_rs._core`.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

/// Extensions taken when walking a folder (case-insensitive).
pub const IMAGE_EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "tif", "tiff"];

/// Raw extensions (those the Python command reads through LibRaw): taken
/// when walking a folder, so that output names agree with the Python
/// command, and refused with an input error here.
pub const RAW_EXTENSIONS: [&str; 46] = [
    "3fr", "ari", "arw", "bay", "braw", "cap", "cr2", "cr3", "crw", "cs1", "dc2", "dcr", "dcs",
    "dng", "drf", "eip", "erf", "fff", "gpr", "iiq", "k25", "kdc", "mdc", "mef", "mos", "mrw",
    "nef", "nrw", "orf", "ori", "pef", "ptx", "pxn", "qtk", "r3d", "raf", "raw", "rdc", "rw2",
    "rwl", "rwz", "sr2", "srf", "srw", "sti", "x3f",
];

/// Video extensions (the Python command reads them through FFmpeg, PyAV):
/// taken when walking a folder, so that output names agree between the
/// commands, and refused with an input error by the binary, which restores
/// a video's frames piped in (`--raw-frames`).
pub const VIDEO_EXTENSIONS: [&str; 21] = [
    "mp4", "m4v", "mov", "mkv", "avi", "mts", "m2ts", "ts", "webm", "mxf", "mpg", "mpeg", "wmv", "3gp", "flv", "ogv", "asf",
    // raw streams of the codecs whose demuxers are allowed (docs/OUTPUTS.md "Videos")
    "h264", "264", "hevc", "h265",
];

/// The lower-case extension of `p` ("" for none).
pub fn extension(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Whether a folder walk takes `p` (an image, raw or video extension).
pub fn supported(p: &Path) -> bool {
    let ext = extension(p);
    let e = ext.as_str();
    IMAGE_EXTENSIONS.contains(&e) || RAW_EXTENSIONS.contains(&e) || VIDEO_EXTENSIONS.contains(&e)
}

/// Ok when `path` is a regular file (after symlinks); else why it is
/// refused. FIFOs, sockets and devices are never opened: opening a FIFO
/// blocks until a writer comes.
pub fn regular_file(path: &Path) -> Result<(), String> {
    match fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(m) if m.is_dir() => Err("is a folder".into()),
        Ok(_) => Err("is not a regular file (a FIFO, socket or device): not opened".into()),
        Err(e) => Err(missing_said(&e)),
    }
}

/// Why a path cannot be looked at, in the words of the commands: "no such
/// file or folder" when it is not there, else what the system says (a loop
/// of symbolic links, a name too long, a file used as a folder, no
/// permission) without its error number.
pub fn missing_said(e: &std::io::Error) -> String {
    if e.kind() == std::io::ErrorKind::NotFound {
        return "no such file or folder".into();
    }
    let text = e.to_string();
    let text = text.split(" (os error").next().unwrap_or(&text).to_string();
    // the system's words start with a capital: the line reads "x.npy: too many levels ..."
    let mut c = text.chars();
    c.next().map_or(text.clone(), |f| f.to_lowercase().chain(c).collect())
}

/// Whether a process runs (`/proc/PID`); without `/proc` (no way to tell)
/// every process is taken to run, so nothing of another is removed or
/// taken over.
pub fn process_runs(pid: u32) -> bool {
    !Path::new("/proc/self").exists() || Path::new("/proc").join(pid.to_string()).exists()
}

/// When process `pid` started, in clock ticks since boot (`/proc/PID/stat`,
/// field 22), or None when that cannot be read. With the pid it names one
/// process: a pid is reused (after a reboot, or a busy machine's wrap), a
/// start time with it is not.
pub fn process_start(pid: u32) -> Option<u64> {
    let stat = fs::read_to_string(Path::new("/proc").join(pid.to_string()).join("stat")).ok()?;
    // the command name (field 2) is in parentheses and may hold spaces and ')': fields 3.. follow the last ')'
    let rest = stat.get(stat.rfind(')')? + 1..)?;
    rest.split_whitespace().nth(19)?.parse().ok()
}

/// Whether the process that recorded itself as `pid` (and, when it did,
/// its start time `start`) still runs: a live process of that pid that
/// started at another time is another process.
pub fn process_is(pid: u32, start: Option<u64>) -> bool {
    if !process_runs(pid) {
        return false;
    }
    match (start, process_start(pid)) {
        (Some(then), Some(now)) => then == now,
        // no start recorded (a claim of an older build), or none readable: the pid alone decides
        _ => true,
    }
}

/// Removes from `dir` the temporary files (`.uwhl-PID-...`, the names both
/// commands write through) of processes that no longer run: what a killed
/// run left. Those of a live process (a concurrent run) stay. Returns how
/// many were removed; without `/proc` (no way to tell) none.
///
/// Only when no other run holds the output folder `gate` (every run holds
/// it with a shared `flock` while it runs, [`hold_folder`]): a run in
/// another pid namespace (a container sharing the folder) has pids this
/// process cannot see, and its live temporaries would be taken for a dead
/// run's. What a killed run left is then swept by the next run that finds
/// the folder to itself. Call it before this process takes its own hold.
pub fn remove_stale_temps(dir: &Path, gate: &Path) -> usize {
    let alone = fs::File::open(gate).map(|f| !matches!(f.try_lock(), Err(fs::TryLockError::WouldBlock)));
    if alone.is_ok_and(|a| !a) {
        return 0;
    }
    let Ok(rd) = fs::read_dir(dir) else { return 0 };
    let own = std::process::id();
    let mut removed = 0;
    for e in rd.flatten() {
        let Some(pid) = temp_owner(&e.file_name()) else { continue };
        if pid == own || process_runs(pid) {
            continue;
        }
        if e.file_type().is_ok_and(|t| t.is_file()) && fs::remove_file(e.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// Removes from `dir` this process's own temporary files (`.uwhl-PID-...`
/// of its pid): what a run ended by a signal leaves otherwise until the
/// next run sweeps it ([`remove_stale_temps`]). Returns how many.
pub fn remove_own_temps(dir: &Path) -> usize {
    let own = std::process::id();
    let Ok(rd) = fs::read_dir(dir) else { return 0 };
    rd.flatten()
        .filter(|e| temp_owner(&e.file_name()) == Some(own))
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()) && fs::remove_file(e.path()).is_ok())
        .count()
}

/// The pid a temporary file's name (`.uwhl-PID-N.tmp...`, as
/// `commit::create_temp` makes them) says made it; None for any other name.
fn temp_owner(name: &std::ffi::OsStr) -> Option<u32> {
    let rest = name.to_str()?.strip_prefix(".uwhl-")?;
    rest.contains(".tmp").then_some(())?;
    rest.split('-').next()?.parse().ok()
}

/// The output folders this process's runs hold, each with the identity
/// (device, inode) its folder had when the run took it.
static HELD: std::sync::Mutex<Vec<(PathBuf, (u64, u64))>> = std::sync::Mutex::new(Vec::new());

/// An output folder a run holds, remembered with its identity for as long
/// as this is kept: a write at or below it is refused once its path names
/// another folder ([`outdir_moved`]).
#[derive(Debug)]
pub struct Mark {
    /// the entry of [`HELD`] this remembers; None when the folder's
    /// identity could not be read
    entry: Option<(PathBuf, (u64, u64))>,
}

impl Mark {
    /// Remembers `dir` as a held output folder, with the identity of
    /// `file` (that folder, opened).
    pub fn new(dir: &Path, file: &fs::File) -> Self {
        use std::os::unix::fs::MetadataExt;
        let entry = file.metadata().ok().map(|m| (dir.to_path_buf(), (m.dev(), m.ino())));
        if let (Some(e), Ok(mut held)) = (&entry, HELD.lock()) {
            held.push(e.clone());
        }
        Self { entry }
    }
}

impl Drop for Mark {
    /// Forgets its own entry: two runs of one process may hold one path as
    /// two folders (one taken before a swap, one after).
    fn drop(&mut self) {
        if let (Some(e), Ok(mut held)) = (&self.entry, HELD.lock()) {
            if let Some(i) = held.iter().position(|x| x == e) {
                held.remove(i);
            }
        }
    }
}

/// An output folder held for a run ([`enter_folder`]): its shared `flock`
/// for as long as this is kept, and its [`Mark`].
#[derive(Debug)]
pub struct Held {
    /// the open folder, its shared `flock` taken
    pub file: fs::File,
    _mark: Mark,
}

/// Why nothing may be written at `path` now: it is at or below an output
/// folder a run holds, and that folder's name now leads elsewhere (the
/// folder moved, or a link was put in its place: its files would land in
/// another folder). Checked before each input's names are claimed, before
/// its outputs are renamed into place, and before each summary row; a
/// swap between the check and the write is not seen.
pub fn outdir_moved(path: &Path) -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    let held = HELD.lock().ok()?;
    held.iter().filter(|(d, _)| path.starts_with(d)).find_map(|(d, id)| match fs::metadata(d) {
        Ok(m) if (m.dev(), m.ino()) == *id => None,
        _ => Some(format!(
            "the output folder {} was moved or replaced during the run (a link put in its place?): nothing more is written there",
            d.display()
        )),
    })
}

/// The output folder `dir` held with a shared `flock` for as long as the
/// returned file is kept: other runs then know this one is there (see
/// [`remove_stale_temps`]). None when it cannot be opened or locked.
pub fn hold_folder(dir: &Path) -> Option<fs::File> {
    hold_folder_waiting(dir, &mut || {})
}

/// [`hold_folder`], saying so through `waiting` (once) when the folder's
/// lock is not had within two seconds ([`lock_shared_waiting`]).
pub fn hold_folder_waiting(dir: &Path, waiting: &mut dyn FnMut()) -> Option<fs::File> {
    let f = fs::File::open(dir).ok()?;
    lock_shared_waiting(&f, waiting).then_some(f)
}

/// Takes a shared `flock` of `f`. The runs' own exclusive locks of a
/// folder are only ever tried and let go at once, so a lock that keeps it
/// from being had for two seconds is some other program's (`flock -x
/// OUTDIR ...`): `waiting` is called once to say so, and the lock is then
/// waited for. Going on without it would let a run that starts when the
/// other program lets go take the folder for its own and start summary.csv
/// afresh over this run's rows. False if the lock cannot be taken at all
/// (a file system without locks).
pub fn lock_shared_waiting(f: &fs::File, waiting: &mut dyn FnMut()) -> bool {
    if lock_shared_within(f) {
        return true;
    }
    waiting();
    f.lock_shared().is_ok()
}

/// Takes a shared `flock` of `f`, trying for at most two seconds; false
/// if it is not had by then (or cannot be taken).
pub fn lock_shared_within(f: &fs::File) -> bool {
    let until = std::time::Instant::now() + std::time::Duration::from_secs(2);
    loop {
        match f.try_lock_shared() {
            Ok(()) => return true,
            Err(fs::TryLockError::WouldBlock) if std::time::Instant::now() < until => {
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            Err(_) => return false,
        }
    }
}

/// A run writing into `dir` starts: the folder is made if it is missing
/// (a folder made at the first output would not be held while that
/// output's temporaries are written, and a run in another pid namespace
/// starting then could sweep them), what killed runs left there is swept
/// ([`remove_stale_temps`], while this run does not hold it yet), then the
/// folder is held for the run ([`hold_folder`]; keep what this returns).
/// A folder that cannot be made is the error returned (a pipe of frames
/// would otherwise restore each frame to fail its write).
/// `waiting` is called if another program's lock keeps the folder
/// ([`lock_shared_waiting`]).
pub fn enter_folder(dir: &Path, waiting: &mut dyn FnMut()) -> Result<Option<Held>, String> {
    make_folder(dir)?;
    remove_stale_temps(dir, dir);
    Ok(hold_folder_waiting(dir, waiting).map(|file| Held { _mark: Mark::new(dir, &file), file }))
}

/// The note said while another program's lock keeps the output folder `dir`.
pub fn waiting_note(dir: &Path) -> String {
    format!("{}: another program holds a lock on this folder (flock); waiting for it to let go", dir.display())
}

/// Why the output folder `dir` cannot take outputs before anything is
/// read: something that is not a folder (a file, a FIFO) is at its name.
/// A missing folder is fine (it is made when the run starts, [`enter_folder`]).
pub fn outdir_problem(dir: &Path) -> Option<String> {
    match fs::metadata(dir) {
        Ok(m) if !m.is_dir() => Some("not a folder (a file is there): the outputs need a folder".into()),
        // a link to nothing: the folder cannot be made at its name, nor written through it
        Err(_) if fs::symlink_metadata(dir).is_ok_and(|m| m.file_type().is_symlink()) => {
            Some("a link to nothing (its target does not exist): the outputs need a folder".into())
        }
        // the folder would be made below something that cannot hold it
        Err(_) => dir.ancestors().skip(1).filter(|a| !a.as_os_str().is_empty()).find_map(|a| match fs::metadata(a) {
            Ok(m) if !m.is_dir() => Some(format!("{} is not a folder (a file is there): the outputs need a folder", a.display())),
            Ok(_) => None,
            Err(_) if fs::symlink_metadata(a).is_ok_and(|m| m.file_type().is_symlink()) => Some(format!(
                "{} is a link to nothing (its target does not exist): the output folder cannot be made below it",
                a.display()
            )),
            Err(_) => None,
        }),
        _ => None,
    }
}

/// One input and where its outputs go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    /// the input path as given (or as found under a given folder)
    pub input: PathBuf,
    /// the output folder of this input
    pub dir: PathBuf,
    /// the output base name (`NAME`)
    pub name: String,
}

/// Whether `dir` is an output folder of `uwhl restore` or `uwhl-rs restore`:
/// it holds a regular `summary.csv` whose first line begins with the
/// summary's first six columns (those every version wrote). Only its first
/// 4 KiB are read.
pub fn is_output_folder(dir: &Path) -> bool {
    use std::io::Read;
    let p = dir.join(crate::files::summary::FILE_NAME);
    if !fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut head = Vec::with_capacity(4096);
    let Ok(f) = fs::File::open(&p) else { return false };
    if f.take(4096).read_to_end(&mut head).is_err() {
        return false;
    }
    let columns = crate::files::summary::columns();
    let first = format!("{},", columns.get(..6).unwrap_or_default().join(","));
    head.starts_with(first.as_bytes())
}

fn walk(
    dir: &Path,
    rel: &Path,
    skip: &Path,
    found: &mut Vec<(PathBuf, PathBuf)>,
    notes: &mut Vec<String>,
) -> Result<(), String> {
    let rd = fs::read_dir(dir).map_err(|e| format!("cannot list {}: {e}", dir.display()))?;
    let mut entries: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        let Some(fname) = p.file_name().map(|f| f.to_os_string()) else {
            continue;
        };
        if fname.to_string_lossy().starts_with('.') {
            continue;
        }
        if p.is_dir() {
            // the output folder is never searched (nor are symlink cycles followed twice)
            if fs::canonicalize(&p).is_ok_and(|c| c == skip) {
                continue;
            }
            if fs::symlink_metadata(&p).is_ok_and(|m| m.file_type().is_symlink()) {
                continue;
            }
            // an earlier run's outputs (restored photos, t maps) are not photos to restore again
            if is_output_folder(&p) {
                notes.push(format!(
                    "{}: an output folder of an earlier restore (its summary.csv): not searched; name its files to \
                     restore them",
                    p.display()
                ));
                continue;
            }
            walk(&p, &rel.join(&fname), skip, found, notes)?;
        } else if supported(&p) && p.is_file() {
            found.push((p, rel.to_path_buf()));
        }
    }
    Ok(())
}

/// The jobs of a batch, named as the Python command names them: files as
/// given, folders walked recursively (sorted, hidden entries and the output
/// folder skipped, JPEG/PNG/TIFF and raw extensions taken), outputs in
/// `outdir/<path relative to the folder>/`. The same file given twice is
/// processed once; files under `outdir` are never inputs. Inputs that would
/// share a `NAME` in one folder get `NAME_ext` (lower-case extension), then
/// `NAME_ext_2`, ...; an input one of whose output files (`NAME` + each of
/// `suffixes`, and `NAME.json`) is another input's output file gets
/// `NAME_2`, ... (inputs `a.jpg` and `a_t.jpg` written as PNG: `a_t.png` is
/// a's transmission, so the second is `a_t_2`). A folder met in a walk
/// that is an earlier run's output folder ([`is_output_folder`]) is not
/// searched. Returns the jobs, the inputs that matched nothing, and notes
/// (the folders not searched).
pub fn collect_jobs(
    inputs: &[PathBuf],
    outdir: &Path,
    suffixes: &[String],
) -> (Vec<Job>, Vec<(PathBuf, String)>, Vec<String>) {
    let out_real = fs::canonicalize(outdir).unwrap_or_else(|_| outdir.to_path_buf());
    let mut found: Vec<(PathBuf, PathBuf)> = Vec::new();
    let mut errors = Vec::new();
    let mut notes = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let before = found.len();
            match walk(input, Path::new(""), &out_real, &mut found, &mut notes) {
                Err(e) => errors.push((input.clone(), e)),
                Ok(()) if found.len() == before => {
                    errors.push((input.clone(), "folder holds no JPEG, PNG, TIFF, raw or video file".into()))
                }
                Ok(()) => {}
            }
        } else {
            match regular_file(input) {
                Ok(()) => found.push((input.clone(), PathBuf::new())),
                Err(why) => errors.push((input.clone(), why)),
            }
        }
    }
    let mut seen = std::collections::HashSet::new();
    found.retain(|(p, _)| {
        let real = fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if real.starts_with(&out_real) {
            errors.push((p.clone(), inside_outdir(outdir)));
            return false;
        }
        seen.insert(real)
    });
    // an output subfolder that is a link (or lies under one) would put
    // its files elsewhere: its inputs fail, named, and nothing is written there
    let mut linked: BTreeMap<PathBuf, Option<PathBuf>> = BTreeMap::new();
    found.retain(|(p, rel)| {
        let link = linked.entry(rel.clone()).or_insert_with(|| linked_below(outdir, rel)).clone();
        match link {
            Some(l) => {
                errors.push((p.clone(), format!(
                    "cannot write into {}: a symbolic link inside the output folder (its files would land elsewhere); not followed",
                    l.display()
                )));
                false
            }
            None => true,
        }
    });
    let names = name_jobs(&found, suffixes);
    let jobs = found
        .into_iter()
        .zip(names)
        .map(|((p, rel), name)| Job {
            input: p,
            dir: outdir.join(&rel),
            name,
        })
        .collect();
    (jobs, errors, notes)
}

/// The first of `outdir/rel`'s folders below `outdir` that is a symbolic
/// link, None when none is (those not made yet are not).
pub fn linked_below(outdir: &Path, rel: &Path) -> Option<PathBuf> {
    let mut at = outdir.to_path_buf();
    for part in rel.components() {
        at.push(part);
        match fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => return Some(at),
            Ok(_) => {}
            Err(_) => return None,
        }
    }
    None
}

/// Why a file under the output folder is not taken as an input (a batch's
/// walk and stream mode say the same).
pub fn inside_outdir(outdir: &Path) -> String {
    format!("is inside the output folder {}: not taken as an input", outdir.display())
}

/// The two bases [`name_jobs`] names an input from: its stem `S`, and
/// `S_E` (E its lowercased extension) when inputs of one folder share the
/// stem; either may then be followed by `_2`, `_3`, ...
pub fn name_bases(p: &Path) -> [String; 2] {
    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let with_ext = format!("{stem}_{}", extension(p));
    [stem, with_ext]
}

/// Makes the output folder `dir` (and its parents) if it is missing; the
/// error says the folder cannot be made.
pub fn make_folder(dir: &Path) -> Result<(), String> {
    fs::create_dir_all(dir).map_err(|e| format!("cannot make the output folder: {e}"))
}

/// The output names of a batch's inputs, given in discovery order as
/// (input, folder relative to the output folder): the naming rules of
/// [`collect_jobs`], which object-storage batches (listed by fsspec, not
/// walked here) share. Inputs that share a stem in one folder get
/// `NAME_ext`, then `NAME_ext_2`, ...; a name one of whose output files
/// (`NAME` + each of `suffixes`, and `NAME.json`) is taken gets `NAME_2`, ...
pub fn name_jobs(found: &[(PathBuf, PathBuf)], suffixes: &[String]) -> Vec<String> {
    let stem = |p: &Path| name_bases(p)[0].clone();
    let mut count: BTreeMap<(PathBuf, String), usize> = BTreeMap::new();
    for (p, rel) in found {
        *count.entry((rel.clone(), stem(p))).or_insert(0) += 1;
    }
    let mut taken = std::collections::HashSet::new();
    found
        .iter()
        .map(|(p, rel)| {
            let [s, with_ext] = name_bases(p);
            let shared = count.get(&(rel.clone(), s.clone())).copied().unwrap_or(0) > 1;
            let base = if shared { with_ext } else { s };
            let files = |name: &str| -> Vec<(PathBuf, String)> {
                suffixes
                    .iter()
                    .map(String::as_str)
                    .chain(std::iter::once(".json"))
                    .map(|s| (rel.clone(), format!("{name}{s}")))
                    .collect()
            };
            let mut name = base.clone();
            let mut k = 1;
            while files(&name).iter().any(|f| taken.contains(f)) {
                k += 1;
                name = format!("{base}_{k}");
            }
            taken.extend(files(&name));
            name
        })
        .collect()
}

/// What a run reads once from a file or a folder, by its canonical path
/// (`--water-from`'s folder, `--altitude`'s navigation log): every input of
/// the run sees the same, even when the run writes beside it; the next run
/// reads it again ([`PerRun::forget`]: a process of the binary is one run,
/// a Python process or a Dask worker serves one after another).
pub struct PerRun<T>(std::sync::OnceLock<std::sync::Mutex<std::collections::HashMap<PathBuf, T>>>);

impl<T: Clone> Default for PerRun<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Clone> PerRun<T> {
    /// An empty cache (for a `static`).
    pub const fn new() -> Self {
        Self(std::sync::OnceLock::new())
    }

    fn map(&self) -> std::sync::MutexGuard<'_, std::collections::HashMap<PathBuf, T>> {
        self.0.get_or_init(Default::default).lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// What this run read from `path`, or `read()` of it now.
    pub fn get_or_read<E>(&self, path: &Path, read: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
        let key = fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        if let Some(v) = self.map().get(&key) {
            return Ok(v.clone());
        }
        let v = read()?;
        self.map().insert(key, v.clone());
        Ok(v)
    }

    /// A new run starts: everything is read again.
    pub fn forget(&self) {
        self.map().clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty folder of the system's temporary one, its name `uwhl-TAG-PID`.
    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("uwhl-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_dangling_link_is_no_output_folder() {
        let d = scratch("dangling");
        let link = d.join("out");
        std::os::unix::fs::symlink(d.join("nowhere"), &link).unwrap();
        assert!(outdir_problem(&link).unwrap().starts_with("a link to nothing"));
        // a link to a folder is a folder; a name not there yet is made
        fs::create_dir(d.join("nowhere")).unwrap();
        assert_eq!(outdir_problem(&link), None);
        assert_eq!(outdir_problem(&d.join("new")), None);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_process_is_its_pid_and_its_start_time() {
        let own = std::process::id();
        let start = process_start(own).expect("/proc/self/stat");
        assert!(process_is(own, Some(start)) && process_is(own, None));
        // the same pid started at another time is another process
        assert!(!process_is(own, Some(start + 1)));
        assert!(!process_is(4_194_399, None) && process_start(4_194_399).is_none());
    }

    #[test]
    fn a_held_folder_moved_or_replaced_by_a_link_takes_no_more_writes() {
        let root = scratch("moved");
        let d = root.join("out");
        let held = enter_folder(&d, &mut || {}).unwrap().unwrap();
        assert_eq!(outdir_moved(&d.join("sub")), None);
        fs::rename(&d, root.join("old")).unwrap();
        fs::create_dir(root.join("elsewhere")).unwrap();
        std::os::unix::fs::symlink(root.join("elsewhere"), &d).unwrap();
        let why = outdir_moved(&d.join("sub")).unwrap();
        assert!(why.contains("was moved or replaced during the run"), "{why}");
        let suffixes = [".jpg".to_string()];
        let req = crate::files::commit::Request {
            dir: &d, base: "a", input: Path::new("/nowhere/a.png"), suffixes: &suffixes, overwrite: false, rename: true,
        };
        assert!(crate::files::commit::claim(&req).unwrap_err().to_string().contains("moved or replaced"));
        assert_eq!(fs::read_dir(root.join("elsewhere")).unwrap().count(), 0);
        // a folder no run holds is not judged
        drop(held);
        assert_eq!(outdir_moved(&d.join("sub")), None);
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_missing_output_folder_is_made_and_held_from_the_start() {
        let root = scratch("enter");
        let d = root.join("not").join("yet");
        assert!(!d.exists());
        let held = enter_folder(&d, &mut || {}).unwrap().unwrap();
        assert!(d.is_dir());
        // another run (another open file description) cannot take it alone
        let other = fs::File::open(&d).unwrap();
        assert!(matches!(other.try_lock(), Err(fs::TryLockError::WouldBlock)));
        drop(held);
        assert!(other.try_lock().is_ok());
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn stale_temporaries_of_dead_processes_go_live_ones_stay() {
        let d = scratch("stale");
        // a pid above the kernel's largest (4194304) never runs
        let dead = d.join(".uwhl-4194399-7.tmp");
        let dead_py = d.join(".uwhl-4194399-ab12cd.tmp.png");
        let live = d.join(format!(".uwhl-{}-1.tmp", std::process::id()));
        let other = d.join(".uwhl-notes");
        for p in [&dead, &dead_py, &live, &other] {
            fs::write(p, b"x").unwrap();
        }
        // another run holds the folder (it may be in another pid
        // namespace, its pids not ours to judge): nothing is swept
        let held = hold_folder(&d).unwrap();
        assert_eq!(remove_stale_temps(&d, &d), 0);
        assert!(dead.exists() && dead_py.exists());
        drop(held);
        assert_eq!(remove_stale_temps(&d, &d), 2);
        assert!(!dead.exists() && !dead_py.exists() && live.exists() && other.exists());
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_path_that_cannot_be_looked_at_says_why() {
        let d = scratch("why");
        std::os::unix::fs::symlink(d.join("b"), d.join("a")).unwrap();
        std::os::unix::fs::symlink(d.join("a"), d.join("b")).unwrap();
        fs::write(d.join("f"), b"x").unwrap();
        assert_eq!(regular_file(&d.join("none")).unwrap_err(), "no such file or folder");
        assert_eq!(regular_file(&d.join("a")).unwrap_err(), "too many levels of symbolic links");
        assert_eq!(regular_file(&d.join("f").join("x.npy")).unwrap_err(), "not a directory");
        assert_eq!(regular_file(&d.join("x".repeat(300))).unwrap_err(), "file name too long");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn names_never_collide_and_the_output_folder_is_never_an_input() {
        let d = std::env::temp_dir().join(format!("uwhl-names-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        for f in ["in/a/x.png", "in/a/x.JPG", "in/b/y.tif", "in/b/.hidden.png", "in/b/notes.txt", "in/raw.NEF", "out/old.png"] {
            let p = d.join(f);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(&p, b"").unwrap();
        }
        let out = d.join("out");
        // a FIFO named like an image, given and in a walked folder: refused, never opened
        let fifo = d.join("in/b/pipe.jpg");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let inputs = [d.join("in"), d.join("in/a/x.png"), d.join("in/raw.NEF"), d.join("out/old.png"), d.join("none.png")];
        let suffixes = [".png".to_string(), "_t.png".into()];
        let (jobs, errors, notes) = collect_jobs(&inputs, &out, &suffixes);
        assert!(notes.is_empty());
        let got: Vec<(String, String)> = jobs
            .iter()
            .map(|j| (j.dir.strip_prefix(&out).unwrap().display().to_string(), j.name.clone()))
            .collect();
        let want = [("a", "x_jpg"), ("a", "x_png"), ("b", "y"), ("", "raw")];
        assert_eq!(got, want.map(|(a, b)| (a.to_string(), b.to_string())));
        assert_eq!(errors.len(), 2, "{errors:?}");
        assert!(errors[0].0.ends_with("none.png") && errors[0].1 == "no such file or folder");
        assert!(errors[1].0.ends_with("out/old.png") && errors[1].1.contains("inside the output folder"));
        let (jobs, errors, _) = collect_jobs(std::slice::from_ref(&fifo), &out, &suffixes);
        assert!(jobs.is_empty() && errors.len() == 1 && errors[0].1.contains("FIFO"), "{errors:?}");
        // outputs of different roles never share a file: a_t.png is a's transmission
        for f in ["in2/a.jpg", "in2/a_t.jpg", "in2/a_t_2.jpg"] {
            let p = d.join(f);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(&p, b"").unwrap();
        }
        let (jobs, _, _) = collect_jobs(&[d.join("in2")], &out, &suffixes);
        let names: Vec<&str> = jobs.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["a", "a_t_2", "a_t_2_2"]);
        let (jobs, _, _) = collect_jobs(&[d.join("in2")], &out, &[".jpg".to_string(), "_t.png".into()]);
        let names: Vec<&str> = jobs.iter().map(|j| j.name.as_str()).collect();
        // as JPEG: a_t.jpg's own image is a_t.jpg, no output of a; a_t's _t.png is a_t_t.png
        assert_eq!(names, ["a", "a_t", "a_t_2"]);
        // an earlier run's output folder inside the input folder: not searched, said in a note;
        // a summary.csv of another program, or a folder given itself, is searched as before
        for f in ["in3/p.jpg", "in3/old/p.jpg", "in3/old/p_t.png", "in3/other/q.jpg"] {
            let p = d.join(f);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(&p, b"").unwrap();
        }
        fs::write(d.join("in3/old/summary.csv"), format!("{}\n", crate::files::summary::columns().join(","))).unwrap();
        fs::write(d.join("in3/other/summary.csv"), "name,value\n").unwrap();
        let (jobs, errors, notes) = collect_jobs(&[d.join("in3")], &out, &suffixes);
        let inputs: Vec<String> = jobs.iter().map(|j| j.input.strip_prefix(&d).unwrap().display().to_string()).collect();
        assert_eq!(inputs, ["in3/other/q.jpg", "in3/p.jpg"]);
        assert!(errors.is_empty() && notes.len() == 1 && notes[0].contains("in3/old: an output folder"), "{notes:?}");
        let (jobs, _, notes) = collect_jobs(&[d.join("in3/old")], &out, &suffixes);
        assert_eq!(jobs.len(), 2);
        assert!(notes.is_empty());
        fs::remove_dir_all(&d).unwrap();
    }
}
