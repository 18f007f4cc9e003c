//! The one table of options: every parameter of the method and every option
//! of the two commands (`uwhl restore`, `uwhl-rs restore`), with its
//! keyword (the name of `restore`'s argument and of the sidecar's
//! `parameters` key), command flag, value kind and valid range, default,
//! help text, and the faces that take it.
//!
//! The binary's parser and `--help`, the Python command's argparse parser,
//! the Python keyword defaults of `restore` and the checks of
//! `uwhl_rs._core.Params` all read this table (docs/CLI.md). Adding an
//! option means one row here plus its use.

pub use crate::method::params::{DEFAULT_EPS, DEFAULT_MAX_MEMORY, DEFAULT_SPHERE_POINTS, DEFAULT_T_SCALE};
/// Default largest accepted input, in pixels (300 megapixels).
pub const DEFAULT_MAX_PIXELS: u64 = 300_000_000;
/// Default JPEG quality.
pub const DEFAULT_QUALITY: u64 = 95;
/// The smallest `--max-side` (the method needs 4x4 pixels).
pub const MIN_MAX_SIDE: u64 = 4;
/// The most worker threads accepted.
pub const MAX_THREADS: u64 = 1024;

/// Which commands take an option. The method's keywords of `restore` are
/// marked by [`Spec::method`], independently of the faces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Faces {
    /// both commands, same spelling, same default
    Both,
    /// `uwhl restore` only (needs Python: raw decoding, thread-level jobs, the contact sheet)
    Python,
    /// `uwhl-rs` only (vehicle modes)
    Rust,
}

impl Faces {
    /// The name used in docs and by the Python layer.
    pub fn name(self) -> &'static str {
        match self {
            Faces::Both => "both",
            Faces::Python => "python",
            Faces::Rust => "rust",
        }
    }
}

/// What values an option takes, with its valid range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// a switch (no value)
    Flag,
    /// an integer in `min..=max`
    Int {
        /// smallest accepted value
        min: u64,
        /// largest accepted value
        max: u64,
    },
    /// one of the integers
    IntOf(&'static [u64]),
    /// a finite number greater than `gt`
    Float {
        /// exclusive lower bound
        gt: f64,
        /// inclusive upper bound (infinity: none)
        le: f64,
    },
    /// one of the names
    Choice(&'static [&'static str]),
    /// a byte count > 0 with an optional suffix K, M, G, T (powers of 1024)
    Bytes,
    /// a file path
    Path,
    /// an integer >= 0 or `auto` (= 0)
    Subsample,
    /// three numbers R,G,B, each in (0, 1]
    Rgb,
    /// repeatable: Jerlov names or `NAME:BETA_BR:BETA_BG`, comma lists allowed
    WaterTypes,
    /// where a batch runs: `local`, `local:N` or a Dask scheduler's address
    /// (`tcp://HOST:PORT`, `tls://...`, or `HOST:PORT`)
    Address,
    /// repeatable: `KEY=VALUE`
    KeyValue,
    /// a frame size `WxH`, each side in 4..=65535
    Size,
}

impl Kind {
    /// The kind's name for the Python layer.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Flag => "flag",
            Kind::Int { .. } | Kind::IntOf(_) => "int",
            Kind::Float { .. } => "float",
            Kind::Choice(_) => "choice",
            Kind::Bytes => "bytes",
            Kind::Path => "path",
            Kind::Subsample => "subsample",
            Kind::Rgb => "rgb",
            Kind::WaterTypes => "water_types",
            Kind::Address => "address",
            Kind::KeyValue => "key_value",
            Kind::Size => "size",
        }
    }
}

/// An option's default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Default {
    /// none: absent, or computed from the image (documented in the help)
    None,
    /// a switch that is off
    Off,
    /// an integer
    Int(u64),
    /// a number
    Float(f64),
    /// a name (of a [`Kind::Choice`])
    Name(&'static str),
}

/// Where an option appears in `--help`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    /// what is written
    Output,
    /// how inputs are read
    Input,
    /// parameters of the method
    Method,
    /// threads, memory, jobs
    Resources,
    /// how the command runs (stream, errors, quiet)
    Mode,
}

impl Group {
    /// The heading of the group in `--help`.
    pub fn title(self) -> &'static str {
        match self {
            Group::Output => "output",
            Group::Input => "input",
            Group::Method => "method (defaults: docs/METHOD.md)",
            Group::Resources => "resources",
            Group::Mode => "mode",
        }
    }
}

/// One option.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spec {
    /// keyword argument (Python) and `parameters` key of the sidecar
    pub key: &'static str,
    /// long flag, with its dashes
    pub flag: &'static str,
    /// short flag, if any
    pub short: Option<char>,
    /// placeholder of the value in `--help`
    pub metavar: &'static str,
    /// values taken
    pub kind: Kind,
    /// default
    pub default: Default,
    /// one-line meaning (more lines are joined with spaces)
    pub help: &'static str,
    /// heading in `--help`
    pub group: Group,
    /// commands that take it
    pub faces: Faces,
    /// a keyword of `restore` / `Sequence` (the method's parameters)
    pub method: bool,
}

const JERLOV_HELP: &str = "candidate water types: Jerlov names (I IA IB II III 1C 3C 5C 7C 9C) or \
NAME:BETA_BR:BETA_BG; repeatable or comma lists (default: all ten)";

