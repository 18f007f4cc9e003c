//! One input through decode -> preprocess -> `restore` -> outputs, and the
//! batch and stream loops around it.

use super::args::{Options, Preprocess};
use crate::budget::{Plan, HELD_WHILE_WRITING};
use super::decode::{decode, decode_mask, Limits};
use super::output::{encode_image, encode_transmission, encode_transmission_color, Encoding};
use crate::commit::{claim, Claim, Request, Resolution, Skip};
use super::sidecar::{sidecar, OutputPaths, Seconds, Source};
use super::{CliError, Kind};
use crate::color::{max_side_factor, reference_srgb_stretch};
use crate::filters::downscale;
use crate::image::ImageRef;
use crate::params::{Input, Params};
use crate::pipeline::restore;
use crate::jobs::{collect_jobs, extension, Job, RAW_EXTENSIONS};
use crate::params::Flag;
use crate::sequence::Sequence;
use crate::water::{jerlov_types, WaterType};
use serde_json::Value;
use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, sync_channel, Receiver, SyncSender};
use std::time::Instant;

/// A decoded mask image (`--mask` or `--water-mask`).
#[derive(Debug, Clone)]
pub struct Mask {
    /// true where the image is nonzero
    pub data: Vec<bool>,
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
}

/// The masks of a run, read once.
#[derive(Debug, Clone, Default)]
pub struct Masks {
    /// `--mask`: true = use the pixel for estimation
    pub mask: Option<Mask>,
    /// `--water-mask`: true = water region
    pub water: Option<Mask>,
}

/// Reads a mask file; an unreadable mask is a usage error (it is an argument).
pub fn load_mask(path: &Path, flag: &str, opts: &Options) -> Result<Mask, CliError> {
    let file = File::open(path)
        .map_err(|e| CliError::usage(format!("{flag} {}: {e}", path.display())))?;
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.max_memory,
    };
    let (data, height, width) = decode_mask(BufReader::new(file), &limits).map_err(|e| {
        let kind = if e.kind == Kind::Budget { Kind::Budget } else { Kind::Usage };
        CliError::new(kind, format!("{flag} {}: {}", path.display(), e.message))
    })?;
    Ok(Mask { data, height, width })
}

/// Reads `--mask` and `--water-mask`.
pub fn load_masks(opts: &Options) -> Result<Masks, CliError> {
    let read = |p: &Option<PathBuf>, flag: &str| p.as_deref().map(|p| load_mask(p, flag, opts)).transpose();
    Ok(Masks {
        mask: read(&opts.mask, "--mask")?,
        water: read(&opts.water_mask, "--water-mask")?,
    })
}

/// What happened to one input.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// restored: the sidecar object
    Done(Box<Value>),
    /// skipped: the sidecar path and why
    Skipped(PathBuf, Skip),
}

fn water_types(opts: &Options) -> Vec<WaterType> {
    match &opts.water_types {
        None => jerlov_types(),
        Some(list) => list.iter().map(|c| c.water_type.clone()).collect(),
    }
}

/// A mask checked against the input size and downscaled by `factor`: a
/// block is true when at least `need` of its pixels are (1.0 = all).
fn fit_mask(m: Option<&Mask>, flag: &str, h: usize, w: usize, factor: usize, need: f32) -> Result<Option<Vec<bool>>, CliError> {
    let Some(m) = m else { return Ok(None) };
    if (m.height, m.width) != (h, w) {
        return Err(CliError::usage(format!(
            "{flag} is {}x{} pixels but the input is {h}x{w}",
            m.width, m.height
        )));
    }
    if factor <= 1 {
        return Ok(Some(m.data.clone()));
    }
    let plane: Vec<f32> = m.data.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
    Ok(Some(downscale(&plane, h, w, 1, factor).0.iter().map(|&v| v >= need).collect()))
}

