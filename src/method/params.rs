//! The parameters and results of [`restore`](crate::restore): what a caller
//! gives (the image, its masks, [`Params`]) and gets back
//! ([`Restoration`]), the defaults that depend on the image, the up-front
//! memory estimate, and the checks made before any work.

use crate::error::{Error, Result};
use crate::method::image::{check_mask, ImageRef};
use crate::method::profile::{Fallback, Method, TypeChoice, WhiteBalance};
use crate::method::recover::Recovery;
use crate::method::water::{jerlov_types, validate_types, WaterType};
use rayon::prelude::*;

/// Default guided-filter regulariser (METHOD §6).
pub const DEFAULT_EPS: f64 = 1e-3;
/// Default scale of t~ (METHOD §4.6).
pub const DEFAULT_T_SCALE: f64 = 0.9;
/// Default number of haze-line clusters (METHOD §4.3).
pub const DEFAULT_SPHERE_POINTS: usize = 500;
/// Default working-memory limit: 16 GiB.
pub const DEFAULT_MAX_MEMORY: u64 = crate::kernels::memory::CEILING;

/// How the water type is chosen (METHOD §9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Selection {
    /// Every candidate type is restored at full resolution and scored
    /// (METHOD §9 as written).
    #[default]
    Exhaustive,
    /// The types are scored on a copy whose longer side is about
    /// `FAST_SIDE` (see `fast_factor`): one pixel (the centre) of every s x s block, s =
    /// ceil(max(H, W) / 1024) (at most min(H, W) / 4), with its water region and mask, and the
    /// full-resolution veiling light. Where the copy's choice (METHOD §9 on
    /// the copy) is uncertain, up to 3 of its best surviving
    /// types are scored again at full resolution and METHOD §9 chooses among
    /// them (within 1.5x of the copy's best score, or within 0.03 of the
    /// exclusion threshold: METHOD §9, fast selection); the
    /// chosen type is restored exactly as the exhaustive mode restores it. Reported scores and exclusions are full-resolution ones for the
    /// re-scored types and the copy's for the others. Images whose longer
    /// side is at most 1024 are processed exhaustively.
    Fast,
}

impl Selection {
    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Selection::Exhaustive => "exhaustive",
            Selection::Fast => "fast",
        }
    }

    /// The selection called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "exhaustive" => Ok(Selection::Exhaustive),
            "fast" => Ok(Selection::Fast),
            other => Err(Error::Param {
                name: "selection",
                msg: format!("must be \"exhaustive\" or \"fast\"; got {other:?}"),
            }),
        }
    }
}

/// Longer side (about) of the copy on which [`Selection::Fast`] scores the types.
pub const FAST_SIDE: usize = 1024;

/// Block factor of the copy [`Selection::Fast`] scores on (1: no copy).
/// At most min(H, W) / MIN_SIDE: a long thin image (10000x4) would
/// otherwise give a copy thinner than the method can restore; it is
/// scored on a shorter copy, or exhaustively.
pub fn fast_factor(h: usize, w: usize) -> usize {
    let thin = h.min(w) / crate::method::image::MIN_SIDE;
    h.max(w).div_ceil(FAST_SIDE).min(thin).max(1)
}