/// Every option, in `--help` order.
pub const OPTIONS: &[Spec] = &[
    // output
    Spec { key: "format", flag: "--format", short: None, metavar: "FMT", kind: Kind::Choice(&["jpg", "png", "tiff"]),
        default: Default::Name("jpg"), help: "corrected photo as jpg (8-bit), png (8 or 16-bit) or tiff (16-bit)",
        group: Group::Output, faces: Faces::Both, method: false },
    Spec { key: "bits", flag: "--bits", short: None, metavar: "8|16", kind: Kind::IntOf(&[8, 16]),
        default: Default::None, help: "bits per sample of png/tiff outputs (default: png 8, tiff 16; jpg is 8)",
        group: Group::Output, faces: Faces::Both, method: false },
    Spec { key: "quality", flag: "--quality", short: None, metavar: "Q", kind: Kind::Int { min: 1, max: 100 },
        default: Default::Int(DEFAULT_QUALITY), help: "JPEG quality 1-100",
        group: Group::Output, faces: Faces::Both, method: false },
    Spec { key: "overwrite", flag: "--overwrite", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "redo inputs whose sidecar exists (default: skip them)",
        group: Group::Output, faces: Faces::Both, method: false },
    Spec { key: "contact_sheet", flag: "--contact-sheet", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "also write NAME_sheet.png: every water type's restoration side by side, \
labelled with its score, the chosen one framed, the water region overlaid on the input",
        group: Group::Output, faces: Faces::Python, method: false },
    Spec { key: "report", flag: "--report", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "after the batch, write OUTDIR/report/index.html: thumbnails, water types, \
the sequence, flagged photos first (uwhl report)",
        group: Group::Output, faces: Faces::Python, method: false },
    Spec { key: "ifdo", flag: "--ifdo", short: None, metavar: "HEADER", kind: Kind::Path,
        default: Default::None, help: "after the batch, write OUTDIR/ifdo.yaml (ifdo.json for a .json HEADER): the \
iFDO of the corrected photos, with the set's fields from the HEADER file (uwhl ifdo)",
        group: Group::Output, faces: Faces::Python, method: false },
    Spec { key: "every", flag: "--every", short: None, metavar: "N", kind: Kind::Int { min: 1, max: u32::MAX as u64 },
        default: Default::None, help: "videos: instead of a restored video, write every N-th frame as a photo \
NAME_00h01m02s345.jpg (its time in the video) with its maps and sidecar",
        group: Group::Output, faces: Faces::Python, method: false },
    Spec { key: "video_codec", flag: "--video-codec", short: None, metavar: "CODEC",
        kind: Kind::Choice(&["h264", "hevc", "prores", "ffv1", "mjpeg", "input"]),
        default: Default::Name("h264"), help: "codec of a restored video: h264 (8- or 10-bit as the input), hevc, \
prores (.mov), ffv1 (lossless, .mkv/.mov/.avi), mjpeg, or input: the input's codec when it can be written",
        group: Group::Output, faces: Faces::Python, method: false },
    Spec { key: "video_quality", flag: "--video-quality", short: None, metavar: "CRF", kind: Kind::Int { min: 0, max: 51 },
        default: Default::Int(18), help: "h264/hevc constant rate factor 0-51, lower is better (0 lossless, 18 \
visually lossless)",
        group: Group::Output, faces: Faces::Python, method: false },
    // input
    Spec { key: "transfer", flag: "--transfer", short: None, metavar: "CURVE",
        kind: Kind::Choice(&["bt709", "srgb", "gamma22", "gamma28", "linear"]),
        default: Default::None, help: "transfer curve of video and raw-frame samples, undone before and applied \
after the restoration: bt709 (also BT.601 and BT.2020 SDR), srgb, gamma22, gamma28, linear (default: a video's \
tag, else bt709)",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "preprocess", flag: "--preprocess", short: None, metavar: "MODE", kind: Kind::Choice(&["none", "reference"]),
        default: Default::Name("none"), help: "none: sRGB decoded to linear; reference: the reference code's \
preprocessing of METHOD §2 (sRGB kept, pulled stretch)",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "linear", flag: "--linear", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "the input values are already linear (float TIFFs always are)",
        group: Group::Input, faces: Faces::Rust, method: false },
    Spec { key: "half_size", flag: "--half-size", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "raw files: demosaic at half size (4x faster)",
        group: Group::Input, faces: Faces::Python, method: false },
    Spec { key: "max_side", flag: "--max-side", short: None, metavar: "N", kind: Kind::Int { min: MIN_MAX_SIDE, max: u32::MAX as u64 },
        default: Default::None, help: "block-average the input so its longer side is at most N; a mask block \
is used if all its pixels are, a water-mask block is water if at least half its pixels are",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "max_pixels", flag: "--max-pixels", short: None, metavar: "N", kind: Kind::Int { min: 1, max: u64::MAX },
        default: Default::Int(DEFAULT_MAX_PIXELS), help: "largest accepted input, in pixels",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "mask", flag: "--mask", short: None, metavar: "PATH", kind: Kind::Path,
        default: Default::None, help: "image of the input's size: nonzero = use the pixel for estimation, \
zero = ignore it (e.g. a color chart); in a JPEG, at least half its brightest value",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "water_mask", flag: "--water-mask", short: None, metavar: "PATH", kind: Kind::Path,
        default: Default::None, help: "image of the input's size: nonzero = water region VL (replaces detection); \
in a JPEG, at least half its brightest value",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "distance", flag: "--distance", short: None, metavar: "TEMPLATE", kind: Kind::Path,
        default: Default::None, help: "each input's distance map, e.g. 'depth/{stem}.tif' ({stem}: the input's \
name without its extension, {name}: with it): .npy or float TIFF in metres, 16-bit PNG or TIFF in millimetres, \
NaN, 0 or 65535 mm = unknown, any size of the input's aspect; the water is fitted from it (METHOD §13); a photo without a \
readable map is restored without and flagged distance_missing",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "altitude", flag: "--altitude", short: None, metavar: "SOURCE", kind: Kind::Path,
        default: Default::None, help: "distance from the camera's altitude over a flat seabed (METHOD §13.7): metres for \
every photo, a navigation CSV (columns altitude and file or time, optional pitch and roll in degrees; by time, \
interpolated between records at most 10 s apart), or xmp (the photo's iFDO field image-meters-above-ground); \
not with a distance map",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "distance_kind", flag: "--distance-kind", short: None, metavar: "KIND", kind: Kind::Choice(&["range", "depth"]),
        default: Default::Name("range"), help: "what --distance's maps measure: range, along each pixel's ray; depth, \
along the camera's axis, as photogrammetry exports it (Metashape, COLMAP), turned into range with the lens (--fov, or \
the EXIF) and the window (--port); METHOD §13.7",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "fov", flag: "--fov", short: None, metavar: "DEG", kind: Kind::Float { gt: 0.0, le: 170.0 },
        default: Default::None, help: "with --altitude, or with --distance-kind's depth: the lens's horizontal field \
of view in air across the photo's width, degrees (default: from the EXIF focal length)",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "port", flag: "--port", short: None, metavar: "PORT", kind: Kind::Choice(&["flat", "dome"]),
        default: Default::Name("flat"), help: "with --altitude, or with --distance-kind's depth: the housing's window; flat: \
refraction narrows the field of view in water; dome: it does not",
        group: Group::Input, faces: Faces::Both, method: false },
    Spec { key: "water_from", flag: "--water-from", short: None, metavar: "DIR", kind: Kind::Path,
        default: Default::None, help: "restore with the water fitted on the photos of DIR that had a distance \
(the ratios of their sidecars' median attenuation, each fit weighted by how narrow its range is; each photo keeps its own \
veiling light); not with a water type given",
        group: Group::Method, faces: Faces::Both, method: false },
    // method
    Spec { key: "water_types", flag: "--water-type", short: None, metavar: "TYPES", kind: Kind::WaterTypes,
        default: Default::None, help: JERLOV_HELP, group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "veiling_light", flag: "--veiling-light", short: None, metavar: "R,G,B", kind: Kind::Rgb,
        default: Default::None, help: "a given veiling light A (linear, each in (0, 1]); default: estimated",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "t_scale", flag: "--t-scale", short: None, metavar: "X", kind: Kind::Float { gt: 0.0, le: 1.0 },
        default: Default::Float(DEFAULT_T_SCALE), help: "scale of the haze-line transmission t~ (METHOD §4.6): t_B of the \
nearest object of each haze-line; in (0, 1]",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "method", flag: "--method", short: None, metavar: "PROFILE", kind: Kind::Choice(&["revised", "paper"]),
        default: Default::Name("revised"), help: "revised: white balance of the restored radiance, shades-of-gray \
type choice, haze floor 3C, fast selection (METHOD §12); paper: the paper's method bit for bit (display stretch, \
gray-world choice with the t_R rule, exhaustive selection)",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "white_balance", flag: "--white-balance", short: None, metavar: "WB",
        kind: Kind::Choice(&["stretch", "gray_world", "shades_of_gray", "white_patch"]),
        default: Default::None, help: "how the radiance is displayed: stretch (METHOD §8), or gains from the \
object pixels' gray_world / shades_of_gray / white_patch color, then exposure (METHOD §12.1); default: the profile's",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "fallback", flag: "--fallback", short: None, metavar: "MODE",
        kind: Kind::Choice(&["none", "input_balance"]),
        default: Default::None, help: "where the restoration cannot be trusted: none, or input_balance: blend \
the colours toward a shades-of-gray balance of the input where confidence is low, and flag the photo unreliable \
(METHOD §12.5); default: the profile's (revised input_balance, paper none)",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "type_choice", flag: "--type-choice", short: None, metavar: "RULE",
        kind: Kind::Choice(&["gray_world", "shades_of_gray", "central"]),
        default: Default::None, help: "how the water type is chosen: gray_world of the stretched image with the \
t_R rule (METHOD §9), the least chromatic shades_of_gray color of the radiance, or central: of the three types \
shades_of_gray scores best, the one whose displayed colours are nearest the other two (METHOD §12.2); default: the profile's",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "haze_floor", flag: "--haze-floor", short: None, metavar: "TYPE",
        kind: Kind::Choice(&["none", "I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]),
        default: Default::None, help: "estimate the transmission with ratios at least this Jerlov type's \
(clearer types' haze-lines are dominated by red noise; the recovery keeps each type's own, METHOD §12.3); \
none: each type's own; default: the profile's (revised 3C, paper none)",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "selection", flag: "--selection", short: None, metavar: "MODE", kind: Kind::Choice(&["exhaustive", "fast"]),
        default: Default::None, help: "exhaustive: every type restored and scored at full resolution; \
fast: types scored on a ~1024 px copy, uncertain ones re-scored at full size; default: the profile's \
(revised fast, paper exhaustive)",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "guided_radius", flag: "--guided-radius", short: None, metavar: "N", kind: Kind::Int { min: 0, max: u32::MAX as u64 },
        default: Default::None, help: "guided-filter radius (default round(min(H, W) / 4))",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "guided_eps", flag: "--guided-eps", short: None, metavar: "X", kind: Kind::Float { gt: 0.0, le: f64::INFINITY },
        default: Default::Float(DEFAULT_EPS), help: "guided-filter regulariser",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "guided_subsample", flag: "--guided-subsample", short: None, metavar: "S|auto", kind: Kind::Subsample,
        default: Default::Int(1), help: "guided-filter subsampling: 1 the exact filter; S >= 2 He and Sun's fast \
guided filter on S x S blocks (for video and sequences: t_B within ~4e-4 on average); auto (= 0) max(1, radius / 32)",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "sphere_points", flag: "--sphere-points", short: None, metavar: "N", kind: Kind::Int { min: 1, max: crate::method::sphere::MAX_POINTS as u64 },
        default: Default::Int(DEFAULT_SPHERE_POINTS as u64), help: "haze-line clusters",
        group: Group::Method, faces: Faces::Both, method: true },
    Spec { key: "reuse_estimates", flag: "--reuse-estimates", short: None, metavar: "N", kind: Kind::Int { min: 1, max: i64::MAX as u64 },
        default: Default::None, help: "sequence mode for the frames of one video or dive (inputs in the order \
given, folders by name, or stream lines): choose the water type and estimate the veiling light on every N-th \
restored input and reuse them in between",
        group: Group::Method, faces: Faces::Both, method: false },
    Spec { key: "reuse_water_mask", flag: "--reuse-water-mask", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "with --reuse-estimates: reuse the estimating input's water region too \
(a camera that holds its attitude; skips the water detection)",
        group: Group::Method, faces: Faces::Both, method: false },
    Spec { key: "scene_cut", flag: "--scene-cut", short: None, metavar: "X", kind: Kind::Float { gt: 0.0, le: 1.0 },
        default: Default::None, help: "in a sequence, estimate afresh when a frame's colours differ from the \
previous frame's (a cut) or the last estimate's (a drift) by more than X, 0-1 (METHOD §10; default 0.3 for videos \
and raw frames, 1 = never for photo sequences)",
        group: Group::Method, faces: Faces::Both, method: false },
    Spec { key: "smoothing", flag: "--smoothing", short: None, metavar: "W", kind: Kind::Float { gt: 0.0, le: 1.0 },
        default: Default::None, help: "in a sequence, a scheduled or drift estimate moves the veiling light W of \
the way to the new value; a cut takes it whole (METHOD §10; default 0.5 for videos and raw frames, 1 for photo \
sequences)",
        group: Group::Method, faces: Faces::Both, method: false },
    // resources
    Spec { key: "threads", flag: "--threads", short: None, metavar: "N", kind: Kind::Int { min: 1, max: MAX_THREADS },
        default: Default::None, help: "worker threads per restore (default: all cores); results do not depend on N",
        group: Group::Resources, faces: Faces::Both, method: true },
    Spec { key: "max_memory", flag: "--max-memory", short: None, metavar: "BYTES", kind: Kind::Bytes,
        default: Default::None, help: "peak memory of the process per input, checked from the header before \
decoding (suffixes K, M, G, T; default: 16G, or what the machine, its cgroup or ulimit -v gives if less)",
        group: Group::Resources, faces: Faces::Both, method: true },
    Spec { key: "dask", flag: "--dask", short: None, metavar: "ADDRESS", kind: Kind::Address,
        default: Default::None, help: "run the batch on a Dask cluster: a scheduler's address (tcp://HOST:PORT) or \
local:N, a local cluster of N worker processes (docs/SCALE.md); inputs and OUTDIR may then be fsspec URLs \
(s3://, gs://, ...)",
        group: Group::Resources, faces: Faces::Python, method: false },
    Spec { key: "storage_option", flag: "--storage-option", short: None, metavar: "KEY=VALUE", kind: Kind::KeyValue,
        default: Default::None, help: "an fsspec storage option for URL inputs and outputs (repeatable), e.g. \
endpoint_url=http://127.0.0.1:9000, anon=true, profile=survey; values true/false/null and numbers are read as such",
        group: Group::Resources, faces: Faces::Python, method: false },
    Spec { key: "jobs", flag: "--jobs", short: Some('j'), metavar: "N", kind: Kind::Int { min: 1, max: 1024 },
        default: Default::Int(1), help: "inputs restored at once (1: one input is written while the next is restored)",
        group: Group::Resources, faces: Faces::Python, method: false },
    // mode
    Spec { key: "stream", flag: "--stream", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "read image paths from stdin, one per line; one JSON line per frame on \
stdout; a bad frame never stops the loop",
        group: Group::Mode, faces: Faces::Rust, method: false },
    Spec { key: "raw_frames", flag: "--raw-frames", short: None, metavar: "WxH", kind: Kind::Size,
        default: Default::None, help: "read raw frames of WxH pixels from stdin (see --pix-fmt) as one sequence; \
-o - writes the restored frames to stdout in the same format, -o DIR each frame's outputs and a JSON line",
        group: Group::Mode, faces: Faces::Rust, method: false },
    Spec { key: "pix_fmt", flag: "--pix-fmt", short: None, metavar: "FMT", kind: Kind::Choice(&["rgb24", "rgb48le"]),
        default: Default::Name("rgb24"), help: "with --raw-frames: rgb24 (8 bits a sample) or rgb48le (16 bits, \
little-endian), FFmpeg's names",
        group: Group::Mode, faces: Faces::Rust, method: false },
    Spec { key: "json_errors", flag: "--json-errors", short: None, metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "report each error as one JSON object on stderr",
        group: Group::Mode, faces: Faces::Both, method: false },
    Spec { key: "quiet", flag: "--quiet", short: Some('q'), metavar: "", kind: Kind::Flag,
        default: Default::Off, help: "no progress lines and no summary; errors are still reported",
        group: Group::Mode, faces: Faces::Both, method: false },
];

/// The option with keyword `key`.
pub fn spec(key: &str) -> Option<&'static Spec> {
    OPTIONS.iter().find(|s| s.key == key)
}

/// A parsed value of an option.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// a switch given
    On,
    /// an integer ([`Kind::Int`], [`Kind::Bytes`], [`Kind::Subsample`])
    Int(u64),
    /// a number
    Float(f64),
    /// a name of a [`Kind::Choice`] or a path
    Text(String),
    /// R, G, B
    Rgb([f64; 3]),
    /// a frame size (width, height)
    Size(usize, usize),
}