/// The memory plan of one input, checked against `--max-memory` from its
/// header. With a `gate` (the reader thread of [`overlapped`]), an input
/// that does not fit beside the previous one's outputs, still being
/// written, first waits until they are.
fn check_plan(h: &super::decode::Header, opts: &Options, masks: &Masks, gate: Option<&mut Gate>) -> Result<(), CliError> {
    let plan = Plan {
        height: h.height,
        width: h.width,
        decoded_bpp: h.bpp,
        decoded_is_rgb: h.is_rgb,
        oriented: h.oriented,
        factor: opts.max_side.map_or(1, |n| max_side_factor(h.height, h.width, n)),
        reference: opts.preprocess == Preprocess::Reference,
        masks: u8::from(masks.mask.is_some()) + u8::from(masks.water.is_some()),
        write_extra: 0,
    };
    // the budget bounds the process's peak: what it holds anyway counts
    let need = plan.bytes().saturating_add(crate::budget::process_base());
    if let Some(g) = gate {
        g.make_room(need, opts.max_memory);
    }
    if need > opts.max_memory {
        return Err(CliError::new(
            Kind::Budget,
            format!(
                "{}x{} pixels need about {need} bytes, over --max-memory {} (use --max-side or raise --max-memory)",
                h.height, h.width, opts.max_memory
            ),
        ));
    }
    if !crate::budget::can_allocate(plan.bytes()) {
        return Err(CliError::new(
            Kind::Budget,
            format!(
                "{}x{} pixels need about {need} bytes, more than the system gives now (free memory, a container \
                 limit or ulimit -v); use --max-side",
                h.height, h.width
            ),
        ));
    }
    Ok(())
}

/// A restored input before anything is written.
#[derive(Debug, Clone)]
pub struct Restored {
    /// the result of `restore`
    pub res: crate::params::Restoration,
    /// where it came from (the sidecar's `source`)
    pub source: Source,
    /// seconds spent decoding and preprocessing
    pub t_read: f64,
    /// seconds spent in `restore`
    pub t_restore: f64,
}

/// The core parameters of the options (the candidate types, a given A).
pub(crate) fn method_params(opts: &Options) -> Params {
    Params {
        water_types: water_types(opts),
        veiling_light: opts.veiling_light.map(|a| a.map(|v| v as f32)),
        guided_radius: opts.guided_radius,
        guided_eps: opts.guided_eps,
        sphere_points: opts.sphere_points,
        // the binary sizes rayon's global pool once (init_threads)
        threads: None,
        max_memory: opts.max_memory,
        selection: opts.selection,
        guided_subsample: opts.guided_subsample,
        t_scale: opts.t_scale,
        method: opts.method,
        white_balance: opts.white_balance,
        type_choice: opts.type_choice,
        haze_floor: opts.haze_floor,
    }
}

#[cfg(any(test, feature = "internals"))]
/// Decodes one file from `reader` and restores it with the options, as the
/// next frame of `seq` when given (`--reuse-estimates`: its
/// [`Sequence`] was made with the same options).
///
/// Order (as the Python command): decode (sRGB -> linear unless `--linear`
/// or `--preprocess reference`; float TIFF as is) -> reference stretch of
/// METHOD §2 (integer inputs with `--preprocess reference`, whole image, no
/// mask) -> `--max-side` block average (masks: see `--help`) -> `restore`.
pub fn decode_and_restore<R: BufRead + Seek>(
    reader: R,
    opts: &Options,
    masks: &Masks,
    seq: Option<&mut Sequence>,
) -> Result<Restored, CliError> {
    decode_and_restore_gated(reader, opts, masks, seq, None)
}

/// [`decode_and_restore`], with the memory check waiting at `gate` when given.
fn decode_and_restore_gated<R: BufRead + Seek>(
    reader: R,
    opts: &Options,
    masks: &Masks,
    seq: Option<&mut Sequence>,
    gate: Option<&mut Gate>,
) -> Result<Restored, CliError> {
    let t0 = Instant::now();
    let reference = opts.preprocess == Preprocess::Reference;
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.max_memory,
    };
    let decoded = decode(reader, &limits, !opts.linear && !reference, |h| {
        check_plan(h, opts, masks, gate)
    })?;
    let (h, w) = (decoded.height, decoded.width);
    // float samples are linear: no reference stretch, sRGB curve on output
    let linear = !reference || decoded.is_float;
    let factor = opts.max_side.map_or(1, |n| max_side_factor(h, w, n));
    let mask = fit_mask(masks.mask.as_ref(), "--mask", h, w, factor, 1.0)?;
    let water = fit_mask(masks.water.as_ref(), "--water-mask", h, w, factor, 0.5)?;
    let data = if linear {
        decoded.data
    } else {
        reference_srgb_stretch(&decoded.data, None)
    };
    let (data, hp, wp) = if factor > 1 {
        downscale(&data, h, w, 3, factor)
    } else {
        (data, h, w)
    };
    let t_read = t0.elapsed().as_secs_f64();
    let input = Input {
        image: ImageRef::new(&data, hp, wp)?,
        mask: mask.as_deref(),
        water_mask: water.as_deref(),
    };
    let t1 = Instant::now();
    let res = match seq {
        Some(seq) => seq.restore(&input)?,
        None => restore(&input, &method_params(opts))?,
    };
    let t_restore = t1.elapsed().as_secs_f64();
    let source = Source {
        kind: if decoded.is_float || opts.linear { "linear" } else { "srgb" },
        format: decoded.format,
        bits: decoded.bits,
        height: h,
        width: w,
        orientation: decoded.orientation,
        linear,
        preprocess: if linear { Preprocess::None } else { Preprocess::Reference },
        processed_height: hp,
        processed_width: wp,
        icc_profile: decoded.icc_profile.clone(),
    };
    Ok(Restored {
        res,
        source,
        t_read,
        t_restore,
    })
}