/// Parameters of [`restore`](crate::restore); `Default` gives docs/METHOD.md's defaults.
#[derive(Debug, Clone)]
pub struct Params {
    /// candidate water types (METHOD §1); default: the ten Jerlov types
    pub water_types: Vec<WaterType>,
    /// a given veiling light A (each component in (0, 1]); default: estimated (METHOD §3)
    pub veiling_light: Option<[f32; 3]>,
    /// guided-filter radius; default round(min(H, W) / 4) (METHOD §6)
    pub guided_radius: Option<usize>,
    /// guided-filter eps, > 0; default 1e-3 (METHOD §6)
    pub guided_eps: f64,
    /// number of haze-line clusters; default 500 (METHOD §4.3)
    pub sphere_points: usize,
    /// worker threads; None = rayon's global pool (all cores)
    pub threads: Option<usize>,
    /// working-memory limit in bytes, checked before anything large is allocated
    pub max_memory: u64,
    /// how the candidate types are scored, exhaustive or fast; default the
    /// profile's (revised fast, paper exhaustive; METHOD §9, §12)
    pub selection: Option<Selection>,
    /// guided-filter subsampling factor s: 1 (default) = the exact filter
    /// of METHOD §6; s >= 2 = He and Sun's fast guided filter, (a, b) computed
    /// on samples at the centres of s x s blocks and interpolated back (METHOD §6, subsampled guided filter);
    /// 0 = automatic, `auto_subsample` of the radius
    pub guided_subsample: usize,
    /// the scale of t~, in (0, 1]: the t_B of the nearest object of each
    /// haze-line; default 0.9 (METHOD §4.6)
    pub t_scale: f64,
    /// the profile whose steps are used where none is given (METHOD §12); default revised
    pub method: Method,
    /// how the radiance is displayed; default the profile's (METHOD §8, §12.1)
    pub white_balance: Option<WhiteBalance>,
    /// how the water type is chosen; default the profile's (METHOD §9, §12.2)
    pub type_choice: Option<TypeChoice>,
    /// the haze-line floor: Some(None) none, Some(Some(name)) a Jerlov type;
    /// default the profile's (METHOD §12.3)
    pub haze_floor: Option<Option<&'static str>>,
    /// what is done where the result cannot be trusted; default the profile's (METHOD §12.5)
    pub fallback: Option<Fallback>,
}

/// Window radius, in blocks, that [`auto_subsample`] keeps at least.
pub const AUTO_SUBSAMPLE_BLOCKS: usize = 32;

/// The automatic guided-filter subsampling factor for radius r:
/// max(1, floor(r / 32)), so that the subsampled window still spans at
/// least 65 x 65 blocks (METHOD §6, subsampled guided filter).
pub fn auto_subsample(r: usize) -> usize {
    (r / AUTO_SUBSAMPLE_BLOCKS).max(1)
}

impl Default for Params {
    fn default() -> Self {
        Self {
            water_types: jerlov_types(),
            veiling_light: None,
            guided_radius: None,
            guided_eps: DEFAULT_EPS,
            sphere_points: DEFAULT_SPHERE_POINTS,
            threads: None,
            max_memory: crate::kernels::memory::default_max_memory(),
            selection: None,
            guided_subsample: 1,
            t_scale: DEFAULT_T_SCALE,
            method: Method::default(),
            white_balance: None,
            type_choice: None,
            haze_floor: None,
            fallback: None,
        }
    }
}

/// A documented fallback or decision of a [`restore`](crate::restore) call,
/// reported in [`Restoration::flags`] and the sidecar by its stable name
/// (docs/OUTPUTS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Flag {
    /// the water region VL is empty: none found, too small, or rejected as a shadow (METHOD §3)
    NoWaterRegion,
    /// A comes from the fallback of METHOD §3
    VeilingFallback,
    /// a component of A was raised to 1e-4 (METHOD §3)
    VeilingLightClamped,
    /// no exclusion threshold (0.1, halved up to 30 times) left a type, so none was excluded (METHOD §9)
    ExclusionRelaxed,
    /// VL exists but its colour covariance has no inverse: no soft matting (METHOD §5)
    MattingSkipped,
    /// a sequence frame reused the water type and A of an earlier frame (METHOD §10)
    EstimatesReused,
    /// the estimated veil exceeds the observed light at more than 30% of the
    /// object pixels: the colours are not to be trusted (METHOD §12.5)
    Unreliable,
    /// a distance map was given but not used: too little of it known, no
    /// fit, or a fit that does not explain the photo (METHOD §13)
    DistanceRejected,
    /// `--distance` named no readable map for this photo: it was restored
    /// without one (docs/OUTPUTS.md "Distance")
    DistanceMissing,
    /// A has as much red as green or blue: no water gives its veil that
    /// colour (every type attenuates red the most), so the photo was
    /// perhaps taken in air, or A is not the water's; the water type means
    /// nothing then (METHOD §3)
    VeilingLightNotWater,
    /// a channel of the input holds almost no light on the objects (fewer
    /// than 10% of them have 0.003 of it, about 10 of 255 in 8-bit sRGB)
    /// while another is exposed (10% have 0.03 of it): the water took it,
    /// and its restored colour is a guess, from noise and quantisation
    /// (METHOD §12.5)
    ChannelEmpty,
}

