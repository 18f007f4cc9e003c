//! The binary's batch and stream loops around the per-input path of
//! `crate::files::pipeline`: the next input is read and restored while the
//! previous one's outputs are written, its line printed, summary.csv kept.

use super::args::Options;
use super::{Failure, Kind};
use crate::files::jobs::{collect_jobs, Job};
use crate::files::pipeline::{complete, load_masks, output_suffixes, prepare, sequence, Masks, Outcome, Prepared};
use crate::files::commit::Skip;
use serde_json::Value;
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, sync_channel, Receiver, SyncSender};
use std::time::Instant;

/// `text` with its control characters (C0, DEL and C1) written as `\xNN`,
/// and the line and paragraph separators and bidirectional formatting
/// characters (U+061C, U+200E, U+200F, U+2028-U+202E, U+2066-U+2069) as
/// `\uNNNN`: a line quoting a file name can neither move the cursor or
/// recolour the terminal it is printed on, nor break a line or reorder how
/// the rest of it reads. The Python command's lines go through the same
/// rule (`uwhl_rs.sidecars.printable`).
pub fn printable(text: &str) -> String {
    escaped(text, |c| {
        if c < '\u{20}' || ('\u{7f}'..='\u{9f}').contains(&c) {
            Some(format!("\\x{:02x}", c as u32))
        } else {
            invisible_order(c).then(|| format!("\\u{:04x}", c as u32))
        }
    })
}

/// `text` with each character for which `escape` gives a replacement
/// replaced by it.
fn escaped(text: &str, escape: impl Fn(char) -> Option<String>) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match escape(c) {
            Some(e) => out.push_str(&e),
            None => out.push(c),
        }
    }
    out
}

/// A JSON text (one line of `--json-errors`, `--stream` or `--raw-frames`)
/// with DEL, the C1 controls and the characters [`printable`] escapes as
/// `\\uNNNN` escapes: serde_json writes them raw, and a raw U+0085, U+2028
/// or U+2029 is a line break to many readers (Python's `str.splitlines`),
/// a raw U+202E reorders the line on a terminal. They can stand only inside
/// the text's strings, where the escape means the same character, so the
/// JSON reads back unchanged (the Python command's lines escape every
/// non-ASCII character).
pub fn json_line(text: &str) -> String {
    escaped(text, |c| (('\u{7f}'..='\u{9f}').contains(&c) || invisible_order(c)).then(|| format!("\\u{:04x}", c as u32)))
}

/// `v` as one line of JSON in the form docs/CLI.md shows and the Python
/// command writes (`", "` between items, `": "` after keys), for the error
/// objects of `--json-errors`.
pub fn spaced(v: &Value) -> String {
    match v {
        Value::Array(items) => format!("[{}]", items.iter().map(spaced).collect::<Vec<_>>().join(", ")),
        Value::Object(map) => {
            let items: Vec<String> = map.iter().map(|(k, x)| format!("{}: {}", Value::from(k.as_str()), spaced(x))).collect();
            format!("{{{}}}", items.join(", "))
        }
        // strings, numbers, booleans and null as serde_json writes them (its escapes)
        _ => v.to_string(),
    }
}