#[cfg(any(test, feature = "internals"))]
/// The fuzz target's body (`fuzz/`) and its regression test: the first byte
/// picks options (bit 0 reference preprocessing, bit 1 `--linear`, bit 2
/// `--max-side 16`, bit 3 two water types), the rest is a file decoded and
/// restored in memory with tight limits (65536 pixels, 256 MiB, one
/// thread's worth of water types in flight). Returns the restoration or the
/// error; panics only if a result breaks the output contract.
pub fn fuzz_one(data: &[u8]) -> Result<Restored, CliError> {
    let Some((&sel, file)) = data.split_first() else {
        return Err(CliError::new(Kind::Input, "empty"));
    };
    let reference = sel & 1 != 0;
    let opts = Options {
        max_pixels: 1 << 16,
        max_memory: 256 << 20,
        sphere_points: 64,
        threads: Some(1),
        preprocess: if reference { Preprocess::Reference } else { Preprocess::None },
        linear: sel & 2 != 0 && !reference,
        max_side: (sel & 4 != 0).then_some(16),
        water_types: (sel & 8 != 0).then(|| {
            ["II", "7C"]
                .iter()
                .filter_map(|n| WaterType::by_name(n).ok())
                .map(|water_type| super::args::WaterChoice {
                    water_type,
                    custom: false,
                })
                .collect()
        }),
        ..Options::default()
    };
    let r = decode_and_restore(std::io::Cursor::new(file), &opts, &Masks::default(), None)?;
    let ok = r.res.image.iter().chain(&r.res.radiance).all(|v| (0.0..=1.0).contains(v))
        && r.res.transmission.iter().all(|t| *t > 0.0 && *t <= 1.0);
    if !ok {
        return Err(CliError::new(Kind::Internal, "output outside [0, 1]"));
    }
    Ok(r)
}

#[cfg(any(test, feature = "internals"))]
/// Restores one input and writes its outputs (see [`decode_and_restore`]).
pub fn process(job: &Job, opts: &Options, masks: &Masks, seq: Option<&mut Sequence>) -> Result<Outcome, CliError> {
    complete(job, prepare(job, opts, masks, seq, None)?, opts)
}

/// What becomes of a prepared input: skipped, or its outputs written.
fn complete(job: &Job, p: Prepared, opts: &Options) -> Result<Outcome, CliError> {
    match p {
        Prepared::Skipped(s, why) => Ok(Outcome::Skipped(s, why)),
        Prepared::Restored(r) => finish(job, *r, opts),
    }
}

/// One input decoded and restored, before anything is written.
#[derive(Debug)]
enum Prepared {
    /// not restored: the sidecar path and why ([`Outcome::Skipped`])
    Skipped(PathBuf, Skip),
    /// restored, with its claimed output names and the time its processing started
    Restored(Box<(Restored, Claim, Instant)>),
}

impl Prepared {
    /// Bytes it holds until its outputs are written ([`super::budget::HELD_WHILE_WRITING`] per pixel).
    fn held_bytes(&self) -> u64 {
        match self {
            Prepared::Skipped(..) => 0,
            Prepared::Restored(r) => (r.0.res.transmission.len() as u64).saturating_mul(HELD_WHILE_WRITING),
        }
    }
}

/// The suffixes of an input's outputs after `NAME`, in writing order (the
/// sidecar comes last, added by `crate::commit`).
fn output_suffixes(opts: &Options) -> Vec<String> {
    vec![format!(".{}", opts.format.extension()), "_t.png".into(), "_t_color.png".into()]
}