impl Flag {
    /// Every flag.
    pub const ALL: [Flag; 11] = [
        Flag::NoWaterRegion,
        Flag::VeilingFallback,
        Flag::VeilingLightClamped,
        Flag::ExclusionRelaxed,
        Flag::MattingSkipped,
        Flag::EstimatesReused,
        Flag::Unreliable,
        Flag::DistanceRejected,
        Flag::DistanceMissing,
        Flag::VeilingLightNotWater,
        Flag::ChannelEmpty,
    ];

    /// The stable name (sidecar, Python `Restoration.flags`).
    pub fn name(self) -> &'static str {
        match self {
            Flag::NoWaterRegion => "no_water_region",
            Flag::VeilingFallback => "veiling_fallback",
            Flag::VeilingLightClamped => "veiling_light_clamped",
            Flag::ExclusionRelaxed => "exclusion_relaxed",
            Flag::MattingSkipped => "matting_skipped",
            Flag::EstimatesReused => "estimates_reused",
            Flag::Unreliable => "unreliable",
            Flag::DistanceRejected => "distance_rejected",
            Flag::DistanceMissing => "distance_missing",
            Flag::VeilingLightNotWater => "veiling_light_not_water",
            Flag::ChannelEmpty => "channel_empty",
        }
    }
}

impl std::fmt::Display for Flag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A timed stage of a [`restore`](crate::restore) call, reported in
/// [`Restoration::timings`] by its stable name (docs/OUTPUTS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// parameter and value checks, the sphere index
    Validation,
    /// veiling light and water region (METHOD §3)
    VeilingLight,
    /// fast selection: every type scored on the sampled copy (METHOD §9)
    FastCopyScoring,
    /// the matting model (METHOD §5), the guide and its statistics (METHOD §6)
    Guide,
    /// allocating the work buffers
    WorkBuffers,
    /// the candidate types evaluated and scored (METHOD §4-9)
    Scoring,
    /// the chosen type recovered from the filtered plane kept from its scoring
    ChosenFromKept,
    /// the chosen type's haze-lines, bounds and first guided-filter pass
    ChosenFirstPass,
    /// the chosen type's second guided-filter pass and recovery
    ChosenSecondPass,
    /// the chosen type's display-stretch limits (METHOD §8)
    ChosenStretch,
    /// the outputs of the chosen type
    ChosenOutputs,
}

impl Stage {
    /// Every stage, in the order a call can run them.
    pub const ALL: [Stage; 11] = [
        Stage::Validation,
        Stage::VeilingLight,
        Stage::FastCopyScoring,
        Stage::Guide,
        Stage::WorkBuffers,
        Stage::Scoring,
        Stage::ChosenFromKept,
        Stage::ChosenFirstPass,
        Stage::ChosenSecondPass,
        Stage::ChosenStretch,
        Stage::ChosenOutputs,
    ];