/// Line and paragraph separators and the bidirectional marks, embeddings,
/// overrides and isolates ([`printable`]).
fn invisible_order(c: char) -> bool {
    matches!(c, '\u{061c}' | '\u{200e}' | '\u{200f}' | '\u{2028}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// Reports an error on `err`: one JSON object per line with `--json-errors`,
/// else `uwhl-rs: INPUT: message` (control characters escaped, [`printable`]).
pub fn report(err: &mut dyn Write, opts_json: bool, input: Option<&Path>, e: &Failure) {
    let input_s = input.map(|p| p.to_string_lossy().into_owned());
    let _ = if opts_json {
        writeln!(err, "{}", json_line(&spaced(&e.to_json(input_s.as_deref()))))
    } else {
        let line = match input_s {
            Some(i) => format!("uwhl-rs: {i}: {e}"),
            None => format!("uwhl-rs: {e}"),
        };
        writeln!(err, "{}", printable(&line))
    };
    let _ = err.flush();
}

/// Makes `--threads N` the size of the global pool used by every step
/// (decoding, restore, encoding). Only the first call of a process counts.
pub fn init_threads(threads: Option<usize>) {
    if let Some(n) = threads {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(|i| format!("uwhl-{i}"))
            .build_global();
    }
}

/// The output folder checked before any input is read (a file at its
/// name would fail every input, and summary.csv, one by one).
pub(crate) fn outdir_usable(opts: &Options, err: &mut dyn Write) -> Result<(), u8> {
    match crate::files::jobs::outdir_problem(&opts.outdir) {
        None => Ok(()),
        Some(why) => Err(write_refused(opts, err, why)),
    }
}

/// A pipe's output folder made, swept and held for the run
/// (`crate::files::jobs::enter_folder`; keep what this returns), a note
/// said while another program's lock keeps it; the exit code when it
/// cannot be made.
pub(crate) fn enter_outdir(opts: &Options, err: &mut dyn Write) -> Result<Option<crate::files::jobs::Held>, u8> {
    let wait_note = [crate::files::jobs::waiting_note(&opts.outdir)];
    let entered = crate::files::jobs::enter_folder(&opts.outdir, &mut || say_notes(&wait_note, opts, err));
    entered.map_err(|why| write_refused(opts, err, why))
}

/// The output folder cannot take outputs (`why`): reported once, and the
/// exit code returned.
fn write_refused(opts: &Options, err: &mut dyn Write, why: String) -> u8 {
    let e = Failure::new(Kind::Write, why);
    report(err, opts.json_errors, Some(&opts.outdir), &e);
    e.kind.exit_code()
}

fn load_run_masks(opts: &Options, err: &mut dyn Write) -> Result<Masks, u8> {
    load_masks(opts).map_err(|e| {
        report(err, opts.json_errors, None, &e);
        e.kind.exit_code()
    })
}

/// The sidecars `--water-from` could not use, said once before any input.
fn dive_notes(opts: &Options, err: &mut dyn Write) {
    if let Some(d) = &opts.settings.water_from {
        say_notes(&d.notes(), opts, err);
    }
    let s = &opts.settings;
    let note = crate::files::sidecar::water_with_distance_note(
        s.water_from.is_some(),
        s.water_types.is_some(),
        s.distance.is_some(),
        s.altitude.is_some(),
    );
    if let Some(n) = note {
        say_notes(&[n], opts, err);
    }
    // this command's batches and streams are photos only
    if let Some(n) = crate::files::sidecar::transfer_note(s.transfer.is_some(), false) {
        say_notes(&[n], opts, err);
    }
}

/// A sidecar's flags, as names.
fn sidecar_flags(side: &Value) -> Vec<&str> {
    side.get("flags").and_then(Value::as_array).map(|a| a.iter().filter_map(Value::as_str).collect()).unwrap_or_default()
}

/// Remarks that are not errors, one `uwhl-rs: note:` line each on stderr
/// (none with `-q`).
fn say_notes(notes: &[String], opts: &Options, err: &mut dyn Write) {
    if !opts.quiet {
        for n in notes {
            let _ = writeln!(err, "{}", printable(&format!("uwhl-rs: note: {n}")));
        }
    }
}

/// The options an input skipped as done was restored with otherwise
/// (`crate::files::sidecar::changed_options` of its sidecar `side`); this
/// run's own, as a sidecar records them, are made at the first skip and
/// kept in `recorded`.
fn changed_since(side: &Path, opts: &Options, recorded: &mut Option<Value>) -> Vec<String> {
    let now = recorded.get_or_insert_with(|| crate::files::sidecar::parameters(&opts.settings));
    crate::files::sidecar::changed_options(side, now)
}

/// The reading side's view of the writing side in [`overlapped`]: how many
/// inputs were handed over and how many are written.
struct Gate {
    acks: Receiver<()>,
    sent: u64,
    acked: u64,
    /// bytes held by the last input handed over, until it is written
    held: u64,
}

impl Gate {
    fn drain(&mut self) {
        while self.acks.try_recv().is_ok() {
            self.acked += 1;
        }
    }

    /// Waits until the writing side has finished the input it holds when
    /// `need` more bytes would not fit in `budget` beside it.
    fn make_room(&mut self, need: u64, budget: u64) {
        self.drain();
        if self.acked < self.sent && need.saturating_add(self.held) > budget {
            while self.acked < self.sent && self.acks.recv().is_ok() {
                self.acked += 1;
            }
        }
    }
}

/// The reading side of [`overlapped`]: hands items over, in order.
struct Handoff<T> {
    tx: SyncSender<T>,
    /// for the memory check of the next input
    gate: Gate,
}

impl<T> Handoff<T> {
    /// Hands `item` (holding `held` bytes until written) to the writing
    /// side once it has finished the previous one; false if it is gone.
    fn hand(&mut self, item: T, held: u64) -> bool {
        // the acks of inputs that needed no room (skipped, failed lines) are
        // taken here, or the channel would keep one per line of an endless stream
        self.gate.drain();
        if self.tx.send(item).is_err() {
            return false;
        }
        self.gate.sent += 1;
        self.gate.held = held;
        true
    }
}

/// Runs `read` (decoding and restoring the inputs, in order) on a second
/// thread and `write` (encoding and writing them, reporting) on this one,
/// one input apart: while input k is written, input k + 1 is decoded and
/// restored. The hand-over waits for the writer (a rendezvous), so at most
/// one restored input waits to be written, and [`Gate::make_room`] keeps
/// both within `--max-memory`. Outputs, their order and every byte written
/// are those of the one-at-a-time loop. Returns an error if the thread
/// cannot be started (nothing was processed then).
fn overlapped<T: Send>(read: impl FnOnce(&mut Handoff<T>) + Send, mut write: impl FnMut(T)) -> Result<(), Failure> {
    let (tx, rx) = sync_channel::<T>(0);
    let (ack_tx, acks) = channel::<()>();
    std::thread::scope(|s| {
        let reader = std::thread::Builder::new().name("uwhl-read".into()).spawn_scoped(s, move || {
            let mut h = Handoff {
                tx,
                gate: Gate {
                    acks,
                    sent: 0,
                    acked: 0,
                    held: 0,
                },
            };
            read(&mut h);
        });
        if let Err(e) = reader {
            return Err(Failure::new(Kind::Internal, format!("cannot start the reading thread: {e}")));
        }
        for item in rx {
            write(item);
            let _ = ack_tx.send(());
        }
        Ok(())
    })
}

static INTERRUPT: std::sync::OnceLock<std::sync::Arc<std::sync::atomic::AtomicBool>> = std::sync::OnceLock::new();

/// Batch mode's SIGINT and SIGTERM handling (SIGTERM is how batch systems
/// and `timeout` stop a job): the first lets the input being written
/// finish and stops the batch with exit 130 (docs/CLI.md); a second ends
/// the process at once. Stream mode and raw frames end at once
/// ([`end_at_once_on_signals`]). `ignored_at_start(sig)`: whether the
/// signal was ignored when the process started (the binary asks the
/// kernel; this library forbids the unsafe call).
pub fn install_interrupt_handler(ignored_at_start: &dyn Fn(i32) -> bool) -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let flag = INTERRUPT.get_or_init(Default::default).clone();
    // a signal ignored when the run started stays ignored (a script's
    // background job has SIGINT so), as the Python command leaves it
    for sig in [SIGINT, SIGTERM].into_iter().filter(|&s| !ignored_at_start(s)) {
        signal_hook::flag::register_conditional_default(sig, flag.clone())?;
        signal_hook::flag::register(sig, flag.clone())?;
    }
    Ok(())
}

/// Stream mode's and raw frames' SIGINT and SIGTERM: the run ends at once,
/// by the signal's own default action (the shell reports 130 or 143), once
/// no new temporary can be created and this process's temporaries in the
/// output folder `dir` are removed (they were left for the next run to
/// sweep). A second signal meanwhile ends it at once. A signal ignored when
/// the process started stays ignored (`ignored_at_start`, as
/// [`install_interrupt_handler`]). When the handling cannot be set up, none
/// of it stays: the default action ends the run.
pub fn end_at_once_on_signals(dir: Option<std::path::PathBuf>, ignored_at_start: &dyn Fn(i32) -> bool) -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let sigs: Vec<i32> = [SIGINT, SIGTERM].into_iter().filter(|&s| !ignored_at_start(s)).collect();
    if sigs.is_empty() {
        return Ok(());
    }
    // the queue first: a signal from here on waits in it for the thread below
    let mut signals = signal_hook::iterator::Signals::new(&sigs)?;
    let handle = signals.handle();
    let armed = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut ids = Vec::new();
    // whatever fails, nothing of this stays: the default action applies again
    let undo = |ids: &mut Vec<signal_hook::SigId>| {
        handle.close();
        for id in ids.drain(..) {
            signal_hook::low_level::unregister(id);
        }
    };
    for &sig in &sigs {
        match signal_hook::flag::register_conditional_default(sig, armed.clone()) {
            Ok(id) => ids.push(id),
            Err(e) => {
                undo(&mut ids);
                return Err(e);
            }
        }
    }
    let spawned = std::thread::Builder::new().name("uwhl-signals".into()).spawn(move || {
        if let Some(sig) = signals.forever().next() {
            armed.store(true, std::sync::atomic::Ordering::SeqCst);
            crate::files::commit::stop_new_temps();
            if let Some(d) = &dir {
                crate::files::jobs::remove_own_temps(d);
            }
            let _ = signal_hook::low_level::emulate_default_handler(sig);
            std::process::exit(128 + sig);
        }
    });
    if let Err(e) = spawned {
        undo(&mut ids);
        return Err(e);
    }
    Ok(())
}