/// The first half of [`process`]: the output names claimed (or the input
/// skipped), decoding and `restore`.
fn prepare(job: &Job, opts: &Options, masks: &Masks, seq: Option<&mut Sequence>, gate: Option<&mut Gate>) -> Result<Prepared, CliError> {
    let t0 = Instant::now();
    let suffixes = output_suffixes(opts);
    let request = Request {
        dir: &job.dir,
        base: &job.name,
        input: &job.input,
        suffixes: &suffixes,
        overwrite: opts.overwrite,
        rename: true,
    };
    let claimed = claim(&request)
        .map_err(|e| CliError::new(Kind::Write, format!("cannot claim output names in {}: {e}", job.dir.display())))?;
    let claimed = match claimed {
        Resolution::Claimed(c) => c,
        Resolution::Skipped(why, s) => return Ok(Prepared::Skipped(s, why)),
    };
    if RAW_EXTENSIONS.contains(&extension(&job.input).as_str()) {
        return Err(CliError::new(
            Kind::Input,
            "raw files are decoded by the Python command (uwhl restore); uwhl-rs reads PNG, JPEG and TIFF",
        ));
    }
    // a FIFO, socket or device is never opened (opening a FIFO blocks)
    crate::jobs::regular_file(&job.input).map_err(|m| CliError::new(Kind::Input, m))?;
    let file = File::open(&job.input)
        .map_err(|e| CliError::new(Kind::Input, format!("cannot open: {e}")))?;
    let restored = decode_and_restore_gated(BufReader::new(file), opts, masks, seq, gate)?;
    Ok(Prepared::Restored(Box::new((restored, claimed, t0))))
}

/// The second half of [`process`]: the outputs and the sidecar, through
/// the claim (written to temporaries, then put in place with the sidecar
/// last: all or nothing).
fn finish(job: &Job, (restored, mut claimed, t0): (Restored, Claim, Instant), opts: &Options) -> Result<Outcome, CliError> {
    let Restored {
        res,
        source,
        t_read,
        t_restore,
    } = restored;
    let (hp, wp) = (source.processed_height, source.processed_width);

    let t2 = Instant::now();
    let [image_path, t_path, tc_path, sidecar_path] = <[PathBuf; 4]>::try_from(claimed.paths().to_vec())
        .map_err(|_| CliError::new(Kind::Internal, "a claim of four outputs was expected"))?;
    let enc = Encoding {
        format: opts.format,
        bits: opts.bits(),
        srgb: source.linear,
        quality: opts.quality,
    };
    // the three encoders (each single-threaded) run at once; the files are
    // then written in order
    let (image_bytes, (t_bytes, tc_bytes)) = rayon::join(
        || encode_image(&image_path, &res.image, hp, wp, enc),
        || {
            rayon::join(
                || encode_transmission(&t_path, &res.transmission, hp, wp),
                || encode_transmission_color(&tc_path, &res.transmission, hp, wp),
            )
        },
    );
    let paths = OutputPaths {
        image: &image_path,
        transmission: &t_path,
        transmission_color: &tc_path,
    };
    // the input's EXIF and XMP, and the restoration's record, into the photo
    // (src/metadata.rs); the record is made of the sidecar's fields
    let sidecar_name = sidecar_path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let preview = sidecar(&job.input, &paths, &source, &res, opts, Seconds::default());
    let (image_bytes, carried) =
        crate::metadata::carry_from(&job.input, image_bytes?, &preview, &sidecar_name, wp as u32, hp as u32);
    let mut temps = Vec::with_capacity(4);
    for (i, (path, bytes)) in [(&image_path, image_bytes), (&t_path, t_bytes?), (&tc_path, tc_bytes?)].into_iter().enumerate() {
        temps.push(write_temp(&mut claimed, i, path, &bytes)?);
    }
    let seconds = Seconds {
        read: t_read,
        restore: t_restore,
        write: t2.elapsed().as_secs_f64(),
        total: t0.elapsed().as_secs_f64(),
    };
    let mut side = sidecar(&job.input, &paths, &source, &res, opts, seconds);
    if let Some(obj) = side.as_object_mut() {
        if opts.reuse_estimates.is_some() {
            let reused = res.flags.contains(&Flag::EstimatesReused);
            obj.insert("reused_estimates".into(), Value::Bool(reused));
        }
        // "metadata" goes before "seconds", as the Python command writes it
        let secs = obj.shift_remove("seconds");
        obj.insert("metadata".into(), carried);
        if let Some(secs) = secs {
            obj.insert("seconds".into(), secs);
        }
    }
    let mut bytes = serde_json::to_vec_pretty(&side)
        .map_err(|e| CliError::new(Kind::Internal, format!("sidecar: {e}")))?;
    bytes.push(b'\n');
    temps.push(write_temp(&mut claimed, 3, &sidecar_path, &bytes)?);
    claimed
        .commit(&temps)
        .map_err(|e| CliError::new(Kind::Write, format!("cannot write the outputs of {} in {}: {e}", job.input.display(), job.dir.display())))?;
    Ok(Outcome::Done(Box::new(side)))
}