    /// The stable name (Python `Restoration.timings` keys).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Validation => "validation",
            Stage::VeilingLight => "veiling_light",
            Stage::FastCopyScoring => "fast_copy_scoring",
            Stage::Guide => "guide",
            Stage::WorkBuffers => "work_buffers",
            Stage::Scoring => "scoring",
            Stage::ChosenFromKept => "chosen_from_kept",
            Stage::ChosenFirstPass => "chosen_first_pass",
            Stage::ChosenSecondPass => "chosen_second_pass",
            Stage::ChosenStretch => "chosen_stretch",
            Stage::ChosenOutputs => "chosen_outputs",
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Params {
    /// The white balance used: the one given, else the profile's.
    pub fn white_balance_used(&self) -> WhiteBalance {
        self.white_balance.unwrap_or_else(|| self.method.white_balance())
    }

    /// The type choice used: the one given, else the profile's.
    pub fn type_choice_used(&self) -> TypeChoice {
        self.type_choice.unwrap_or_else(|| self.method.type_choice())
    }

    /// The fallback used: the one given, else the profile's (METHOD §12.5).
    pub fn fallback_used(&self) -> Fallback {
        self.fallback.unwrap_or_else(|| self.method.fallback())
    }

    /// The selection used: the one given, else the profile's.
    pub fn selection_used(&self) -> Selection {
        self.selection.unwrap_or_else(|| self.method.selection())
    }

    /// The haze-line floor used, by name (None: none): the one given, else
    /// the profile's (METHOD §12.3).
    pub fn haze_floor_used(&self) -> Option<&'static str> {
        self.haze_floor.unwrap_or_else(|| self.method.haze_floor())
    }

    /// The ratios of [`Params::haze_floor_used`].
    pub fn haze_floor_ratios(&self) -> Option<[f64; 2]> {
        let name = self.haze_floor_used()?;
        crate::method::water::JERLOV.iter().find(|t| t.0 == name).map(|t| [t.1, t.2])
    }

    /// The profile and the steps used, as (keyword, name) pairs: what the
    /// sidecar and the evaluation record (METHOD §12).
    pub fn steps(&self) -> [(&'static str, &'static str); 6] {
        [
            ("method", self.method.name()),
            ("selection", self.selection_used().name()),
            ("white_balance", self.white_balance_used().name()),
            ("type_choice", self.type_choice_used().name()),
            ("haze_floor", self.haze_floor_used().unwrap_or("none")),
            ("fallback", self.fallback_used().name()),
        ]
    }

    /// The guided-filter subsampling factor used at radius `r` (METHOD §6):
    /// `guided_subsample`, with 0 resolved by [`auto_subsample`].
    pub fn subsample_at(&self, r: usize) -> usize {
        match self.guided_subsample {
            0 => auto_subsample(r),
            s => s,
        }
    }
}

/// The haze-line floor called `name`: "none" or a Jerlov type (METHOD §12.3).
pub fn haze_floor_from_name(name: &str) -> Result<Option<&'static str>> {
    if name.eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    crate::method::water::table_entry(name).map(|t| Some(t.0)).ok_or_else(|| Error::Param {
        name: "haze_floor",
        msg: format!("must be \"none\" or a Jerlov type (I IA IB II III 1C 3C 5C 7C 9C); got {name:?}"),
    })
}

/// The image and its optional masks.
#[derive(Debug, Clone, Copy)]
pub struct Input<'a> {
    /// linear RGB in [0, 1]
    pub image: ImageRef<'a>,
    /// true = use the pixel for estimation (METHOD §2); false e.g. on color charts
    pub mask: Option<&'a [bool]>,
    /// a given water region VL, used instead of detection (METHOD §3)
    pub water_mask: Option<&'a [bool]>,
}