fn interrupted() -> bool {
    INTERRUPT.get().is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
}

/// The exit code of an interrupted run (docs/CLI.md).
fn exit_interrupted() -> u8 {
    crate::files::options::exit_code("interrupted")
}

/// Batch mode: every input is processed; returns the largest exit code.
/// The next input is decoded and restored while the outputs of the
/// previous one are written (`overlapped`).
pub fn run_batch(opts: &Options, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    // measured before any input is read: the part of --max-memory the process holds anyway
    crate::kernels::memory::process_base();
    if let Err(code) = outdir_usable(opts, err) {
        return code;
    }
    let masks = match load_run_masks(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    dive_notes(opts, err);
    let (jobs, errors, notes) = collect_jobs(&opts.inputs, &opts.outdir, &output_suffixes(opts));
    say_notes(&notes, opts, err);
    let errors: Vec<(PathBuf, Failure)> = errors
        .into_iter()
        .map(|(p, m)| {
            // a pattern that reached the command as it is (quoted, or one the
            // shell found no match for): this command takes paths only
            let pattern = p.to_string_lossy().contains(['*', '?', '[']);
            let m = if pattern && m == "no such file or folder" {
                format!("{m} (a pattern given as it is: quoted, or matching nothing; uwhl-rs does not expand patterns, uwhl does)")
            } else {
                m
            };
            (p, Failure::new(Kind::Input, m))
        })
        .collect();
    let mut code = 0u8;
    // what a killed run left in the output folders goes first, before
    // this run holds the folder (its summary's lock)
    let dirs: std::collections::BTreeSet<&Path> = jobs.iter().map(|j| j.dir.as_path()).collect();
    if !jobs.is_empty() {
        // made now, so that the summary below holds it from the start
        // (crate::files::jobs::enter_folder says why); one that cannot be
        // made would fail every input and the summary, one by one
        if let Err(why) = crate::files::jobs::make_folder(&opts.outdir) {
            return write_refused(opts, err, why);
        }
    }
    for d in dirs {
        crate::files::jobs::remove_stale_temps(d, &opts.outdir);
    }
    // OUTDIR/summary.csv, a row per input as it is settled
    let wait_note = [crate::files::jobs::waiting_note(&opts.outdir)];
    let mut summary = crate::files::summary::Summary::create_waiting(&opts.outdir, &mut || say_notes(&wait_note, opts, err));
    // an earlier run's failures of inputs this run was not given stay listed
    let named = |p: &Path| p.to_string_lossy().into_owned();
    summary.given(jobs.iter().map(|j| named(&j.input)).chain(errors.iter().map(|(p, _)| named(p))));
    for (p, e) in &errors {
        report(err, opts.json_errors, Some(p), e);
        code = code.max(e.kind.exit_code());
        summary.failed(p, e.kind.name(), &e.to_string(), e.kind.exit_code());
    }
    // --reuse-estimates N: the inputs are the frames of one sequence, in order
    let mut seq = sequence(opts);
    let read = |h: &mut Handoff<(usize, Result<Prepared, Failure>)>| {
        for (i, job) in jobs.iter().enumerate() {
            if interrupted() {
                break;
            }
            let r = prepare(job, opts, &masks, seq.as_mut(), Some(&mut |need| h.gate.make_room(need, opts.params.max_memory)));
            let held = r.as_ref().map_or(0, Prepared::held_bytes);
            if !h.hand((i, r), held) {
                break;
            }
        }
    };
    let t0 = Instant::now();
    let total = jobs.len();
    // done, skipped, failed (the inputs that matched nothing count as failed)
    let mut counts = [0usize, 0, errors.len()];
    let mut recorded = None;
    let write = |(i, r): (usize, Result<Prepared, Failure>)| {
        let Some(job) = jobs.get(i) else {
            return;
        };
        let outcome = r.and_then(|p| complete(job, p, opts));
        let k = i + 1;
        match outcome {
            Ok(Outcome::Done(side)) => {
                counts[0] += 1;
                summary.done(&job.input, &side, &job.dir);
                if !opts.quiet {
                    let img = side
                        .pointer("/outputs/image")
                        .and_then(Value::as_str)
                        .map(|f| job.dir.join(f))
                        .unwrap_or_default();
                    let secs = side.pointer("/seconds/total").and_then(Value::as_f64).unwrap_or(0.0);
                    let line = format!(
                        "[{k}/{total}] {} -> {} (water type {}{}, {secs:.2} s)",
                        job.input.display(),
                        img.display(),
                        side.get("water_type").and_then(Value::as_str).unwrap_or("?"),
                        crate::files::sidecar::progress_said(side.get("fallback_share").and_then(Value::as_f64), &sidecar_flags(&side))
                    );
                    let _ = writeln!(out, "{}", printable(&line));
                }
            }
            Ok(Outcome::Skipped(s, why)) => {
                counts[1] += 1;
                let note = if why == Skip::Done {
                    "already done (sidecar exists; --overwrite redoes it)".to_string()
                } else {
                    why.reason()
                };
                summary.skipped(&job.input, &s, &note);
                if !opts.quiet {
                    let why = if why == Skip::Done {
                        let changed = changed_since(&s, opts, &mut recorded);
                        format!("{} exists{}", s.display(), crate::files::sidecar::changed_said(&changed))
                    } else {
                        why.reason()
                    };
                    let _ = writeln!(out, "{}", printable(&format!("[{k}/{total}] {}: skipped ({why})", job.input.display())));
                }
            }
            Err(e) => {
                counts[2] += 1;
                report(err, opts.json_errors, Some(&job.input), &e);
                code = code.max(e.kind.exit_code());
                summary.failed(&job.input, e.kind.name(), &e.to_string(), e.kind.exit_code());
            }
        }
        let _ = out.flush();
    };
    if let Err(e) = overlapped(read, write) {
        report(err, opts.json_errors, None, &e);
        code = code.max(e.kind.exit_code());
    }
    summary.close();
    say_notes(&summary.notes, opts, err);
    if let Some(why) = summary.error.take() {
        if summary.read_only && counts[0] == 0 {
            // a rerun over a finished survey on a read-only mount: nothing
            // was to be written, the earlier summary.csv still holds
            if !opts.quiet {
                let _ = writeln!(err, "{}", printable(&format!("uwhl-rs: note: {why} (read-only output folder: the earlier summary.csv stays)")));
            }
        } else {
            let e = Failure::new(Kind::Write, why);
            report(err, opts.json_errors, None, &e);
            code = code.max(e.kind.exit_code());
        }
    }
    let [done, skipped, failed] = counts;
    if !opts.quiet {
        let _ = writeln!(out, "{done} done, {skipped} skipped, {failed} failed in {:.1} s", t0.elapsed().as_secs_f64());
    }
    if interrupted() {
        let message = format!(
            "interrupted after {} of {total} inputs; run the same command again to resume",
            done + skipped + failed - errors.len()
        );
        let _ = if opts.json_errors {
            let obj = serde_json::json!({"error": "interrupted", "input": null, "message": message, "exit_code": exit_interrupted()});
            writeln!(err, "{obj}")
        } else {
            writeln!(err, "uwhl-rs: {message}")
        };
        return exit_interrupted();
    }
    if failed > 0 && !opts.json_errors {
        let _ = writeln!(err, "uwhl-rs: {failed} input(s) failed");
    }
    code
}

/// The longest path line accepted in stream mode.
pub const MAX_LINE: usize = 64 * 1024;

/// Reads one line of at most [`MAX_LINE`] bytes into `line`; a longer line
/// is consumed to its end and reported as `Some(true)`. `None` at the end.
fn read_line(input: &mut dyn BufRead, line: &mut Vec<u8>) -> std::io::Result<Option<bool>> {
    let n = Read::take(&mut *input, MAX_LINE as u64 + 1).read_until(b'\n', line)?;
    if n == 0 {
        return Ok(None);
    }
    if line.len() <= MAX_LINE || line.last() == Some(&b'\n') {
        return Ok(Some(false));
    }
    let mut rest = Vec::new();
    loop {
        rest.clear();
        let k = Read::take(&mut *input, MAX_LINE as u64).read_until(b'\n', &mut rest)?;
        if k == 0 || rest.last() == Some(&b'\n') {
            break;
        }
    }
    line.truncate(MAX_LINE);
    Ok(Some(true))
}

/// What the reading side of stream mode hands over: a frame's outcome so
/// far, a line that names no frame, or an unreadable stdin (the end).
enum StreamItem {
    Frame(Job, Result<Prepared, Failure>),
    /// the failure and the line as it can be shown (U+FFFD for bytes that
    /// are not UTF-8, cut after 256 characters), so that a reader can match it
    BadLine(Failure, String),
    Fatal(Failure),
}

/// Stream mode: one image path per line of `input`, one JSON line per frame
/// on `out` (the sidecar, `{"skipped": ...}` or an error object), flushed at
/// once; a bad frame never stops the loop. With `--reuse-estimates N` the
/// water type and veiling light of the last estimating frame are reused for
/// the next N - 1 frames. The next frame is read, decoded and restored
/// while the previous one's outputs are written (`overlapped`); its line
/// is printed as soon as they are. Returns 0 at the end of the input (or
/// the code of a bad `--mask`).
pub fn run_stream(opts: &Options, input: &mut (dyn BufRead + Send), out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    crate::kernels::memory::process_base();
    if let Err(code) = outdir_usable(opts, err) {
        return code;
    }
    let masks = match load_run_masks(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    dive_notes(opts, err);
    let mut seq = sequence(opts);
    let _presence = match enter_outdir(opts, err) {
        Ok(p) => p,
        Err(code) => return code,
    };
    // stdout gone (closed pipe, full disk): the frames' lines cannot be
    // reported, so the loop stops instead of restoring frames nobody hears of
    let gone = std::sync::atomic::AtomicBool::new(false);
    let mut lost: Option<String> = None;
    let mut recorded = None;
    // as in a batch, a file under the output folder (an earlier frame's
    // output, fed back by a watch on the folder) is not an input
    let out_real = std::fs::canonicalize(&opts.outdir).unwrap_or_else(|_| opts.outdir.clone());
    let read = |h: &mut Handoff<StreamItem>| {
        let mut line = Vec::new();
        let mut number: u64 = 0;
        loop {
            if gone.load(std::sync::atomic::Ordering::Relaxed) {
                break;
            }
            line.clear();
            let too_long = match read_line(input, &mut line) {
                Ok(None) => break,
                Ok(Some(too_long)) => too_long,
                Err(e) => {
                    let e = Failure::new(Kind::Input, format!("cannot read stdin: {e}"));
                    h.hand(StreamItem::Fatal(e), 0);
                    break;
                }
            };
            number += 1;
            let shown = || {
                let text = String::from_utf8_lossy(&line);
                let text = text.trim_end_matches(['\n', '\r']);
                match text.char_indices().nth(256) {
                    Some((cut, _)) => format!("{}...", &text[..cut]),
                    None => text.to_string(),
                }
            };
            let item = match std::str::from_utf8(&line) {
                _ if too_long => StreamItem::BadLine(
                    Failure::new(Kind::Input, format!("input line {number} is longer than {MAX_LINE} bytes")),
                    shown(),
                ),
                Err(_) => StreamItem::BadLine(
                    Failure::new(Kind::Input, format!("input line {number} is not valid UTF-8")),
                    shown(),
                ),
                Ok(s) => {
                    let s = s.trim_end_matches(['\n', '\r']);
                    if s.trim().is_empty() {
                        continue;
                    }
                    let path = PathBuf::from(s);
                    let job = Job {
                        name: path
                            .file_stem()
                            .map(|s| s.to_string_lossy().into_owned())
                            .unwrap_or_default(),
                        input: path.clone(),
                        dir: opts.outdir.clone(),
                    };
                    let r = if std::fs::canonicalize(&path).is_ok_and(|real| real.starts_with(&out_real)) {
                        Err(Failure::new(Kind::Input, crate::files::jobs::inside_outdir(&opts.outdir)))
                    } else {
                        prepare(&job, opts, &masks, seq.as_mut(), Some(&mut |need| h.gate.make_room(need, opts.params.max_memory)))
                    };
                    StreamItem::Frame(job, r)
                }
            };
            let held = match &item {
                StreamItem::Frame(_, Ok(p)) => p.held_bytes(),
                _ => 0,
            };
            if !h.hand(item, held) {
                break;
            }
        }
    };
    // stdin itself could not be read (a folder given as stdin): the run's code
    let mut fatal: Option<u8> = None;
    let write = |item: StreamItem| {
        let result = match item {
            StreamItem::Frame(job, r) => match r.and_then(|p| complete(&job, p, opts)) {
                Ok(o) => Ok((job.input, o)),
                Err(e) => Err((Some(job.input), e)),
            },
            StreamItem::BadLine(e, shown) => Err((Some(PathBuf::from(shown)), e)),
            StreamItem::Fatal(e) => {
                report(err, opts.json_errors, None, &e);
                fatal = Some(e.kind.exit_code());
                return;
            }
        };
        let json = match result {
            Ok((_, Outcome::Done(side))) => *side,
            Ok((p, Outcome::Skipped(s, why))) => {
                let mut line = serde_json::json!({
                    "input": p.to_string_lossy(),
                    "skipped": why.reason(),
                    "sidecar": s.to_string_lossy(),
                });
                if why == Skip::Done {
                    // restored earlier with other options: which, by flag (as batch lines say)
                    let changed = changed_since(&s, opts, &mut recorded);
                    if let (false, Some(o)) = (changed.is_empty(), line.as_object_mut()) {
                        o.insert("other_options".into(), crate::files::sidecar::flags_of(&changed).into());
                    }
                }
                line
            }
            Err((p, e)) => {
                report(err, opts.json_errors, p.as_deref(), &e);
                e.to_json(p.as_deref().map(|p| p.to_string_lossy()).as_deref())
            }
        };
        if lost.is_none() {
            if let Err(e) = writeln!(out, "{}", json_line(&json.to_string())).and_then(|()| out.flush()) {
                gone.store(true, std::sync::atomic::Ordering::Relaxed);
                lost = Some(e.to_string());
            }
        }
    };
    if let Err(e) = overlapped(read, write) {
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    if let Some(why) = lost {
        let e = Failure::new(
            Kind::Write,
            format!("cannot write the frame lines to stdout ({why}): stopped; the lines after it were not read"),
        );
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    fatal.unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_in_lines_are_escaped() {
        assert_eq!(printable("a\u{1b}[31mb\nc\u{7f}\u{85}é"), "a\\x1b[31mb\\x0ac\\x7f\\x85é");
        assert_eq!(printable("plain/name.jpg"), "plain/name.jpg");
        // a right-to-left override and a line separator: escaped, other text kept
        assert_eq!(printable("x\u{202e}gnp.exe\u{2028}y \u{05d0}.png"), "x\\u202egnp.exe\\u2028y \u{05d0}.png");
        // error objects in the documented form
        let v = serde_json::json!({"error": "x", "input": null, "list": [1, "a\"b"], "in": {"k": 2.5}});
        assert_eq!(spaced(&v), r#"{"error": "x", "input": null, "list": [1, "a\"b"], "in": {"k": 2.5}}"#);
        assert_eq!(serde_json::from_str::<serde_json::Value>(&spaced(&v)).unwrap(), v);
        // JSON lines: the same characters and C1 as JSON escapes, read back unchanged
        let v = serde_json::json!({"input": "a\u{202e}b\u{2028}c\u{85}d\u{7f}\u{05d0}\n"});
        let line = json_line(&v.to_string());
        assert_eq!(line, format!("{}{}{}", r#"{"input":"a\u202eb\u2028c\u0085d\u007f"#, '\u{05d0}', r#"\n"}"#));
        assert_eq!(serde_json::from_str::<serde_json::Value>(&line).unwrap(), v);
    }

    #[test]
    fn stream_lines_are_bounded() {
        let long = vec![b'a'; MAX_LINE + 10];
        let data = [&b"one\n"[..], &long, b"\ntwo"].concat();
        let mut input = std::io::Cursor::new(data);
        let mut line = Vec::new();
        assert_eq!(read_line(&mut input, &mut line).unwrap(), Some(false));
        assert_eq!(line, b"one\n");
        line.clear();
        assert_eq!(read_line(&mut input, &mut line).unwrap(), Some(true));
        assert_eq!(line.len(), MAX_LINE);
        line.clear();
        assert_eq!(read_line(&mut input, &mut line).unwrap(), Some(false));
        assert_eq!(line, b"two");
        line.clear();
        assert_eq!(read_line(&mut input, &mut line).unwrap(), None);
    }

    #[test]
    fn gate_waits_for_the_writer_only_when_both_would_not_fit() {
        let (ack_tx, acks) = channel::<()>();
        let mut g = Gate {
            acks,
            sent: 1,
            acked: 0,
            held: 100,
        };
        // 10 + 100 <= 120: no wait, the previous input is still held
        g.make_room(10, 120);
        assert_eq!(g.acked, 0);
        // 50 + 100 > 120: waits for the writer's acknowledgement
        let t = Instant::now();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(100));
            ack_tx.send(()).unwrap();
            ack_tx
        });
        g.make_room(50, 120);
        assert_eq!(g.acked, 1);
        assert!(t.elapsed() >= std::time::Duration::from_millis(90));
        // nothing outstanding: never waits, whatever the need
        g.make_room(1000, 120);
        drop(writer.join().unwrap());
        // a writer that is gone does not hang the reader
        g.sent = 2;
        g.make_room(1000, 120);
        assert_eq!(g.acked, 1);
    }

    #[test]
    fn overlapped_hands_items_over_in_order_one_ahead_at_most() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let produced = AtomicUsize::new(0);
        let mut seen = Vec::new();
        overlapped(
            |h: &mut Handoff<usize>| {
                for i in 0..50 {
                    produced.store(i + 1, Ordering::SeqCst);
                    if !h.hand(i, 0) {
                        break;
                    }
                }
            },
            |i| {
                // the reader is working on item i + 1 at most
                assert!(produced.load(Ordering::SeqCst) <= i + 2);
                seen.push(i);
            },
        )
        .unwrap();
        assert_eq!(seen, (0..50).collect::<Vec<_>>());
    }

    #[test]
    fn acknowledgements_do_not_pile_up_when_no_input_needs_room() {
        // a stream of lines that are all skipped never calls make_room; the
        // writer's acks must still be taken, one hand-over behind at most
        let mut most = 0;
        overlapped(
            |h: &mut Handoff<usize>| {
                for i in 0..2000 {
                    assert!(h.hand(i, 0));
                    // the item handed over and the one before may be unwritten
                    most = most.max(h.gate.sent - h.gate.acked);
                }
            },
            |_| {},
        )
        .unwrap();
        assert!(most <= 2, "{most} acknowledgements left in the channel");
    }
}