/// Parses `WxH` (each side in 4..=65535); None for anything else.
pub fn parse_size(s: &str) -> Option<(usize, usize)> {
    let (w, h) = s.trim().to_ascii_lowercase().split_once('x').map(|(w, h)| (w.to_string(), h.to_string()))?;
    // digits only: Rust's integer parser would take a sign ("+64x+48")
    let side = |v: &str| {
        (!v.is_empty() && v.bytes().all(|b| b.is_ascii_digit()))
            .then(|| v.parse::<usize>().ok())
            .flatten()
            .filter(|n| (4..=65535).contains(n))
    };
    Some((side(&w)?, side(&h)?))
}

/// Parses a byte count with an optional suffix K, M, G, T (powers of 1024;
/// `KiB`, `MB` and the like are read the same way). None for anything else.
pub fn parse_bytes(s: &str) -> Option<u64> {
    let s = s.trim();
    let split = s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
    let (digits, suffix) = s.split_at(split);
    let n: u64 = digits.parse().ok()?;
    let shift = match suffix.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 0,
        "K" | "KB" | "KIB" => 10,
        "M" | "MB" | "MIB" => 20,
        "G" | "GB" | "GIB" => 30,
        "T" | "TB" | "TIB" => 40,
        _ => return None,
    };
    n.checked_mul(1u64 << shift)
}