/// Everything [`restore`](crate::restore) returns (METHOD §10).
#[derive(Debug, Clone)]
pub struct Restoration {
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// the displayed result of the chosen type: white-balanced and exposed
    /// (METHOD §12.1) or display-stretched (METHOD §8), interleaved RGB
    pub image: Vec<f32>,
    /// J after the artifact clamp, before the display (METHOD §7), interleaved RGB
    pub radiance: Vec<f32>,
    /// t_B of the chosen type (METHOD §7; with a haze floor, METHOD §12.3); -ln t_B = beta_B z
    pub transmission: Vec<f32>,
    /// the chosen water type
    pub water_type: WaterType,
    /// every evaluated type with its score (METHOD §9 or §12.2, lower is better), in input order
    pub scores: Vec<(String, f64)>,
    /// names of the types excluded by the t_R rule (METHOD §9; none under METHOD §12.2)
    pub excluded: Vec<String>,
    /// the veiling light A used
    pub veiling_light: [f32; 3],
    /// the water region VL (all false when there is none)
    pub veiling_mask: Vec<bool>,
    /// documented fallbacks and decisions, in the order they were taken
    pub flags: Vec<Flag>,
    /// how far each pixel's displayed colour can be trusted, in [0, 1]
    /// (METHOD §12.5); None when the fallback is `none`
    pub confidence: Option<Vec<f32>>,
    /// the share of object pixels where the estimated veil exceeds the
    /// observed light (METHOD §12.5); None when the fallback is `none`
    pub veil_excess: Option<f64>,
    /// the share of the shown colour taken from the input's own balance
    /// rather than the restoration (the mean blend weight of METHOD §12.5
    /// step 4: 0 none, 1 all); None when nothing is blended (the fallback
    /// `none`, or a known distance, §13.4)
    pub fallback_share: Option<f64>,
    /// with a known distance ([`crate::restore_at_distance`]): what became
    /// of it and the water fitted from it (METHOD §13); None without
    pub distance: Option<crate::method::pipeline::given::DistanceUse>,
    /// the guided-filter radius used
    pub guided_radius: usize,
    /// the guided-filter subsampling factor used at full resolution (1: exact)
    pub guided_subsample: usize,
    /// wall-clock seconds of each stage, in order (for profiling; not part
    /// of the result proper and different from run to run)
    pub timings: Vec<(Stage, f64)>,
}

impl Restoration {
    /// Per-channel transmission maps (t_R, t_G, t_B) of the chosen type (METHOD §7).
    pub fn channel_transmissions(&self) -> [Vec<f32>; 3] {
        channel_transmissions(&self.transmission, &self.water_type)
    }
}

/// Per-channel transmission maps (t_R, t_G, t_B) from a clamped t_B (METHOD §7).
pub fn channel_transmissions(t_b: &[f32], wt: &WaterType) -> [Vec<f32>; 3] {
    let rec = Recovery::new([1.0; 3], wt);
    let per: Vec<[f32; 3]> = t_b.par_iter().map(|&t| rec.channel_t(t)).collect();
    [
        per.iter().map(|v| v[0]).collect(),
        per.iter().map(|v| v[1]).collect(),
        per.iter().map(|v| v[2]).collect(),
    ]
}

/// Default guided-filter radius: round(min(H, W) / 4), halves away from zero (METHOD §6).
pub fn default_radius(h: usize, w: usize) -> usize {
    (h.min(w) as f64 / 4.0).round() as usize
}

/// Working memory of [`restore`](crate::restore) in bytes beyond the input image, estimated
/// up front from the image size (documented in the README):
/// `H W (88 + 17 holes)` bytes, holes = the estimation mask has false pixels.
/// Per pixel: 12 B guide + 36 B guide statistics (window means and inverse
/// covariances, f32) + 1 B water region, image-wide; 12 B (J, first the
/// refined transmission) + 16 B (t_LB and cluster in its first half, then
/// the guided filter's a, b) + 4 B (the filtered plane q) for the type being
/// evaluated; 4 B for the q kept of the best type so far (so that the
/// chosen type is not filtered again); 3 B for row buffers,
/// order-statistics brackets and allocator slack (measured: 86.7 B per
/// pixel at 12 MP). With masked-out pixels, 17 B for the fill of METHOD
/// §4.5. The outputs (29 B per pixel) are allocated after the per-type
/// buffers and the guide statistics are freed. [`Selection::Fast`] scores
/// its copy before the full-size buffers exist (`check_params` adds the
/// copy's share anyway, where there is a copy).
pub fn memory_estimate(h: usize, w: usize, holes: bool) -> u64 {
    let n = (h as u64).saturating_mul(w as u64);
    let per_px = 88 + if holes { 17 } else { 0 };
    n.saturating_mul(per_px)
}