/// Writes `bytes` into a new temporary of output `index` of the claim.
fn write_temp(claimed: &mut Claim, index: usize, path: &Path, bytes: &[u8]) -> Result<PathBuf, CliError> {
    let (tmp, mut f) = claimed
        .temp(index)
        .map_err(|e| CliError::new(Kind::Write, format!("cannot write {}: {e}", path.display())))?;
    f.write_all(bytes)
        .map_err(|e| CliError::new(Kind::Write, format!("cannot write {}: {e}", path.display())))?;
    Ok(tmp)
}

/// Reports an error on `err`: one JSON object per line with `--json-errors`,
/// else `uwhl-rs: INPUT: message`.
pub fn report(err: &mut dyn Write, opts_json: bool, input: Option<&Path>, e: &CliError) {
    let input_s = input.map(|p| p.to_string_lossy().into_owned());
    let _ = if opts_json {
        writeln!(err, "{}", e.to_json(input_s.as_deref()))
    } else {
        match input_s {
            Some(i) => writeln!(err, "uwhl-rs: {i}: {e}"),
            None => writeln!(err, "uwhl-rs: {e}"),
        }
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

fn load_run_masks(opts: &Options, err: &mut dyn Write) -> Result<Masks, u8> {
    load_masks(opts).map_err(|e| {
        report(err, opts.json_errors, None, &e);
        e.kind.exit_code()
    })
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
fn overlapped<T: Send>(read: impl FnOnce(&mut Handoff<T>) + Send, mut write: impl FnMut(T)) -> Result<(), CliError> {
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
            return Err(CliError::new(Kind::Internal, format!("cannot start the reading thread: {e}")));
        }
        for item in rx {
            write(item);
            let _ = ack_tx.send(());
        }
        Ok(())
    })
}

static INTERRUPT: std::sync::OnceLock<std::sync::Arc<std::sync::atomic::AtomicBool>> = std::sync::OnceLock::new();

/// Batch mode's SIGINT handling: the first SIGINT lets the input being
/// written finish and stops the batch with exit 130 (docs/CLI.md); a second
/// one ends the process at once. Stream mode keeps the default (the process
/// ends at once; a shell reports 130).
pub fn install_interrupt_handler() -> std::io::Result<()> {
    use signal_hook::consts::SIGINT;
    let flag = INTERRUPT.get_or_init(Default::default).clone();
    signal_hook::flag::register_conditional_default(SIGINT, flag.clone())?;
    signal_hook::flag::register(SIGINT, flag)?;
    Ok(())
}

fn interrupted() -> bool {
    INTERRUPT.get().is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
}

/// The exit code of an interrupted run (docs/CLI.md).
fn exit_interrupted() -> u8 {
    crate::options::exit_code("interrupted")
}

/// The core sequence of `--reuse-estimates N`: restored inputs 0, N, 2N,
/// ... estimate the water type and veiling light, the others reuse them.
fn sequence(opts: &Options) -> Option<Sequence> {
    opts.reuse_estimates.map(|n| {
        let mut s = Sequence::new(method_params(opts));
        s.refresh_every = n;
        s.reuse_water_mask = opts.reuse_water_mask;
        s
    })
}

