//! How one input's outputs reach the output folder, one implementation for
//! both commands (docs/OUTPUTS.md, "What a reader may find"):
//!
//! 1. [`claim`] picks the name the outputs are written under and claims it:
//!    a claim file `.uwhl-claim-HASH` made exclusively, naming the process
//!    and the input, so a second process on the same folder skips what the
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
//! file. A claim file whose process no longer runs (kill -9, power cut) is
//! stale: the next run takes the name over and replaces the outputs that
//! run may have renamed in without their sidecar.

use std::collections::HashMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// The most names tried for one input (`NAME`, `NAME_2`, ...).
const MAX_NAMES: usize = 10_000;

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
    temps: Vec<PathBuf>,
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

/// The `input` recorded in a sidecar; None if it cannot be read.
fn sidecar_input(path: &Path) -> Option<PathBuf> {
    let text = fs::read(path).ok()?;
    let v: serde_json::Value = serde_json::from_slice(&text).ok()?;
    v.get("input")?.as_str().map(PathBuf::from)
}

/// The pid and input a claim file names.
fn read_claim(path: &Path) -> Option<(u32, PathBuf)> {
    let mut s = String::new();
    File::open(path).ok()?.read_to_string(&mut s).ok()?;
    let mut lines = s.lines();
    let pid = lines.next()?.parse().ok()?;
    let _name = lines.next()?;
    Some((pid, PathBuf::from(lines.next()?)))
}

fn in_flight<T>(f: impl FnOnce(&mut HashMap<PathBuf, PathBuf>) -> T) -> T {
    let mut g = IN_FLIGHT.lock().unwrap_or_else(PoisonError::into_inner);
    f(g.get_or_insert_with(HashMap::new))
}

/// Syncs a folder, so that the renames into it survive a power cut.
fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}

/// Creates `.uwhl-PID-N.tmp{ext}` beside `dir`'s outputs, exclusively
/// (`O_EXCL`: a file or link planted at that name is never opened, so a
/// link cannot redirect the write), under a short name that fits whatever
/// the output's length. `ext` (e.g. `.png`) tells format-by-name writers
/// what to write.
pub fn create_temp(dir: &Path, ext: &str) -> io::Result<(PathBuf, File)> {
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

/// Claims a name for `req.input`'s outputs (see the module documentation).
/// Tries `NAME`, then (with `rename`) `NAME_2`, ... until one is free or
/// holds this input's own sidecar. Errors: the folder cannot be created or
/// written, or (without `rename`) another process holds the name.
pub fn claim(req: &Request<'_>) -> io::Result<Resolution> {
    fs::create_dir_all(req.dir)?;
    let key = input_key(req.input);
    let own = std::process::id();
    let tries = if req.rename { MAX_NAMES } else { 1 };
    for k in 1..=tries {
        let name = if k == 1 { req.base.to_string() } else { format!("{}_{k}", req.base) };
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
        let mut stale = false;
        // true once this process holds the claim file; false when another
        // live process holds it for another input
        let owned = loop {
            match OpenOptions::new().write(true).create_new(true).open(&claim_file) {
                Ok(mut f) => {
                    writeln!(f, "{own}\n{name}\n{}", key.display())?;
                    break true;
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => match read_claim(&claim_file) {
                    Some((pid, holder)) if pid != own && crate::files::jobs::process_runs(pid) => {
                        if holder == key {
                            return Ok(Resolution::Skipped(Skip::Busy(pid), sidecar));
                        }
                        if !req.rename {
                            return Err(io::Error::other(format!(
                                "{} is being written by process {pid}",
                                sidecar.display()
                            )));
                        }
                        break false;
                    }
                    // the claim of a process that no longer runs (or an
                    // earlier one with this process's pid): taken over
                    Some(_) => {
                        stale = true;
                        let _ = fs::remove_file(&claim_file);
                    }
                    None => {
                        // a claim being written this instant, or one cut short by a crash
                        std::thread::sleep(std::time::Duration::from_millis(20));
                        if read_claim(&claim_file).is_none() {
                            stale = true;
                            let _ = fs::remove_file(&claim_file);
                        }
                    }
                },
                Err(e) => return Err(e),
            }
        };
        if !owned {
            continue;
        }
        let release = |claim_file: &Path| {
            let _ = fs::remove_file(claim_file);
        };
        if sidecar.exists() {
            let mine = sidecar_input(&sidecar).is_some_and(|i| i == req.input || input_key(&i) == key);
            if mine && !req.overwrite {
                release(&claim_file);
                return Ok(Resolution::Skipped(Skip::Done, sidecar));
            }
            if !mine && req.rename {
                // another input's outputs (another camera's frame.jpg): never replaced
                release(&claim_file);
                continue;
            }
        } else if req.rename && !req.overwrite && !stale && paths.iter().any(|p| fs::symlink_metadata(p).is_ok()) {
            // unrelated files at this name, not left by a killed run of ours
            release(&claim_file);
            continue;
        }
        in_flight(|m| {
            for p in &paths {
                m.insert(p.clone(), key.clone());
            }
        });
        return Ok(Resolution::Claimed(Claim {
            dir: req.dir.to_path_buf(),
            name,
            paths,
            claim_file,
            temps: Vec::new(),
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

    /// Puts the written temporaries (one per path, in the order of
    /// [`Claim::paths`], each made by [`Claim::temp`]) in place: syncs
    /// them, removes an earlier sidecar, renames the outputs, syncs the
    /// folder, renames the sidecar, syncs the folder. On an error the
    /// outputs renamed so far are removed (there is no sidecar then, so
    /// the next run redoes the input).
    pub fn commit(self, temps: &[PathBuf]) -> io::Result<()> {
        if temps.len() != self.paths.len() || !temps.iter().all(|t| self.temps.contains(t)) {
            return Err(io::Error::other("commit needs one temporary of this claim per output"));
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
        match fs::remove_file(sidecar) {
            Ok(()) => sync_dir(&self.dir)?,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
        let mut renamed = Vec::new();
        let result = (|| {
            for (t, p) in output_temps.iter().zip(outputs) {
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
        let c = claimed(claim(&request(&d, "x", &d.join("x.jpg"), &s, true)).unwrap());
        assert_eq!(c.name(), "x");
        drop(c);
        assert_eq!(fs::read(d.join("x_t.png")).unwrap(), b"mine");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_live_claim_of_another_process_makes_the_input_busy_a_dead_one_is_taken_over() {
        let d = folder("busy");
        let s = suffixes();
        let a = d.join("a.jpg");
        fs::write(&a, b"").unwrap();
        let key = input_key(&a);
        let claim_file = d.join(format!(".uwhl-claim-{:016x}", name_hash("a")));
        // pid 1 runs on every Linux system
        fs::write(&claim_file, format!("1\na\n{}\n", key.display())).unwrap();
        assert!(matches!(claim(&request(&d, "a", &a, &s, false)).unwrap(), Resolution::Skipped(Skip::Busy(1), _)));
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
}
