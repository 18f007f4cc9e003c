//! One input through decode -> preprocess -> `restore` -> outputs, and the
//! batch and stream loops around it.

use super::args::{Options, Preprocess};
use super::budget::Plan;
use super::decode::{decode, decode_mask, Limits};
use super::output::{write_bytes, write_image, write_transmission, write_transmission_color, Transaction};
use super::sidecar::{sidecar, OutputPaths, Seconds, Source};
use super::{CliError, Kind};
use crate::color::{max_side_factor, reference_srgb_stretch};
use crate::filters::downscale;
use crate::image::ImageRef;
use crate::pipeline::{restore, Input, Params};
use crate::water::{jerlov_types, WaterType};
use serde_json::Value;
use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Extensions taken when walking a folder (case-insensitive).
pub const IMAGE_EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "tif", "tiff"];

/// Raw extensions: taken when walking a folder (so that names agree with the
/// Python command, which decodes them), refused with an input error here.
pub const RAW_EXTENSIONS: [&str; 18] = [
    "dng", "nef", "nrw", "cr2", "cr3", "crw", "arw", "srf", "sr2", "orf", "rw2", "raf", "pef",
    "srw", "rwl", "3fr", "iiq", "x3f",
];

fn extension(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
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

fn walk(dir: &Path, rel: &Path, found: &mut Vec<(PathBuf, PathBuf)>) -> Result<(), CliError> {
    let rd = fs::read_dir(dir)
        .map_err(|e| CliError::new(Kind::Input, format!("cannot list {}: {e}", dir.display())))?;
    let mut entries: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        let Some(fname) = p.file_name().map(|f| f.to_os_string()) else {
            continue;
        };
        if fname.to_string_lossy().starts_with('.') {
            continue;
        }
        // symlinked folders are not followed (no cycles); symlinked files are
        let Ok(meta) = fs::symlink_metadata(&p) else {
            continue;
        };
        if meta.is_dir() {
            walk(&p, &rel.join(&fname), found)?;
        } else {
            let ext = extension(&p);
            let known = IMAGE_EXTENSIONS.contains(&ext.as_str()) || RAW_EXTENSIONS.contains(&ext.as_str());
            if known && p.is_file() {
                found.push((p, rel.to_path_buf()));
            }
        }
    }
    Ok(())
}

/// The jobs of a batch: files as given, folders walked recursively (sorted,
/// hidden entries skipped), outputs in `outdir/<path relative to the folder>/`.
/// Inputs that would share a `NAME` in one folder get `NAME_ext`. Returns the
/// jobs and the inputs that could not be listed.
pub fn collect_jobs(inputs: &[PathBuf], outdir: &Path) -> (Vec<Job>, Vec<(PathBuf, CliError)>) {
    let mut found: Vec<(PathBuf, PathBuf)> = Vec::new();
    let mut errors = Vec::new();
    for input in inputs {
        if input.is_dir() {
            if let Err(e) = walk(input, Path::new(""), &mut found) {
                errors.push((input.clone(), e));
            }
        } else {
            found.push((input.clone(), PathBuf::new()));
        }
    }
    let mut seen = std::collections::HashSet::new();
    found.retain(|(p, _)| seen.insert(p.clone()));
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut count: BTreeMap<(PathBuf, String), usize> = BTreeMap::new();
    for (p, rel) in &found {
        *count.entry((outdir.join(rel), stem(p))).or_insert(0) += 1;
    }
    let jobs = found
        .into_iter()
        .map(|(p, rel)| {
            let dir = outdir.join(&rel);
            let s = stem(&p);
            let shared = count.get(&(dir.clone(), s.clone())).copied().unwrap_or(0) > 1;
            let name = match (shared, p.extension()) {
                (true, Some(e)) => format!("{s}_{}", e.to_string_lossy()),
                _ => s,
            };
            Job { input: p, dir, name }
        })
        .collect();
    (jobs, errors)
}

/// A decoded `--mask`.
#[derive(Debug, Clone)]
pub struct Mask {
    /// true = use the pixel for estimation
    pub data: Vec<bool>,
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
}

/// Reads `--mask`; an unreadable mask is a usage error (it is an argument).
pub fn load_mask(path: &Path, opts: &Options) -> Result<Mask, CliError> {
    let file = File::open(path)
        .map_err(|e| CliError::usage(format!("--mask {}: {e}", path.display())))?;
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.max_memory,
    };
    let (data, height, width) = decode_mask(BufReader::new(file), &limits).map_err(|e| {
        let kind = if e.kind == Kind::Budget { Kind::Budget } else { Kind::Usage };
        CliError::new(kind, format!("--mask {}: {}", path.display(), e.message))
    })?;
    Ok(Mask { data, height, width })
}

/// The water type and veiling light of a restored frame, for `--reuse-estimates`.
#[derive(Debug, Clone)]
pub struct Estimates {
    /// the chosen type
    pub water_type: WaterType,
    /// A
    pub veiling_light: [f32; 3],
}

/// What happened to one input.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// restored: the sidecar object and the estimates
    Done(Box<Value>, Estimates),
    /// skipped: its sidecar exists (no `--overwrite`)
    Skipped(PathBuf),
}