impl Spec {
    /// Parses the text of a value given on a command line (not for
    /// [`Kind::Flag`], which takes none, nor [`Kind::WaterTypes`], whose
    /// items are parsed by the command). The error names the flag, the value
    /// and what is accepted.
    pub fn parse(&self, text: &str) -> Result<Value, String> {
        let bad = |why: String| format!("{}: {text:?} {why}", self.flag);
        let t = text.trim();
        match self.kind {
            Kind::Flag | Kind::WaterTypes => Ok(Value::Text(text.to_string())),
            Kind::Int { min, max } => match t.parse::<u64>() {
                Ok(n) if n >= min && n <= max => Ok(Value::Int(n)),
                Ok(n) if n > max && max >= u64::from(u32::MAX) => Err(bad(format!("is over {max}"))),
                _ if max >= u64::from(u32::MAX) => Err(bad(format!("is not an integer >= {min}"))),
                _ => Err(bad(format!("is not an integer in {min}..{max}"))),
            },
            Kind::IntOf(values) => match t.parse::<u64>() {
                Ok(n) if values.contains(&n) => Ok(Value::Int(n)),
                _ => Err(bad(format!(
                    "is not one of {}",
                    values.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")
                ))),
            },
            Kind::Float { gt, le } => match t.parse::<f64>() {
                Ok(x) if x.is_finite() && x > gt && x <= le => Ok(Value::Float(x)),
                _ if le.is_finite() => Err(bad(format!("is not a number in ({gt}, {le}]"))),
                _ => Err(bad(format!("is not a finite number > {gt}"))),
            },
            Kind::Choice(names) => {
                let lower = t.to_ascii_lowercase();
                let alias = match (self.key, lower.as_str()) {
                    ("format", "jpeg") => "jpg",
                    ("pix_fmt", "rgb48") => "rgb48le",
                    ("video_codec", "h265" | "x265") => "hevc",
                    ("video_codec", "x264" | "avc") => "h264",
                    ("format", "tif") => "tiff",
                    (_, other) => other,
                };
                names
                    .iter()
                    .find(|n| n.eq_ignore_ascii_case(alias))
                    .map(|n| Value::Text((*n).to_string()))
                    .ok_or_else(|| bad(format!("is not one of {}", names.join(", "))))
            }
            Kind::Bytes => parse_bytes(t)
                .filter(|&b| b > 0)
                .map(Value::Int)
                .ok_or_else(|| bad("is not a byte count > 0 (e.g. 2000000000, 512M, 4G)".into())),
            Kind::Path => {
                if t.is_empty() {
                    Err(bad("is not a path".into()))
                } else {
                    Ok(Value::Text(text.to_string()))
                }
            }
            Kind::Address => {
                let port = |p: &str| p.parse::<u16>().is_ok_and(|n| n > 0);
                let ok = match t.split_once(':') {
                    None => t == "local",
                    Some(("local", n)) => n.parse::<u64>().is_ok_and(|n| (1..=1024).contains(&n)),
                    Some((_, rest)) if rest.starts_with("//") => {
                        let hostport = &rest[2..];
                        hostport.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && port(p))
                    }
                    Some((h, p)) => !h.is_empty() && port(p),
                };
                if ok {
                    Ok(Value::Text(t.to_string()))
                } else {
                    Err(bad("is not local, local:N (1..1024 worker processes) or a scheduler address \
(tcp://HOST:PORT)".into()))
                }
            }
            Kind::Size => parse_size(t)
                .map(|(w, h)| Value::Size(w, h))
                .ok_or_else(|| bad("is not WIDTHxHEIGHT with each side in 4..65535 (e.g. 1920x1080)".into())),
            Kind::KeyValue => match t.split_once('=') {
                Some((k, _)) if !k.trim().is_empty() => Ok(Value::Text(t.to_string())),
                _ => Err(bad("is not KEY=VALUE".into())),
            },
            Kind::Subsample => match t {
                "auto" => Ok(Value::Int(0)),
                _ => t
                    .parse::<u64>()
                    .map(Value::Int)
                    .map_err(|_| bad("is not an integer >= 0 or auto".into())),
            },
            Kind::Rgb => {
                let parts: Vec<&str> = t.split(|c: char| c == ',' || c.is_whitespace()).filter(|p| !p.is_empty()).collect();
                let mut out = [0.0f64; 3];
                if parts.len() != 3 {
                    return Err(bad("is not three numbers R,G,B".into()));
                }
                for (o, p) in out.iter_mut().zip(parts) {
                    *o = p.parse().map_err(|_| bad("is not three numbers R,G,B".into()))?;
                }
                if out.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 1.0)) {
                    return Err(bad("has a component outside (0, 1]".into()));
                }
                Ok(Value::Rgb(out))
            }
        }
    }

    /// The default as a command line would write it ("" for none).
    pub fn default_text(&self) -> String {
        match self.default {
            Default::None | Default::Off => String::new(),
            Default::Int(n) if self.kind == Kind::Bytes && n % (1 << 30) == 0 => format!("{}G", n >> 30),
            Default::Int(n) => n.to_string(),
            Default::Float(x) => x.to_string(),
            Default::Name(s) => s.to_string(),
        }
    }

    /// The help line with its default appended (when it has one and the
    /// text does not state it).
    pub fn help_with_default(&self) -> String {
        let d = self.default_text();
        if d.is_empty() || self.help.contains("(default") {
            self.help.to_string()
        } else {
            format!("{} (default {d})", self.help)
        }
    }
}

