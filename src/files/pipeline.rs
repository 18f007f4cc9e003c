//! One input's path through the files layer, the same for both commands:
//! its output names claimed (or the input skipped), the memory plan checked
//! from the header, decoding, preprocessing and `--max-side`, `restore` (or
//! a Sequence's next frame), the three encodes, the metadata carried, the
//! sidecar, and the commit with the sidecar last (docs/OUTPUTS.md).
//!
//! [`prepare`] does the reading half and [`complete`] the writing half, so
//! that a loop can write one input while it restores the next.

use crate::error::{Failure, Kind};
use crate::files::budget::{Plan, HELD_WHILE_WRITING};
use crate::files::color::{max_side_factor, reference_srgb_stretch};
use crate::files::commit::{claim, Claim, Request, Resolution, Skip};
use crate::files::decode::{decode, decode_mask, Limits};
use crate::files::encode::{encode_image, encode_transmission, encode_transmission_color, Encoding};
use crate::files::jobs::{extension, Job, RAW_EXTENSIONS, VIDEO_EXTENSIONS};
use crate::files::settings::{Preprocess, Settings};
use crate::files::sidecar::{sidecar, Estimates, OutputPaths, Seconds, Source};
use crate::kernels::filters::downscale;
use crate::method::image::ImageRef;
use crate::method::params::{Flag, Input};
use crate::method::pipeline::restore;
use crate::method::sequence::Sequence;
#[cfg(any(test, feature = "internals"))]
use crate::method::water::WaterType;
use serde_json::Value;
use std::fs::File;
use std::io::{BufRead, BufReader, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Called with an input's memory need before it is checked against the
/// budget: the overlapped loop waits there until the previous input's
/// outputs, still being written, are (see `cli::run`).
pub type Room<'a> = Option<&'a mut dyn FnMut(u64)>;

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

/// Reads a mask file (nonzero = true) under `limits`; an unreadable mask is
/// a usage error naming `flag` (it is an argument). Both commands read
/// masks here.
pub fn load_mask(path: &Path, flag: &str, limits: &Limits) -> Result<Mask, Failure> {
    // a FIFO or a device would block the open or never end the read
    crate::files::jobs::regular_file(path).map_err(|why| Failure::usage(format!("{flag} {}: {why}", path.display())))?;
    let file = File::open(path)
        .map_err(|e| Failure::usage(format!("{flag} {}: {e}", path.display())))?;
    let (data, height, width) = decode_mask(BufReader::new(file), limits).map_err(|e| {
        let kind = if e.kind == Kind::Budget { Kind::Budget } else { Kind::Usage };
        Failure::new(kind, format!("{flag} {}: {}", path.display(), e.message))
    })?;
    Ok(Mask { data, height, width })
}

/// Reads `--mask` and `--water-mask`.
pub fn load_masks(opts: &Settings) -> Result<Masks, Failure> {
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.params.max_memory,
    };
    let read = |p: &Option<PathBuf>, flag: &str| p.as_deref().map(|p| load_mask(p, flag, &limits)).transpose();
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

/// What a mask's size error adds for an input its EXIF orientation turned:
/// masks are drawn on the upright photo (both commands say it alike).
pub fn upright_said(orientation: u8) -> String {
    if orientation == 1 {
        String::new()
    } else {
        format!(" upright (after its EXIF orientation {orientation}; a mask is drawn on the upright photo)")
    }
}

/// A mask checked against the input size (upright: after its EXIF
/// `orientation`) and downscaled by `factor`: a block is true when at
/// least `need` of its pixels are (1.0 = all).
pub(crate) fn fit_mask(m: Option<&Mask>, flag: &str, (h, w, orientation): (usize, usize, u8), factor: usize, need: f32)
    -> Result<Option<Vec<bool>>, Failure> {
    let Some(m) = m else { return Ok(None) };
    if (m.height, m.width) != (h, w) {
        return Err(Failure::usage(format!(
            "{flag} is {}x{} pixels but the input is {w}x{h}{}",
            m.width,
            m.height,
            upright_said(orientation)
        )));
    }
    if factor <= 1 {
        return Ok(Some(m.data.clone()));
    }
    let plane: Vec<f32> = m.data.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
    Ok(Some(downscale(&plane, h, w, 1, factor).0.iter().map(|&v| v >= need).collect()))
}

/// The memory plan of one input, checked against `--max-memory` from its
/// header. With a [`Room`] hook (the reading side of the binary's
/// overlapped loop), an input that does not fit beside the previous one's
/// outputs, still being written, first waits until they are.
fn check_plan(h: &crate::files::decode::Header, opts: &Settings, masks: &Masks, room: Room<'_>, given: &Given<'_>) -> Result<(), Failure> {
    let plan = plan_of(h.height, h.width, h.bpp, h.is_rgb, h.oriented, opts, masks);
    // the budget bounds the process's peak: what it holds anyway counts,
    // and so does the distance (METHOD §13): the map as read (twice for
    // depth along the axis, turned into ranges on a copy) and the map at
    // the processed size that the restoration reads
    let map = |d: &crate::files::depth::DistanceMap| (d.data.len() as u64).saturating_mul(4);
    let at_size = map_at_size(&plan);
    let distance = match given {
        Given::None => 0,
        Given::Map(d) => map(d).saturating_add(at_size),
        Given::Axis(d, ..) => map(d).saturating_mul(2).saturating_add(at_size),
        Given::Floor(..) => at_size,
    };
    let need = plan.bytes().saturating_add(distance).saturating_add(crate::kernels::memory::process_base());
    if let Some(make_room) = room {
        make_room(need);
    }
    if need > opts.params.max_memory {
        return Err(Failure::new(
            Kind::Budget,
            format!(
                "{}x{} pixels need about {need} bytes, over --max-memory {} (use --max-side or raise --max-memory)",
                h.width, h.height, opts.params.max_memory
            ),
        ));
    }
    if !crate::kernels::memory::can_allocate(plan.bytes().saturating_add(distance)) {
        return Err(Failure::new(
            Kind::Budget,
            format!(
                "{}x{} pixels need about {need} bytes, more than the system gives now (free memory, a container \
                 limit or ulimit -v); use --max-side",
                h.width, h.height
            ),
        ));
    }
    Ok(())
}

/// The bytes a photo of `h` x `w` pixels decoding to `bpp` bytes a pixel
/// (`is_rgb`: three channels as decoded) plans for (METHOD §13: with the
/// map at its processed size), from its header before it is decoded, as
/// [`check_plan`] counts it then: a map this lets through fits there too,
/// and an 8-bit photo leaves the map what a 16-bit or float one would not.
/// The process's base is not in it (the map's reader adds it).
fn photo_plan_with_map(h: usize, w: usize, bpp: u64, is_rgb: bool, opts: &Settings, masks: &Masks) -> u64 {
    let plan = plan_of(h, w, bpp, is_rgb, true, opts, masks);
    plan.bytes().saturating_add(map_at_size(&plan))
}

/// The memory plan of a photo of `h` x `w` pixels decoded to `bpp` bytes a
/// pixel (`is_rgb`: already three channels; `oriented`: rotated on reading)
/// under this run's options.
fn plan_of(h: usize, w: usize, bpp: u64, is_rgb: bool, oriented: bool, opts: &Settings, masks: &Masks) -> Plan {
    Plan {
        height: h,
        width: w,
        decoded_bpp: bpp,
        decoded_is_rgb: is_rgb,
        oriented,
        factor: opts.max_side.map_or(1, |n| max_side_factor(h, w, n)),
        reference: opts.preprocess == Preprocess::Reference,
        masks: u8::from(masks.mask.is_some()) + u8::from(masks.water.is_some()),
        write_extra: 0,
        index: crate::method::sphere::index_bytes(opts.params.sphere_points),
    }
}

/// Bytes of a distance map at the processed size of `plan` (float32 metres).
fn map_at_size(plan: &Plan) -> u64 {
    let (h, w) = plan.processed();
    (h as u64).saturating_mul(w as u64).saturating_mul(4)
}

/// A restored input before anything is written.
#[derive(Debug, Clone)]
pub struct Restored {
    /// the result of `restore`
    pub res: crate::method::params::Restoration,
    /// where it came from (the sidecar's `source`)
    pub source: Source,
    /// seconds spent decoding and preprocessing
    pub t_read: f64,
    /// seconds spent in `restore`
    pub t_restore: f64,
    /// the sidecar's `distance` of a `--distance` run (METHOD §13)
    pub distance: Option<Value>,
    /// with `--altitude`: the sidecar's `distance.floor`, or why the photo
    /// has no distance
    pub floor: Option<Result<Value, String>>,
    /// with `--distance-kind depth`: the sidecar's `distance.depth` (the
    /// lens the map was turned into ranges with), or why it was not used
    pub depth: Option<Result<Value, String>>,
}

/// A distance an input is restored with (METHOD §13).
#[derive(Clone, Copy)]
pub enum Given<'a> {
    /// none
    None,
    /// a map read from a file
    Map(&'a crate::files::depth::DistanceMap),
    /// a camera over a flat seabed (`--altitude`, METHOD §13.7): the map is
    /// made at the processed size
    Floor(&'a crate::files::nav::Camera, crate::method::floor::Port),
    /// a map of depth along the camera's axis (`--distance-kind depth`),
    /// turned into ranges with the lens once the photo's size is known
    Axis(&'a crate::files::depth::DistanceMap, &'a crate::files::nav::LensOf, crate::method::floor::Port),
}

/// The note of a float image given `--preprocess reference` (the Python
/// command says the same).
pub const FLOAT_NOT_PREPROCESSED: &str =
    "the reference preprocessing does not apply to float samples (linear light): they are restored as they are";

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
    opts: &Settings,
    masks: &Masks,
    seq: Option<&mut Sequence>,
) -> Result<Restored, Failure> {
    decode_and_restore_gated(reader, opts, masks, seq, None, Given::None)
}

/// (height, width, bytes a pixel, three channels as decoded) of a photo
/// from its header (PNG, JPEG, TIFF), None when it cannot be read that way
/// (the decoder then says why).
fn photo_size(input: &Path) -> Option<(u64, u64, u64, bool)> {
    use image::ImageDecoder;
    let reader = image::ImageReader::open(input).ok()?.with_guessed_format().ok()?;
    if reader.format() == Some(image::ImageFormat::Tiff) {
        // a damaged structure is said by the decoding (decode.rs), before the tiff crate sees it
        crate::files::exif::tiff_structure(&mut std::fs::File::open(input).ok()?).ok()?;
    }
    let jpeg = reader.format() == Some(image::ImageFormat::Jpeg);
    let decoder = reader.into_decoder().ok()?;
    let (w, h) = decoder.dimensions();
    // as the decoder's own header counts it
    let (bpp, is_rgb) = crate::files::decode::decoded_layout(decoder.color_type(), jpeg);
    Some((u64::from(h), u64::from(w), bpp, is_rgb))
}

/// [`decode_and_restore`], with the memory check waiting at `gate` when given.
fn decode_and_restore_gated<R: BufRead + Seek>(
    reader: R,
    opts: &Settings,
    masks: &Masks,
    seq: Option<&mut Sequence>,
    room: Room<'_>,
    given: Given<'_>,
) -> Result<Restored, Failure> {
    let t0 = Instant::now();
    let reference = opts.preprocess == Preprocess::Reference;
    let limits = Limits {
        max_pixels: opts.max_pixels,
        max_memory: opts.params.max_memory,
    };
    let mut decoded = decode(reader, &limits, !opts.linear && !reference, |h| {
        check_plan(h, opts, masks, room, &given)
    })?;
    let (h, w) = (decoded.height, decoded.width);
    // float samples are linear: no reference stretch, sRGB curve on output
    let linear = !reference || decoded.is_float;
    let factor = opts.max_side.map_or(1, |n| max_side_factor(h, w, n));
    let mask = fit_mask(masks.mask.as_ref(), "--mask", (h, w, decoded.orientation), factor, 1.0)?;
    let water = fit_mask(masks.water.as_ref(), "--water-mask", (h, w, decoded.orientation), factor, 0.5)?;
    // the full-size values are dropped as soon as the next copy is made: a
    // shadowed binding would hold them (12 bytes a pixel of the input)
    // through the restoration, which the memory plan does not count
    let full = std::mem::take(&mut decoded.data);
    let data = if linear {
        full
    } else {
        let stretched = reference_srgb_stretch(&full, None);
        drop(full);
        stretched
    };
    let (data, hp, wp) = if factor > 1 {
        let small = downscale(&data, h, w, 3, factor);
        drop(data);
        small
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
    // a map made from the photo's size: a seabed's (`--altitude`) or a
    // depth map's turned into ranges; its sidecar record, or why not
    let derived = match given {
        Given::Axis(d, lens, port) => {
            let mut m = d.clone();
            Some(lens.to_range(&mut m, (h, w), port).map(|record| (m, record)))
        }
        Given::Floor(camera, port) => Some(crate::files::nav::floor_map(camera, port, (h, w), (hp, wp))),
        Given::None | Given::Map(_) => None,
    };
    let record = derived.as_ref().map(|r| r.as_ref().map(|(_, rec)| rec.clone()).map_err(Clone::clone));
    let (floor, depth) = match given {
        Given::Floor(..) => (record, None),
        Given::Axis(..) => (None, record),
        Given::None | Given::Map(_) => (None, None),
    };
    let distance = match (given, &derived) {
        (Given::Map(d), _) => Some(d),
        (_, Some(Ok((m, _)))) => Some(m),
        _ => None,
    };
    let res = match (seq, distance) {
        (Some(seq), _) => seq.restore(&input)?,
        (None, Some(d)) => crate::restore_at_distance(&input, &d.data, d.height, d.width, &opts.method_params())?,
        (None, None) => restore(&input, &opts.method_params())?,
    };
    let t_restore = t1.elapsed().as_secs_f64();
    let source = Source {
        kind: (if decoded.is_float || opts.linear { "linear" } else { "srgb" }).to_string(),
        format: decoded.format.to_string(),
        bits: decoded.bits,
        height: h,
        width: w,
        orientation: decoded.orientation,
        linear,
        preprocess: if linear { Preprocess::None } else { Preprocess::Reference },
        processed_height: hp,
        processed_width: wp,
        icc_profile: decoded.icc_profile.clone(),
        camera_matrix: None,
        white_balance: None,
        notes: {
            let mut n = decoded.notes.clone();
            if reference && decoded.is_float {
                n.push(FLOAT_NOT_PREPROCESSED.to_string());
            }
            n
        },
    };
    Ok(Restored {
        res,
        source,
        t_read,
        t_restore,
        distance: None,
        floor,
        depth,
    })
}

#[cfg(any(test, feature = "internals"))]
/// The fuzz target's body (`fuzz/`) and its regression test: the first byte
/// picks options (bit 0 reference preprocessing, bit 1 `--linear`, bit 2
/// `--max-side 16`, bit 3 two water types), the rest is a file decoded and
/// restored in memory with tight limits (65536 pixels, 256 MiB, one
/// thread's worth of water types in flight). Returns the restoration or the
/// error; panics only if a result breaks the output contract.
pub fn fuzz_one(data: &[u8]) -> Result<Restored, Failure> {
    let Some((&sel, file)) = data.split_first() else {
        return Err(Failure::new(Kind::Input, "empty"));
    };
    let reference = sel & 1 != 0;
    let opts = Settings {
        max_pixels: 1 << 16,
        params: crate::method::params::Params {
            max_memory: 256 << 20,
            sphere_points: 64,
            threads: Some(1),
            ..Default::default()
        },
        preprocess: if reference { Preprocess::Reference } else { Preprocess::None },
        linear: sel & 2 != 0 && !reference,
        max_side: (sel & 4 != 0).then_some(16),
        water_types: (sel & 8 != 0).then(|| {
            ["II", "7C"]
                .iter()
                .filter_map(|n| WaterType::by_name(n).ok())
                .map(|water_type| crate::files::settings::WaterChoice {
                    water_type,
                    custom: false,
                })
                .collect()
        }),
        ..Settings::default()
    };
    let r = decode_and_restore(std::io::Cursor::new(file), &opts, &Masks::default(), None)?;
    let ok = r.res.image.iter().chain(&r.res.radiance).all(|v| (0.0..=1.0).contains(v))
        && r.res.transmission.iter().all(|t| *t > 0.0 && *t <= 1.0);
    if !ok {
        return Err(Failure::new(Kind::Internal, "output outside [0, 1]"));
    }
    Ok(r)
}

#[cfg(any(test, feature = "internals"))]
/// Restores one input and writes its outputs (see [`decode_and_restore`]).
pub fn process(job: &Job, opts: &Settings, masks: &Masks, seq: Option<&mut Sequence>) -> Result<Outcome, Failure> {
    complete(job, prepare(job, opts, masks, seq, None)?, opts)
}

/// What becomes of a prepared input: skipped, or its outputs written.
pub fn complete(job: &Job, p: Prepared, opts: &Settings) -> Result<Outcome, Failure> {
    match p {
        Prepared::Skipped(s, why) => Ok(Outcome::Skipped(s, why)),
        Prepared::Restored(r) => finish(job, *r, opts),
    }
}

/// One input decoded and restored, before anything is written.
#[derive(Debug)]
pub enum Prepared {
    /// not restored: the sidecar path and why ([`Outcome::Skipped`])
    Skipped(PathBuf, Skip),
    /// restored, with its claimed output names and the time its processing started
    Restored(Box<(Restored, Claim, Instant)>),
}

impl Prepared {
    /// Bytes it holds until its outputs are written ([`HELD_WHILE_WRITING`] per pixel).
    pub fn held_bytes(&self) -> u64 {
        match self {
            Prepared::Skipped(..) => 0,
            Prepared::Restored(r) => (r.0.res.transmission.len() as u64).saturating_mul(HELD_WHILE_WRITING),
        }
    }
}

/// The suffixes of an input's outputs after `NAME`, in writing order (the
/// sidecar comes last, added by `crate::files::commit`).
pub fn output_suffixes(opts: &Settings) -> Vec<String> {
    crate::files::settings::output_suffixes(opts.format, false)
}

/// Opens an input to decode it: regular files only (a FIFO, socket or
/// device is never opened: opening a FIFO blocks).
pub fn open_input(path: &Path) -> Result<File, Failure> {
    crate::files::jobs::regular_file(path).map_err(|m| Failure::new(Kind::Input, m))?;
    let f = File::open(path).map_err(|e| Failure::new(Kind::Input, format!("cannot open: {e}")))?;
    // the Python command's words for a file of no bytes, not a format's
    if f.metadata().is_ok_and(|m| m.len() == 0) {
        return Err(Failure::new(Kind::Input, "empty file"));
    }
    Ok(f)
}

/// The first half of [`process`]: the output names claimed (or the input
/// skipped), decoding and `restore`.
pub fn prepare(job: &Job, opts: &Settings, masks: &Masks, seq: Option<&mut Sequence>, room: Room<'_>) -> Result<Prepared, Failure> {
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
        .map_err(|e| Failure::new(Kind::Write, format!("cannot claim output names in {}: {e}", job.dir.display())))?;
    let claimed = match claimed {
        Resolution::Claimed(c) => c,
        Resolution::Skipped(why, s) => return Ok(Prepared::Skipped(s, why)),
    };
    if RAW_EXTENSIONS.contains(&extension(&job.input).as_str()) {
        return Err(Failure::new(
            Kind::Input,
            "raw files are decoded by the Python command (uwhl restore); uwhl-rs reads PNG, JPEG and TIFF",
        ));
    }
    if VIDEO_EXTENSIONS.contains(&extension(&job.input).as_str()) {
        return Err(Failure::new(
            Kind::Input,
            "a video: the Python command restores video files (uwhl restore); uwhl-rs restores its frames piped \
             in with --raw-frames (docs/CLI.md)",
        ));
    }
    let file = open_input(&job.input)?;
    // METHOD §13: the input's distance map; one that cannot be read leaves
    // the photo to be restored without it, flagged
    let given = opts.distance.as_deref().map(|t| {
        match crate::files::depth::expand(t, &job.input) {
            Ok(path) => {
                // the photo's size from its header, so that a map far larger than the photo is not read
                // the map gets what the budget leaves beside the photo's own plan: one that
                // does not fit is left out (the photo restored without it, flagged), whichever
                // check would meet it, so a larger budget never fails what a smaller one restored
                let header = photo_size(&job.input);
                let photo = header.map(|(h, w, ..)| (h, w));
                let room_for_map = header.map_or(opts.params.max_memory, |(h, w, bpp, rgb)| {
                    opts.params.max_memory.saturating_sub(photo_plan_with_map(h as usize, w as usize, bpp, rgb, opts, masks))
                });
                let map = crate::files::depth::read_distance_of(&path, opts.max_pixels, room_for_map, photo)
                    .map_err(|f| format!("{}: {}", path.display(), f.message));
                (path, map)
            }
            Err(why) => (PathBuf::from(t), Err(why)),
        }
    });
    let (map, mut missing) = match &given {
        Some((_, Ok(m))) => (Some(m), None),
        Some((_, Err(why))) => (None, Some(why.clone())),
        None => (None, None),
    };
    // METHOD §13.7: depth along the axis needs the lens; without one the
    // photo is restored without distance, flagged
    let lens = match (map, opts.depth_along_axis) {
        (Some(_), true) => Some(crate::files::nav::LensOf::of(opts.fov, &job.input)),
        _ => None,
    };
    if let Some(Err(why)) = &lens {
        missing = Some(why.clone());
    }
    // METHOD §13.7: the camera over a flat seabed; without its pose or lens
    // the photo is restored without distance, flagged
    let camera = opts.altitude.as_ref().map(|src| crate::files::nav::camera_for(src, opts.fov, &job.input));
    let target = match (&camera, map, &lens) {
        (Some(Ok(c)), _, _) => Given::Floor(c, opts.port),
        (_, Some(m), Some(Ok(l))) => Given::Axis(m, l, opts.port),
        (_, Some(_), Some(Err(_))) => Given::None,
        (_, Some(m), None) => Given::Map(m),
        _ => Given::None,
    };
    let mut restored = decode_and_restore_gated(BufReader::new(file), opts, masks, seq, room, target)?;
    if let Some(src) = &opts.altitude {
        let floor = match camera {
            Some(Err(why)) => Err(why),
            _ => restored.floor.take().unwrap_or_else(|| Err("no camera".into())),
        };
        let record = restored.res.distance.as_ref().map(|d| crate::files::sidecar::distance_record(d, None));
        missing = floor.as_ref().err().cloned();
        restored.distance = crate::files::sidecar::distance_entry(record, &src.label(), missing.as_deref());
        if let (Ok(f), Some(Value::Object(o))) = (floor, restored.distance.as_mut()) {
            o.insert("floor".into(), f);
        }
        if missing.is_some() {
            restored.res.flags.push(Flag::DistanceMissing);
        }
    }
    let depth = restored.depth.take();
    if let Some(Err(why)) = &depth {
        missing = Some(why.clone());
    }
    if let Some((path, _)) = &given {
        let record = restored.res.distance.as_ref().map(|d| crate::files::sidecar::distance_record(d, None));
        restored.distance = crate::files::sidecar::distance_entry(record, &path.to_string_lossy(), missing.as_deref());
        if let (Some(m), Some(Value::Object(o))) = (map, restored.distance.as_mut()) {
            if m.out_of_range > 0 {
                o.insert("out_of_range".into(), Value::from(m.out_of_range));
            }
            if let Some(Ok(record)) = depth {
                o.insert("depth".into(), record);
            }
        }
        if missing.is_some() {
            restored.res.flags.push(Flag::DistanceMissing);
        }
    }
    Ok(Prepared::Restored(Box::new((restored, claimed, t0))))
}

/// The second half of [`process`]: the outputs and the sidecar through the
/// claim ([`write_outputs`]).
fn finish(job: &Job, (restored, claimed, t0): (Restored, Claim, Instant), opts: &Settings) -> Result<Outcome, Failure> {
    let Restored {
        res,
        source,
        t_read,
        t_restore,
        distance,
        ..
    } = restored;
    let label = job.input.to_string_lossy();
    let parameters = crate::files::sidecar::parameters(opts);
    let side = write_outputs(
        claimed,
        Outputs {
            label: &label,
            input: Some(&job.input),
            implementation: "rust",
            source: &source,
            estimates: Estimates { distance: distance.or_else(|| Estimates::of(&res).distance), ..Estimates::of(&res) },
            image: &res.image,
            transmission: &res.transmission,
            confidence: res.confidence.as_deref(),
            contact_sheet: None,
            reused: opts.reuse_estimates.map(|_| res.flags.contains(&Flag::EstimatesReused)),
            parameters: &parameters,
        },
        opts,
        Timing { read: t_read, restore: t_restore, contact_sheet: None, start: t0 },
    )?;
    Ok(Outcome::Done(Box::new(side)))
}

/// What one input's outputs are made of ([`write_outputs`]).
#[derive(Debug)]
pub struct Outputs<'a> {
    /// the input as the batch names it (the sidecar's `input`: a path, or a URL)
    pub label: &'a str,
    /// the local file whose metadata is carried into the photo; None for a
    /// frame of a video or a pipe, which has no file of its own
    pub input: Option<&'a Path>,
    /// the command: "rust" or "python"
    pub implementation: &'a str,
    /// where the input came from
    pub source: &'a Source,
    /// the restoration's estimates
    pub estimates: Estimates<'a>,
    /// the image to encode, interleaved RGB of the processed size (raw
    /// inputs: already through the camera matrix)
    pub image: &'a [f32],
    /// t_B, of the processed size
    pub transmission: &'a [f32],
    /// the confidence map of the processed size, when the method made one
    /// (METHOD §12.5); without, the claim's `_confidence.png` is omitted
    pub confidence: Option<&'a [f32]>,
    /// the contact sheet, encoded (PNG): the claim's fourth output
    pub contact_sheet: Option<&'a [u8]>,
    /// with `--reuse-estimates`: whether this input reused them
    pub reused: Option<bool>,
    /// the sidecar's `parameters` ([`crate::files::sidecar::parameters`])
    pub parameters: &'a Value,
}

/// Seconds already spent on an input, for its sidecar.
#[derive(Debug, Clone, Copy)]
pub struct Timing {
    /// decoding and preprocessing
    pub read: f64,
    /// `restore`
    pub restore: f64,
    /// making the contact sheet
    pub contact_sheet: Option<f64>,
    /// when the input's processing started
    pub start: Instant,
}

/// Encodes an input's outputs, carries the input's metadata into the photo,
/// makes the sidecar, and commits them through the claim (temporaries put
/// in place with the sidecar last: all or nothing; docs/OUTPUTS.md). The
/// one writing half of both commands. Returns the sidecar.
pub fn write_outputs(mut claimed: Claim, out: Outputs<'_>, opts: &Settings, timing: Timing) -> Result<Value, Failure> {
    let (hp, wp) = (out.source.processed_height, out.source.processed_width);
    let t2 = Instant::now();
    let paths = claimed.paths().to_vec();
    // the claim's order: image, t, t colour, confidence, [contact sheet,] sidecar
    let (image_path, t_path, tc_path, conf_slot, sheet_path, sidecar_path) = match (paths.as_slice(), out.contact_sheet) {
        ([i, t, tc, c, s], None) => (i.clone(), t.clone(), tc.clone(), c.clone(), None, s.clone()),
        ([i, t, tc, c, sheet, s], Some(_)) => (i.clone(), t.clone(), tc.clone(), c.clone(), Some(sheet.clone()), s.clone()),
        (paths, sheet) => {
            return Err(Failure::new(
                Kind::Internal,
                format!("a claim of {} outputs does not fit {} contact sheet", paths.len(), if sheet.is_some() { "a" } else { "no" }),
            ))
        }
    };
    let conf_path = out.confidence.map(|_| conf_slot);
    if out.confidence.is_none() {
        claimed.omit(3);
    }
    let enc = Encoding {
        format: opts.format,
        bits: opts.bits(),
        srgb: out.source.linear,
        quality: opts.quality,
    };
    // the three encoders (each single-threaded) run at once; the files are
    // then written in order
    let ((image_bytes, conf_bytes), (t_bytes, tc_bytes)) = rayon::join(
        || {
            rayon::join(
                || encode_image(&image_path, out.image, hp, wp, enc),
                || match (&conf_path, out.confidence) {
                    (Some(p), Some(c)) => encode_transmission(p, c, hp, wp).map(Some),
                    _ => Ok(None),
                },
            )
        },
        || {
            rayon::join(
                || encode_transmission(&t_path, out.transmission, hp, wp),
                || encode_transmission_color(&tc_path, out.transmission, hp, wp),
            )
        },
    );
    let names = OutputPaths {
        image: &image_path,
        transmission: &t_path,
        transmission_color: &tc_path,
        confidence: conf_path.as_deref(),
        contact_sheet: sheet_path.as_deref(),
    };
    // the input file's absolute path, links resolved, where it is a local
    // file the batch names by its path (a URL's input is a private copy):
    // a rerun recognises its sidecar by it whatever folder it starts in
    // (crate::files::commit, docs/OUTPUTS.md "Names already in use")
    let resolved = out
        .input
        .filter(|_| !out.label.contains("://"))
        .and_then(|p| std::fs::canonicalize(p).ok())
        .and_then(|p| p.to_str().map(str::to_owned));
    let make = |seconds: Seconds| {
        let mut side = sidecar(out.label, out.implementation, &names, out.source, &out.estimates, out.parameters, seconds);
        if let (Some(reused), Some(obj)) = (out.reused, side.as_object_mut()) {
            obj.insert("reused_estimates".into(), Value::Bool(reused));
        }
        if let (Some(r), Some(obj)) = (&resolved, side.as_object_mut()) {
            obj.insert("input_resolved".into(), Value::String(r.clone()));
        }
        side
    };
    // the input's EXIF and XMP, and the restoration's record, into the photo
    // (src/files/metadata.rs); the record is made of the sidecar's fields
    let sidecar_name = sidecar_path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    // a TIFF input is re-read whole for its tags (the EXIF parser takes the
    // whole file): at most what its pixels took when decoded (RGBA at its
    // bits) and a block of tags, memory the plan already gave this input
    let tiff_cap = (out.source.height as u64 * out.source.width as u64 * 4 * u64::from(out.source.bits.max(8)) / 8)
        .saturating_add(crate::files::exif::MAX_BLOCK);
    let (image_bytes, carried) = match out.input {
        Some(input) => crate::files::metadata::carry_from(
            input,
            image_bytes?,
            &make(Seconds::default()),
            &sidecar_name,
            wp as u32,
            hp as u32,
            tiff_cap,
        ),
        None => crate::files::metadata::carry_frame(
            image_bytes?,
            &make(Seconds::default()),
            &sidecar_name,
            wp as u32,
            hp as u32,
            out.label,
            "metadata: a frame of a video or a pipe; no file to carry metadata from (the record and an image UUID are written)",
        ),
    };
    let mut files = vec![(image_path.clone(), image_bytes), (t_path.clone(), t_bytes?), (tc_path.clone(), tc_bytes?)];
    if let (Some(p), Some(bytes)) = (&conf_path, conf_bytes?) {
        files.push((p.clone(), bytes));
    }
    if let (Some(p), Some(sheet)) = (&sheet_path, out.contact_sheet) {
        files.push((p.clone(), sheet.to_vec()));
    }
    let mut temps = Vec::with_capacity(files.len() + 1);
    for (path, bytes) in &files {
        let i = paths.iter().position(|p| p == path).unwrap_or(0);
        temps.push(write_temp(&mut claimed, i, path, bytes)?);
    }
    let seconds = Seconds {
        read: timing.read,
        restore: timing.restore,
        write: t2.elapsed().as_secs_f64(),
        contact_sheet: timing.contact_sheet,
        total: timing.start.elapsed().as_secs_f64(),
    };
    let mut side = make(seconds);
    if let Some(obj) = side.as_object_mut() {
        // "metadata" goes before "seconds"
        let secs = obj.shift_remove("seconds");
        obj.insert("metadata".into(), carried);
        if let Some(secs) = secs {
            obj.insert("seconds".into(), secs);
        }
    }
    let mut bytes = serde_json::to_vec_pretty(&side)
        .map_err(|e| Failure::new(Kind::Internal, format!("sidecar: {e}")))?;
    bytes.push(b'\n');
    temps.push(write_temp(&mut claimed, paths.len() - 1, &sidecar_path, &bytes)?);
    let dir = sidecar_path.parent().unwrap_or(Path::new(".")).to_path_buf();
    claimed
        .commit(&temps)
        .map_err(|e| Failure::new(Kind::Write, format!("cannot write the outputs of {} in {}: {e}", out.label, dir.display())))?;
    Ok(side)
}

/// Writes `bytes` into a new temporary of output `index` of the claim.
fn write_temp(claimed: &mut Claim, index: usize, path: &Path, bytes: &[u8]) -> Result<PathBuf, Failure> {
    let (tmp, mut f) = claimed
        .temp(index)
        .map_err(|e| Failure::new(Kind::Write, format!("cannot write {}: {e}", path.display())))?;
    f.write_all(bytes)
        .map_err(|e| Failure::new(Kind::Write, format!("cannot write {}: {e}", path.display())))?;
    Ok(tmp)
}

/// The core sequence of `--reuse-estimates N`: restored inputs 0, N, 2N,
/// ... estimate the water type and veiling light, the others reuse them;
/// a cut or a drift re-estimates only with `--scene-cut`, and A is
/// smoothed only with `--smoothing` (photos of a dive are not a video's
/// frames: the defaults of videos are not theirs).
pub fn sequence(opts: &Settings) -> Option<Sequence> {
    opts.reuse_estimates.map(|n| sequence_of(opts, n, 0.0, 1.0))
}

/// A sequence with the options' method, `refresh` frames between scheduled
/// estimates, and `--scene-cut` and `--smoothing` when given, else `cut`
/// and `smoothing` (the defaults of what the frames are: photos or a video's).
pub fn sequence_of(opts: &Settings, refresh: usize, cut: f32, smoothing: f32) -> Sequence {
    let mut s = Sequence::new(opts.method_params());
    s.refresh_every = refresh;
    s.reuse_water_mask = opts.reuse_water_mask;
    s.cut_threshold = opts.scene_cut.unwrap_or(cut);
    s.smoothing = opts.smoothing.unwrap_or(smoothing);
    s
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_photos_header_gives_the_bytes_its_samples_decode_to() {
        // the map's room is the budget less the photo's plan at these: an
        // 8-bit photo's 3 bytes a pixel, not a 16-bit one's 6
        let d = std::env::temp_dir().join(format!("uwhl-photo-size-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let eight = image::RgbImage::from_pixel(5, 3, image::Rgb([10, 20, 30]));
        eight.save(d.join("a.png")).unwrap();
        eight.save(d.join("a.jpg")).unwrap();
        image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(5, 3, image::Rgb([1000u16, 2000, 3000])).save(d.join("b.png")).unwrap();
        assert_eq!(photo_size(&d.join("a.png")), Some((3, 5, 3, true)));
        // a JPEG decoder holds its planes beside the output: not "already RGB"
        assert_eq!(photo_size(&d.join("a.jpg")), Some((3, 5, 3, false)));
        assert_eq!(photo_size(&d.join("b.png")), Some((3, 5, 6, true)));
        assert_eq!(photo_size(&d.join("none.png")), None);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