fn water_types(opts: &Options) -> Result<Vec<WaterType>, CliError> {
    match &opts.water_types {
        None => Ok(jerlov_types()),
        Some(names) => names
            .iter()
            .map(|n| WaterType::by_name(n).map_err(|e| CliError::usage(e.to_string())))
            .collect(),
    }
}

/// Restores one input and writes its outputs; `reuse` replaces the water
/// types and the veiling light by a previous frame's.
pub fn process(job: &Job, opts: &Options, mask: Option<&Mask>, reuse: Option<&Estimates>) -> Result<Outcome, CliError> {
    let t0 = Instant::now();
    let sidecar_path = job.dir.join(format!("{}.json", job.name));
    if !opts.overwrite && sidecar_path.exists() {
        return Ok(Outcome::Skipped(sidecar_path));
    }
    if RAW_EXTENSIONS.contains(&extension(&job.input).as_str()) {
        return Err(CliError::new(
            Kind::Input,
            "raw files are decoded by the Python command (uwhl restore); uwhl-rs reads PNG, JPEG and TIFF",
        ));
    }
    let types = match reuse {
        Some(r) => vec![r.water_type.clone()],
        None => water_types(opts)?,
    };
    let threads = opts.threads.unwrap_or_else(rayon::current_num_threads);
    let in_flight = threads.min(types.len()).max(1);
    let file = File::open(&job.input)
        .map_err(|e| CliError::new(Kind::Input, format!("cannot open: {e}")))?;
    let reference = opts.preprocess == Preprocess::Reference;
    let linearize = !opts.linear && !reference;
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.max_memory,
    };
    let decoded = decode(BufReader::new(file), &limits, linearize, |h| {
        let plan = Plan {
            height: h.height,
            width: h.width,
            decoded_bpp: h.bpp,
            decoded_is_rgb: h.is_rgb,
            oriented: h.oriented,
            factor: opts.max_side.map_or(1, |n| max_side_factor(h.height, h.width, n)),
            reference,
            mask: mask.is_some(),
            in_flight,
        };
        let need = plan.bytes();
        if need > opts.max_memory {
            return Err(CliError::new(
                Kind::Budget,
                format!(
                    "{}x{} pixels need about {need} bytes, over --max-memory {} (use --max-side or raise --max-memory)",
                    h.height, h.width, opts.max_memory
                ),
            ));
        }
        Ok(())
    })?;
    let (h, w) = (decoded.height, decoded.width);
    if let Some(m) = mask {
        if (m.height, m.width) != (h, w) {
            return Err(CliError::usage(format!(
                "--mask is {}x{} pixels but the input is {h}x{w}",
                m.height, m.width
            )));
        }
    }
    let factor = opts.max_side.map_or(1, |n| max_side_factor(h, w, n));
    let (data, hp, wp) = if factor > 1 {
        downscale(&decoded.data, h, w, 3, factor)
    } else {
        (decoded.data, h, w)
    };
    // A block of the downscaled mask is used only when every pixel in it is.
    let mask_p: Option<Vec<bool>> = mask.map(|m| {
        if factor > 1 {
            let plane: Vec<f32> = m.data.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
            downscale(&plane, h, w, 1, factor).0.iter().map(|&v| v >= 1.0).collect()
        } else {
            m.data.clone()
        }
    });
    let data = if reference {
        reference_srgb_stretch(&data, mask_p.as_deref())
    } else {
        data
    };
    let t_read = t0.elapsed().as_secs_f64();

    let params = Params {
        water_types: types,
        veiling_light: match (reuse, opts.veiling_light) {
            (_, Some(a)) => Some(a.map(|v| v as f32)),
            (Some(r), None) => Some(r.veiling_light),
            (None, None) => None,
        },
        guided_radius: opts.guided_radius,
        guided_eps: opts.guided_eps,
        sphere_points: opts.sphere_points,
        threads: None,
        max_memory: opts.max_memory,
    };
    let image = ImageRef::new(&data, hp, wp)?;
    let input = Input {
        image,
        mask: mask_p.as_deref(),
        water_mask: None,
    };
    let t1 = Instant::now();
    let res = restore(&input, &params)?;
    let t_restore = t1.elapsed().as_secs_f64();
    drop(data);

    let t2 = Instant::now();
    fs::create_dir_all(&job.dir)
        .map_err(|e| CliError::new(Kind::Write, format!("cannot create {}: {e}", job.dir.display())))?;
    let image_path = job.dir.join(format!("{}.{}", job.name, opts.format.extension()));
    let t_path = job.dir.join(format!("{}_t.png", job.name));
    let tc_path = job.dir.join(format!("{}_t_color.png", job.name));
    let mut tx = Transaction::new();
    write_image(&mut tx, &image_path, &res.image, hp, wp, opts.format, opts.bits, !reference)?;
    write_transmission(&mut tx, &t_path, &res.transmission, hp, wp)?;
    write_transmission_color(&mut tx, &tc_path, &res.transmission, hp, wp)?;
    let source = Source {
        kind: if opts.linear { "linear" } else { "srgb" },
        format: decoded.format,
        bits: decoded.bits,
        height: h,
        width: w,
        orientation: decoded.orientation,
        processed_height: hp,
        processed_width: wp,
    };
    let paths = OutputPaths {
        image: &image_path,
        transmission: &t_path,
        transmission_color: &tc_path,
    };
    let seconds = Seconds {
        read: t_read,
        restore: t_restore,
        write: t2.elapsed().as_secs_f64(),
        total: t0.elapsed().as_secs_f64(),
    };
    let mut side = sidecar(&job.input, &paths, &source, &res, opts, seconds);
    if opts.stream && opts.reuse_estimates.is_some() {
        if let Some(obj) = side.as_object_mut() {
            obj.insert("reused_estimates".into(), Value::Bool(reuse.is_some()));
        }
    }
    let mut bytes = serde_json::to_vec_pretty(&side)
        .map_err(|e| CliError::new(Kind::Internal, format!("sidecar: {e}")))?;
    bytes.push(b'\n');
    write_bytes(&mut tx, &sidecar_path, &bytes)?;
    tx.commit();
    Ok(Outcome::Done(
        Box::new(side),
        Estimates {
            water_type: res.water_type,
            veiling_light: res.veiling_light,
        },
    ))
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