/// Batch mode: every input is processed; returns the largest exit code.
/// The next input is decoded and restored while the outputs of the
/// previous one are written (`overlapped`).
pub fn run_batch(opts: &Options, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    // measured before any input is read: the part of --max-memory the process holds anyway
    crate::budget::process_base();
    let masks = match load_run_masks(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    let (jobs, errors) = collect_jobs(&opts.inputs, &opts.outdir, &output_suffixes(opts));
    let errors: Vec<(PathBuf, CliError)> = errors.into_iter().map(|(p, m)| (p, CliError::new(Kind::Input, m))).collect();
    let mut code = 0u8;
    // OUTDIR/summary.csv, a row per input as it is settled
    let mut summary = super::summary::Summary::create(&opts.outdir);
    for (p, e) in &errors {
        report(err, opts.json_errors, Some(p), e);
        code = code.max(e.kind.exit_code());
        summary.failed(p, e.kind.name(), &e.to_string(), e.kind.exit_code());
    }
    // --reuse-estimates N: the inputs are the frames of one sequence, in order
    let mut seq = sequence(opts);
    // what a killed run left in the output folders goes first
    let dirs: std::collections::BTreeSet<&Path> = jobs.iter().map(|j| j.dir.as_path()).collect();
    for d in dirs {
        crate::jobs::remove_stale_temps(d);
    }
    let read = |h: &mut Handoff<(usize, Result<Prepared, CliError>)>| {
        for (i, job) in jobs.iter().enumerate() {
            if interrupted() {
                break;
            }
            let r = prepare(job, opts, &masks, seq.as_mut(), Some(&mut h.gate));
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
    let write = |(i, r): (usize, Result<Prepared, CliError>)| {
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
                    let _ = writeln!(
                        out,
                        "[{k}/{total}] {} -> {} (water type {}, {secs:.2} s)",
                        job.input.display(),
                        img.display(),
                        side.get("water_type").and_then(Value::as_str).unwrap_or("?")
                    );
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
                    let why = if why == Skip::Done { format!("{} exists", s.display()) } else { why.reason() };
                    let _ = writeln!(out, "[{k}/{total}] {}: skipped ({why})", job.input.display());
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
    if let Some(why) = summary.error.take() {
        let e = CliError::new(Kind::Write, why);
        report(err, opts.json_errors, None, &e);
        code = code.max(e.kind.exit_code());
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
    Frame(Job, Result<Prepared, CliError>),
    BadLine(CliError),
    Fatal(CliError),
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
    crate::budget::process_base();
    let masks = match load_run_masks(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    let mut seq = sequence(opts);
    crate::jobs::remove_stale_temps(&opts.outdir);
    // stdout gone (closed pipe, full disk): the frames' lines cannot be
    // reported, so the loop stops instead of restoring frames nobody hears of
    let gone = std::sync::atomic::AtomicBool::new(false);
    let mut lost: Option<String> = None;
    let read = |h: &mut Handoff<StreamItem>| {
        let mut line = Vec::new();
        loop {
            if gone.load(std::sync::atomic::Ordering::Relaxed) {
                break;
            }
            line.clear();
            let too_long = match read_line(input, &mut line) {
                Ok(None) => break,
                Ok(Some(too_long)) => too_long,
                Err(e) => {
                    let e = CliError::new(Kind::Input, format!("cannot read stdin: {e}"));
                    h.hand(StreamItem::Fatal(e), 0);
                    break;
                }
            };
            let item = match std::str::from_utf8(&line) {
                _ if too_long => {
                    StreamItem::BadLine(CliError::new(Kind::Input, format!("input line longer than {MAX_LINE} bytes")))
                }
                Err(_) => StreamItem::BadLine(CliError::new(Kind::Input, "input line is not valid UTF-8")),
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
                    let r = prepare(&job, opts, &masks, seq.as_mut(), Some(&mut h.gate));
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
    let write = |item: StreamItem| {
        let result = match item {
            StreamItem::Frame(job, r) => match r.and_then(|p| complete(&job, p, opts)) {
                Ok(o) => Ok((job.input, o)),
                Err(e) => Err((Some(job.input), e)),
            },
            StreamItem::BadLine(e) => Err((None, e)),
            StreamItem::Fatal(e) => {
                report(err, opts.json_errors, None, &e);
                return;
            }
        };
        let json = match result {
            Ok((_, Outcome::Done(side))) => *side,
            Ok((p, Outcome::Skipped(s, why))) => serde_json::json!({
                "input": p.to_string_lossy(),
                "skipped": why.reason(),
                "sidecar": s.to_string_lossy(),
            }),
            Err((p, e)) => {
                report(err, opts.json_errors, p.as_deref(), &e);
                e.to_json(p.as_deref().map(|p| p.to_string_lossy()).as_deref())
            }
        };
        if lost.is_none() {
            if let Err(e) = writeln!(out, "{json}").and_then(|()| out.flush()) {
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
        let e = CliError::new(
            Kind::Write,
            format!("cannot write the frame lines to stdout ({why}): stopped; the lines after it were not read"),
        );
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

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

}