/// The `Options:` part of a `--help` text for `face`, grouped, wrapped at
/// `width` columns: what both commands print for their options.
pub fn help_text(face: Faces, width: usize) -> String {
    let mut out = String::new();
    let groups = [Group::Output, Group::Input, Group::Method, Group::Resources, Group::Mode];
    for g in groups {
        let rows: Vec<&Spec> = OPTIONS
            .iter()
            .filter(|s| s.group == g && (s.faces == Faces::Both || s.faces == face))
            .collect();
        if rows.is_empty() {
            continue;
        }
        out.push_str(g.title());
        out.push_str(":\n");
        for s in rows {
            let mut head = match s.short {
                Some(c) => format!("  -{c}, {}", s.flag),
                None => format!("      {}", s.flag),
            };
            if !s.metavar.is_empty() {
                head.push(' ');
                head.push_str(s.metavar);
            }
            let indent = 27;
            let body = wrap(&s.help_with_default(), width.saturating_sub(indent).max(20));
            let mut lines = body.into_iter();
            if head.len() + 2 <= indent {
                let first = lines.next().unwrap_or_default();
                out.push_str(&format!("{head:<indent$}{first}\n"));
            } else {
                out.push_str(&head);
                out.push('\n');
            }
            for l in lines {
                out.push_str(&format!("{:indent$}{l}\n", ""));
            }
        }
    }
    out
}

fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut cur = String::new();
    for word in text.split_whitespace() {
        if !cur.is_empty() && cur.len() + 1 + word.len() > width {
            lines.push(std::mem::take(&mut cur));
        }
        if !cur.is_empty() {
            cur.push(' ');
        }
        cur.push_str(word);
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

/// The checks that concern several options at once, made by both commands
/// before any input is read; the error is the usage message.
pub fn check_combination(
    format: &str,
    bits: Option<u64>,
    reuse_estimates: Option<u64>,
    reuse_water_mask: bool,
    linear: bool,
    preprocess: &str,
    names: Names,
) -> Result<(), String> {
    let n = |key: &str| names.of(key);
    if reuse_water_mask && reuse_estimates.is_none() {
        return Err(format!("{} needs {} N", n("reuse_water_mask"), n("reuse_estimates")));
    }
    if format == "jpg" && bits == Some(16) {
        return Err(format!("{} 16 needs {} png or tiff (JPEG holds 8 bits)", n("bits"), n("format")));
    }
    if linear && preprocess == "reference" {
        return Err(format!(
            "{} reference is the METHOD §2 treatment of sRGB inputs; it cannot be used with {}",
            n("preprocess"),
            n("linear")
        ));
    }
    Ok(())
}

/// The checks of the distance options together (METHOD §13), made by both
/// commands before any input is read: one source of distance, none with
/// a sequence (it reuses one water for its frames; a distance fits each
/// photo's own), depth along the axis only of a distance map, and the lens
/// and the window (`port`: given, not defaulted) only with `--altitude` or
/// depth along the axis.
#[allow(clippy::too_many_arguments)]
pub fn check_distance(
    distance: bool,
    altitude: bool,
    fov: bool,
    depth: bool,
    reuse_estimates: bool,
    port: bool,
    names: Names,
) -> Result<(), String> {
    let n = |key: &str| names.of(key);
    if depth && !distance {
        return Err(format!("{} depth describes the maps of {}: give both", n("distance_kind"), n("distance")));
    }
    if distance && altitude {
        return Err(format!("{} and {} are two sources of distance: give one", n("distance"), n("altitude")));
    }
    if (distance || altitude) && reuse_estimates {
        let by = if distance { n("distance") } else { n("altitude") };
        return Err(format!("{by} fits each photo's water: it does not go with {}", n("reuse_estimates")));
    }
    if fov && !altitude && !depth {
        return Err(format!("{} is the lens of {} or of {} depth: give one", n("fov"), n("altitude"), n("distance_kind")));
    }
    if port && !altitude && !depth {
        return Err(format!("{} is the window of {} or of {} depth: give one", n("port"), n("altitude"), n("distance_kind")));
    }
    Ok(())
}

/// A dive's water (`--water-from`) is the water type: both commands
/// refuse it with water types given, before any input is read.
pub fn check_water(water_from: bool, water_types: bool, names: Names) -> Result<(), String> {
    if water_from && water_types {
        return Err(format!("{} gives the water type: it does not go with {}", names.of("water_from"), names.of("water_types")));
    }
    Ok(())
}

/// The usage error of an unknown short option, in both commands: the whole
/// `word` it began (`-dash.mp4`, not `-d`), and for a word that looks like
/// a file name (a dot, or a path that is there, a dangling link too) the
/// two ways to give it as one.
pub fn unknown_short_said(word: &str) -> String {
    let named = word.chars().count() > 2 && (word.contains('.') || std::fs::symlink_metadata(word).is_ok());
    let hint = if named { format!(" (a file whose name starts with '-': write ./{word}, or put it after --)") } else { String::new() };
    format!("invalid option '{word}'{hint}")
}

/// How a message names an option: by its command-line flag or by its
/// Python keyword (the option table's two faces).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Names {
    /// `--bits`, as the commands print it
    Flags,
    /// `bits`, as `restore_file` and `FileSettings` take it
    Keywords,
}