fn load_run_mask(opts: &Options, err: &mut dyn Write) -> Result<Option<Mask>, u8> {
    match &opts.mask {
        None => Ok(None),
        Some(p) => load_mask(p, opts).map(Some).map_err(|e| {
            report(err, opts.json_errors, None, &e);
            e.kind.exit_code()
        }),
    }
}

/// Batch mode: every input is processed; returns the largest exit code.
pub fn run_batch(opts: &Options, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    let mask = match load_run_mask(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    let (jobs, errors) = collect_jobs(&opts.inputs, &opts.outdir);
    let mut code = 0u8;
    for (p, e) in &errors {
        report(err, opts.json_errors, Some(p), e);
        code = code.max(e.kind.exit_code());
    }
    for job in &jobs {
        match process(job, opts, mask.as_ref(), None) {
            Ok(Outcome::Done(side, est)) => {
                if !opts.quiet {
                    let img = side
                        .pointer("/outputs/image")
                        .and_then(Value::as_str)
                        .unwrap_or("");
                    let secs = side.pointer("/seconds/total").and_then(Value::as_f64).unwrap_or(0.0);
                    let _ = writeln!(
                        out,
                        "{} -> {img} (water type {}, {secs:.2} s)",
                        job.input.display(),
                        est.water_type.name
                    );
                }
            }
            Ok(Outcome::Skipped(s)) => {
                if !opts.quiet {
                    let _ = writeln!(out, "{}: skipped ({} exists)", job.input.display(), s.display());
                }
            }
            Err(e) => {
                report(err, opts.json_errors, Some(&job.input), &e);
                code = code.max(e.kind.exit_code());
            }
        }
        let _ = out.flush();
    }
    code
}

/// Stream mode: one image path per line of `input`, one JSON line per frame
/// on `out` (the sidecar, `{"skipped": ...}` or an error object), flushed at
/// once; a bad frame never stops the loop. With `--reuse-estimates N` the
/// water type and veiling light of the last estimating frame are reused for
/// the next N - 1 frames. Returns 0 at the end of the input (or the code of
/// a bad `--mask`).
pub fn run_stream(opts: &Options, input: &mut dyn BufRead, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    let mask = match load_run_mask(opts, err) {
        Ok(m) => m,
        Err(code) => return code,
    };
    let every = opts.reuse_estimates.unwrap_or(1);
    let mut last: Option<Estimates> = None;
    let mut since = 0usize;
    let mut line = Vec::new();
    loop {
        line.clear();
        match input.read_until(b'\n', &mut line) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) => {
                let e = CliError::new(Kind::Input, format!("cannot read stdin: {e}"));
                report(err, opts.json_errors, None, &e);
                break;
            }
        }
        let result = match std::str::from_utf8(&line) {
            Err(_) => Err((None, CliError::new(Kind::Input, "input line is not valid UTF-8"))),
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
                let reuse = last.as_ref().filter(|_| since < every);
                match process(&job, opts, mask.as_ref(), reuse) {
                    Ok(o) => Ok((job.input, o, reuse.is_some())),
                    Err(e) => Err((Some(job.input), e)),
                }
            }
        };
        let json = match result {
            Ok((_, Outcome::Done(side, est), reused)) => {
                if reused {
                    since += 1;
                } else {
                    last = Some(est);
                    since = 1;
                }
                *side
            }
            Ok((p, Outcome::Skipped(s), _)) => serde_json::json!({
                "input": p.to_string_lossy(),
                "skipped": "sidecar exists",
                "sidecar": s.to_string_lossy(),
            }),
            Err((p, e)) => {
                report(err, opts.json_errors, p.as_deref(), &e);
                e.to_json(p.as_deref().map(|p| p.to_string_lossy()).as_deref())
            }
        };
        let _ = writeln!(out, "{json}");
        let _ = out.flush();
    }
    0
}