/// The working memory a restoration of an `h` x `w` image with `params`
/// needs ([`memory_estimate`], the sphere index of its `sphere_points`, and
/// the sampled copy of fast selection where there is one): what
/// `max_memory` is checked against.
pub fn needed_memory(h: usize, w: usize, holes: bool, params: &Params) -> u64 {
    let mut needed = memory_estimate(h, w, holes).saturating_add(crate::method::sphere::index_bytes(params.sphere_points));
    let s = fast_factor(h, w);
    // a copy exists only for several types on an image larger than it
    if params.selection_used() == Selection::Fast && s > 1 && params.water_types.len() >= 2 {
        needed += memory_estimate(h.div_ceil(s), w.div_ceil(s), holes);
    }
    needed
}

/// The checks of `params` that need no image: the water types, eps,
/// t_scale, A and the number of sphere points in range (a sequence and a
/// manifest's entry are checked with them before any frame or image).
pub fn check_values(params: &Params) -> Result<()> {
    validate_types(&params.water_types)?;
    crate::method::sphere::check_points(params.sphere_points)?;
    if !(params.guided_eps.is_finite() && params.guided_eps > 0.0) {
        return Err(Error::Param {
            name: "guided_eps",
            msg: format!("{} is not a finite number > 0", params.guided_eps),
        });
    }
    if !(params.t_scale.is_finite() && params.t_scale > 0.0 && params.t_scale <= 1.0) {
        return Err(Error::Param {
            name: "t_scale",
            msg: format!("{} is not a number in (0, 1]", params.t_scale),
        });
    }
    if let Some(a) = params.veiling_light {
        if a.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 1.0)) {
            return Err(Error::Param {
                name: "veiling_light",
                msg: format!("{a:?}: every component must be a finite number in (0, 1]"),
            });
        }
    }
    Ok(())
}

/// Checks `params` against `input` before any work: the values of
/// [`check_values`], radius and subsampling factor in range, the masks of
/// the right size, and the memory estimate within `max_memory`.
pub(crate) fn check_params(input: &Input, params: &Params) -> Result<()> {
    let img = &input.image;
    check_values(params)?;
    if let Some(r) = params.guided_radius {
        if r > img.height.max(img.width) {
            return Err(Error::Param {
                name: "guided_radius",
                msg: format!(
                    "{r} is larger than the image ({}x{})",
                    img.height, img.width
                ),
            });
        }
    }
    if params.guided_subsample > img.height.max(img.width) {
        return Err(Error::Param {
            name: "guided_subsample",
            msg: format!(
                "{} is larger than the image ({}x{})",
                params.guided_subsample, img.height, img.width
            ),
        });
    }
    check_mask("mask", input.mask, img.len(), 1)?;
    check_mask("water_mask", input.water_mask, img.len(), 0)?;
    let holes = input.mask.is_some_and(|m| m.iter().any(|&b| !b));
    let needed = needed_memory(img.height, img.width, holes, params);
    if needed > params.max_memory {
        return Err(Error::Memory {
            height: img.height,
            width: img.width,
            needed,
            limit: params.max_memory,
        });
    }
    // within the budget but more than the system gives (a budget set above
    // the machine): an error for this image, not an aborted process
    if !crate::kernels::memory::can_allocate(needed) {
        return Err(Error::Unavailable {
            height: img.height,
            width: img.width,
            needed,
        });
    }
    Ok(())
}