impl Names {
    /// The name of the option `key` in this face (the key itself when the
    /// table has no such row).
    pub fn of(self, key: &str) -> String {
        match (self, spec(key)) {
            (Names::Flags, Some(s)) => s.flag.to_string(),
            _ => key.to_string(),
        }
    }
}

/// The exit codes of both commands (docs/CLI.md), defined with the failure kinds.
pub use crate::error::{exit_code, EXIT_CODES};

/// The exit-code table as `--help` prints it.
pub fn exit_code_text() -> String {
    let mut s = String::from("exit codes (with several inputs, every input is processed and the largest code is returned):\n");
    for (code, _, what) in EXIT_CODES {
        s.push_str(&format!("  {code:<4} {what}\n"));
    }
    s
}

/// Where a method option's value reaches [`Params`](crate::method::params::Params):
/// the Python keywords of `restore` and the binary's parsed flags both go
/// through this one function, so the option table, the field and its use
/// are all a new option touches.
impl crate::method::params::Params {
    /// Sets the method parameter `key` (a row of `crate::files::options::OPTIONS`
    /// with `method: true`, other than `water_types`) to a value of its
    /// kind: where a Python keyword's value and the binary's parsed flag
    /// reach `Params` (the binary through `files::settings::Settings::set`). Ranges
    /// that depend on the image are checked by `check_params` when
    /// `restore` runs.
    pub fn set(&mut self, key: &str, v: &crate::files::options::Value) -> crate::error::Result<()> {
        use crate::files::options::Value as V;
        let bad = || crate::error::Error::Param {
            name: crate::files::options::spec(key).map_or("parameter", |s| s.key),
            msg: format!("{v:?} is not a value of this parameter"),
        };
        let size = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
        match (key, v) {
            ("veiling_light", V::Rgb(a)) => {
                // checked as given: 1e308 would be inf once single precision, and be quoted so
                if a.iter().any(|x| !(x.is_finite() && *x > 0.0 && *x <= 1.0)) {
                    return Err(crate::error::Error::Param {
                        name: "veiling_light",
                        msg: format!("{a:?}: every component must be a finite number in (0, 1]"),
                    });
                }
                self.veiling_light = Some(a.map(|x| x as f32));
            }
            ("guided_radius", V::Int(n)) => self.guided_radius = Some(size(*n)),
            ("guided_eps", V::Float(x)) => self.guided_eps = *x,
            ("guided_eps", V::Int(n)) => self.guided_eps = *n as f64,
            ("sphere_points", V::Int(n)) => self.sphere_points = size(*n),
            ("threads", V::Int(n)) => self.threads = Some(size(*n)),
            ("max_memory", V::Int(n)) => self.max_memory = *n,
            ("selection", V::Text(t)) => self.selection = Some(crate::method::params::Selection::from_name(t)?),
            ("guided_subsample", V::Int(n)) => self.guided_subsample = size(*n),
            ("t_scale", V::Float(x)) => self.t_scale = *x,
            ("t_scale", V::Int(n)) => self.t_scale = *n as f64,
            ("t_scale", _) => return Err(bad()),
            ("method", V::Text(t)) => self.method = crate::method::profile::Method::from_name(t)?,
            ("white_balance", V::Text(t)) => self.white_balance = Some(crate::method::profile::WhiteBalance::from_name(t)?),
            ("type_choice", V::Text(t)) => self.type_choice = Some(crate::method::profile::TypeChoice::from_name(t)?),
            ("fallback", V::Text(t)) => self.fallback = Some(crate::method::profile::Fallback::from_name(t)?),
            ("haze_floor", V::Text(t)) => self.haze_floor = Some(crate::method::params::haze_floor_from_name(t)?),
            _ => return Err(bad()),
        }
        Ok(())
    }

    /// The method parameter `key` as the sidecar's `parameters` records it
    /// (docs/OUTPUTS.md): the value asked for, the profile's steps as
    /// resolved (`Params::steps`). None for `water_types` and
    /// `veiling_light`, which the files layer echoes as given, and for a key
    /// that is not a method parameter. Beside [`Params::set`], so that a new
    /// method option is recorded by the row, the field and this arm.
    #[cfg(any(feature = "cli", feature = "python"))]
    pub fn recorded(&self, key: &str) -> Option<serde_json::Value> {
        use serde_json::json;
        if let Some((_, name)) = self.steps().into_iter().find(|s| s.0 == key) {
            return Some(json!(name));
        }
        Some(match key {
            "guided_radius" => json!(self.guided_radius),
            "guided_eps" => json!(self.guided_eps),
            "t_scale" => json!(self.t_scale),
            "guided_subsample" => json!(self.guided_subsample),
            "sphere_points" => json!(self.sphere_points),
            "threads" => json!(self.threads),
            "max_memory" => json!(self.max_memory),
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combination_messages_name_options_in_the_face_asked_for() {
        let cases = [
            (("jpg", Some(16), None, false, false, "none"), "bits 16 needs format png or tiff", "--bits 16 needs --format png or tiff"),
            (("png", None, None, true, false, "none"), "reuse_water_mask needs reuse_estimates N", "--reuse-water-mask needs --reuse-estimates N"),
            (("png", None, None, false, true, "reference"), "with linear", "with --linear"),
        ];
        for ((f, b, r, w, l, p), keyword, flag) in cases {
            let k = check_combination(f, b, r, w, l, p, Names::Keywords).unwrap_err();
            assert!(k.contains(keyword) && !k.contains("--"), "{k}");
            let g = check_combination(f, b, r, w, l, p, Names::Flags).unwrap_err();
            assert!(g.contains(flag), "{g}");
        }
        assert!(check_combination("png", Some(16), Some(3), true, false, "none", Names::Flags).is_ok());
    }

    #[test]
    fn keys_and_flags_are_unique_and_spelled_alike() {
        for (i, a) in OPTIONS.iter().enumerate() {
            for b in &OPTIONS[i + 1..] {
                assert_ne!(a.key, b.key);
                assert_ne!(a.flag, b.flag);
                assert!(a.short.is_none() || a.short != b.short);
            }
            // --water-type is the one flag named in the singular (it is repeatable)
            let from_key = format!("--{}", a.key.replace('_', "-"));
            assert!(a.flag == from_key || a.key == "water_types", "{} {}", a.key, a.flag);
            assert_eq!(a.metavar.is_empty(), a.kind == Kind::Flag, "{}", a.key);
            assert_eq!(a.default == Default::Off, a.kind == Kind::Flag, "{}", a.key);
        }
    }

    #[test]
    fn defaults_are_valid_values() {
        for s in OPTIONS {
            let d = s.default_text();
            if !d.is_empty() {
                assert!(s.parse(&d).is_ok(), "{}: default {d:?} does not parse", s.key);
            }
        }
        // the default follows the machine (crate::kernels::memory::default_max_memory)
        assert_eq!(spec("max_memory").map(Spec::default_text).as_deref(), Some(""));
        assert_eq!(spec("guided_eps").map(Spec::default_text).as_deref(), Some("0.001"));
    }

    #[test]
    fn addresses_and_storage_options_parse() {
        let d = spec("dask").unwrap();
        for good in ["local", "local:1", "local:16", "tcp://10.0.0.5:8786", "tls://sched.example:8786", "sched:8786"] {
            assert_eq!(d.parse(good).ok(), Some(Value::Text(good.to_string())), "{good}");
        }
        for bad in ["", "loc", "local:0", "local:x", "tcp://host", "tcp://:8786", "host:0", "host:99999", ":8786"] {
            assert!(d.parse(bad).unwrap_err().contains("--dask"), "{bad}");
        }
        let so = spec("storage_option").unwrap();
        assert_eq!(so.parse("anon=true").ok(), Some(Value::Text("anon=true".into())));
        assert_eq!(so.parse("key=").ok(), Some(Value::Text("key=".into())));
        for bad in ["anon", "=x", " =x", ""] {
            assert!(so.parse(bad).unwrap_err().contains("KEY=VALUE"), "{bad}");
        }
    }

    #[test]
    fn values_are_checked_against_the_range() {
        let q = spec("quality").unwrap();
        assert_eq!(q.parse("95").ok(), Some(Value::Int(95)));
        for bad in ["0", "101", "-5", "x", ""] {
            let e = q.parse(bad).unwrap_err();
            assert!(e.contains("--quality") && e.contains("1..100"), "{e}");
        }
        let eps = spec("guided_eps").unwrap();
        for bad in ["0", "-1", "inf", "nan", "x"] {
            assert!(eps.parse(bad).is_err(), "{bad}");
        }
        let sub = spec("guided_subsample").unwrap();
        assert_eq!(sub.parse("auto").ok(), Some(Value::Int(0)));
        assert!(sub.parse("AUTO").is_err() && sub.parse("1.5").is_err() && sub.parse("-1").is_err());
        let vl = spec("veiling_light").unwrap();
        assert_eq!(vl.parse("0.1 0.2,0.3").ok(), Some(Value::Rgb([0.1, 0.2, 0.3])));
        assert!(vl.parse("0,0.2,0.3").is_err() && vl.parse("0.1,0.2").is_err());
        let f = spec("format").unwrap();
        assert_eq!(f.parse("TIF").ok(), Some(Value::Text("tiff".into())));
        assert!(f.parse("gif").is_err());
        let m = spec("max_memory").unwrap();
        assert_eq!(m.parse("512M").ok(), Some(Value::Int(512 << 20)));
        assert!(m.parse("0").is_err() && m.parse("lots").is_err());
    }

    #[test]
    fn exit_codes_are_distinct_and_found_by_name() {
        for (i, (c, n, _)) in EXIT_CODES.iter().enumerate() {
            assert_eq!(exit_code(n), *c);
            assert!(EXIT_CODES[i + 1..].iter().all(|(c2, n2, _)| c2 != c && n2 != n));
        }
        assert_eq!((exit_code("ok"), exit_code("interrupted"), exit_code("no such kind")), (0, 130, 6));
    }

    #[test]
    fn byte_suffixes() {
        assert_eq!(parse_bytes("1024"), Some(1024));
        assert_eq!(parse_bytes("2K"), Some(2048));
        assert_eq!(parse_bytes("3GiB"), Some(3 << 30));
        assert_eq!(parse_bytes("1x"), None);
        assert_eq!(parse_bytes("99999999999T"), None);
    }

    #[test]
    fn help_lists_each_option_of_the_face_once() {
        let rust = help_text(Faces::Rust, 100);
        let py = help_text(Faces::Python, 100);
        for s in OPTIONS {
            let n = |t: &str| t.matches(&format!("{} ", s.flag)).count() + t.matches(&format!("{}\n", s.flag)).count();
            let (want_r, want_p) = match s.faces {
                Faces::Both => (1, 1),
                Faces::Rust => (1, 0),
                Faces::Python => (0, 1),
            };
            assert_eq!((n(&rust), n(&py)), (want_r, want_p), "{}", s.flag);
        }
        assert!(rust.contains("(default 0.001)") && rust.contains("default: 16G, or what the machine"));
    }
}
