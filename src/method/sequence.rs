//! Sequence mode: the frames of one video or dive restored in order, with
//! the water type and the veiling light A estimated on one frame and reused
//! for the next ones (the water does not change from frame to frame; a
//! frame then costs one type instead of ten), and the full-resolution work
//! buffers kept from frame to frame ([`Buffers`], METHOD §10, sequence mode).
//!
//! ```
//! use uwhl::Sequence;
//! use uwhl::{ImageRef, Input, Params};
//! let mut data = Vec::new();
//! for y in 0..16 {
//!     for x in 0..16 {
//!         let p = if y < 5 { [0.05, 0.3, 0.45] } else if x % 4 < 2 { [0.3, 0.35, 0.3] } else { [0.1, 0.25, 0.3] };
//!         data.extend_from_slice(&p);
//!     }
//! }
//! let frame = Input { image: ImageRef::new(&data, 16, 16).unwrap(), mask: None, water_mask: None };
//! let mut seq = Sequence::new(Params::default());
//! let first = seq.restore(&frame).unwrap(); // every type scored
//! let next = seq.restore(&frame).unwrap(); // the first frame's type and A
//! assert_eq!(next.water_type.name, first.water_type.name);
//! assert_eq!(next.scores.len(), 1);
//! ```

use crate::error::Result;
use crate::kernels::util::zip3;
use crate::method::params::{Flag, Input, Params, Restoration};
use crate::method::pipeline::{restore_with, Buffers};
use crate::method::water::WaterType;


/// What a frame's estimation gave, reused for the following frames.
#[derive(Debug, Clone)]
pub struct Estimates {
    /// the chosen water type
    pub water_type: WaterType,
    /// the veiling light A
    pub veiling_light: [f32; 3],
    /// the water region (reused with `reuse_water_mask`)
    water_mask: Vec<bool>,
    /// the size of the frame it came from
    shape: (usize, usize),
}

/// Why a frame of a [`Sequence`] estimated the water type and A, or reused
/// them (METHOD §10, sequence mode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// the first frame after [`Sequence::new`] or [`Sequence::reset`]
    First,
    /// the refresh schedule (`refresh_every`) was due
    Scheduled,
    /// the frame's colours differ from the previous frame's by more than
    /// `cut_threshold`: a cut, estimated afresh (never smoothed)
    Cut,
    /// the frame's colours drifted from the estimating frame's by more than
    /// `cut_threshold` (a slow change of water or light)
    Drift,
    /// the estimates were reused
    Reused,
}

impl Decision {
    /// The stable name (sidecars, Python).
    pub fn name(self) -> &'static str {
        match self {
            Decision::First => "first",
            Decision::Scheduled => "scheduled",
            Decision::Cut => "cut",
            Decision::Drift => "drift",
            Decision::Reused => "reused",
        }
    }
}

/// The scene-cut threshold of videos and raw frames (`--scene-cut`'s
/// default there; METHOD §10): a rendered pan through one water changed
/// by at most 0.04 from frame to frame, cuts to other water by 0.53-0.87.
pub const VIDEO_SCENE_CUT: f32 = 0.3;
/// The smoothing of A of videos and raw frames (`--smoothing`'s default
/// there; METHOD §10): on rendered pans it lowered the 95th percentile of
/// a fixed patch's frame-to-frame change by 9-19%, at the cost of about
/// one estimate's interval of lag when the water changes gradually.
pub const VIDEO_SMOOTHING: f32 = 0.5;

/// Bins per axis of a frame's chromaticity histogram ([`Signature`]).
const BINS: usize = 16;
/// At most about this many pixels are sampled for a frame's signature.
const SIGNATURE_SAMPLES: usize = 16_384;
/// Pixels darker than this (R + G + B, linear) carry no chromaticity.
const DARK: f32 = 0.03;

/// A frame's colour signature (METHOD §10, scene changes): the histogram of
/// the chromaticities (r, g) = (R, G) / (R + G + B) of a regular sample of
/// its pixels, 16 x 16 bins over [0, 1]^2, normalised to sum 1; pixels
/// darker than R + G + B = 0.03 are left out (their chromaticity is noise).
/// It does not change with exposure and changes little when the camera
/// pans through one water, but a cut to other water moves its mass.
#[derive(Debug, Clone, PartialEq)]
pub struct Signature {
    hist: Vec<f32>,
}

impl Signature {
    /// The signature of an interleaved RGB image (`data.len() == 3 h w`).
    pub fn of(data: &[f32], height: usize, width: usize) -> Self {
        let n = height * width;
        // one stride for rows and columns: about SIGNATURE_SAMPLES pixels
        let stride = ((n as f64 / SIGNATURE_SAMPLES as f64).sqrt().ceil() as usize).max(1);
        let mut counts = vec![0u32; BINS * BINS];
        let mut total = 0u32;
        for y in (0..height).step_by(stride) {
            for x in (0..width).step_by(stride) {
                let i = 3 * (y * width + x);
                let Some(&[r, g, b]) = data.get(i..i + 3) else {
                    continue;
                };
                let sum = r + g + b;
                if !sum.is_finite() || sum < DARK {
                    continue;
                }
                let bin = |v: f32| ((v / sum * BINS as f32) as usize).min(BINS - 1);
                if let Some(n) = counts.get_mut(bin(r.max(0.0)) * BINS + bin(g.max(0.0))) {
                    *n += 1;
                }
                total += 1;
            }
        }
        let scale = if total > 0 { 1.0 / total as f32 } else { 0.0 };
        Self { hist: counts.iter().map(|&c| c as f32 * scale).collect() }
    }

    /// How different two signatures are: 1 minus their histogram
    /// intersection, in [0, 1] (0: the same colours; 1: none in common, or
    /// a frame with no pixel bright enough to tell).
    pub fn change(&self, other: &Signature) -> f32 {
        let common: f32 = self.hist.iter().zip(&other.hist).map(|(a, b)| a.min(*b)).sum();
        (1.0 - common).clamp(0.0, 1.0)
    }
}

/// A restorer for the frames of one sequence (see the module documentation).
///
/// Frame k (counting from 0 after [`Sequence::new`] or [`Sequence::reset`])
/// runs the whole method with the given [`Params`] (water type selection,
/// water region and A estimated unless given) when it is the first, when
/// `refresh_every` frames have passed since the last estimate (never when
/// it is 0, the default), and, with `cut_threshold` > 0, when its colour
/// [`Signature`] differs from the previous frame's by more than that (a
/// cut) or from the last estimating frame's (a drift). Every other frame
/// uses the last estimate's water type and A (METHOD §9 and METHOD §3 are
/// skipped; METHOD §4-8 run on the frame) and, with `reuse_water_mask`, its
/// water region (a frame of another size detects its own). With
/// `smoothing` w < 1, a scheduled or drift estimate moves A only w of the
/// way from the A in use to the new estimate, and the frame is restored
/// with that A and the new type; a first frame and a cut take the new
/// estimate as it is (METHOD §10, sequence mode). A failed frame changes
/// nothing. The same frames give the same bits as [`crate::restore`]
/// called with the water type and A the frame used.
#[derive(Debug)]
pub struct Sequence {
    params: Params,
    /// re-estimate every this many frames (0: only on the first frame)
    pub refresh_every: usize,
    /// reuse the estimating frame's water region as well (saves the water
    /// detection; right for a camera that holds its attitude)
    pub reuse_water_mask: bool,
    /// re-estimate when a frame's [`Signature`] differs from the previous
    /// frame's (a cut) or the last estimating frame's (a drift) by more
    /// than this, in (0, 1); 0, or 1 and above: never
    pub cut_threshold: f32,
    /// the weight of a scheduled or drift estimate of A against the A in
    /// use, in (0, 1]; 1: the new estimate as it is
    pub smoothing: f32,
    state: Option<Estimates>,
    since: usize,
    pool: Buffers,
    /// the previous frame's signature (with `cut_threshold` > 0)
    previous: Option<Signature>,
    /// the last estimating frame's signature
    estimated: Option<Signature>,
    decision: Decision,
    change: f32,
}

impl Sequence {
    /// A sequence restored with `params`; estimates on the first frame only
    /// and re-detects the water region on every frame (change the public
    /// fields for other behaviour).
    pub fn new(params: Params) -> Self {
        Self {
            params,
            refresh_every: 0,
            reuse_water_mask: false,
            cut_threshold: 0.0,
            smoothing: 1.0,
            state: None,
            since: 0,
            pool: Buffers::kept(),
            previous: None,
            estimated: None,
            decision: Decision::First,
            change: 0.0,
        }
    }

    /// The parameters the estimating frames use.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The estimates the next frame will reuse (None before the first frame
    /// and after [`Sequence::reset`]).
    pub fn estimates(&self) -> Option<&Estimates> {
        self.state.as_ref()
    }

    /// Why the last restored frame estimated or reused, and how much its
    /// colours changed from the previous frame's ([`Signature::change`];
    /// 0 without `cut_threshold` or on a first frame).
    pub fn last_decision(&self) -> (Decision, f32) {
        (self.decision, self.change)
    }

    /// Bytes of work buffers kept between frames (32 per pixel once a frame
    /// has been restored).
    pub fn buffer_bytes(&self) -> usize {
        self.pool.bytes()
    }

    /// Forgets the estimates (the next frame estimates again, e.g. after a
    /// scene change) and frees the kept buffers.
    pub fn reset(&mut self) {
        self.state = None;
        self.since = 0;
        self.pool = Buffers::kept();
        self.previous = None;
        self.estimated = None;
    }

    /// Gives the planes of a restoration the caller is done with back to
    /// the sequence, so that the next frame of the same size writes its
    /// outputs into them instead of allocating (a video or a pipe of
    /// frames: no frame-sized allocation for the image, the radiance and
    /// t_B in steady state). Results do not depend on it.
    pub fn recycle(&mut self, res: Restoration) {
        self.pool.recycle(res);
    }

    /// Whether the next frame runs the estimation by the schedule (a cut
    /// or a drift is only known once the frame is seen).
    pub fn estimates_next(&self) -> bool {
        self.state.is_none() || (self.refresh_every > 0 && self.since >= self.refresh_every)
    }

    /// What the frame with signature `sig` does, and its change from the previous frame.
    fn decide(&self, sig: Option<&Signature>) -> (Decision, f32) {
        let change = match (sig, &self.previous) {
            (Some(s), Some(p)) => s.change(p),
            _ => 0.0,
        };
        if self.state.is_none() {
            return (Decision::First, change);
        }
        if let Some(s) = sig {
            if change > self.cut_threshold {
                return (Decision::Cut, change);
            }
            if self.estimated.as_ref().is_some_and(|e| s.change(e) > self.cut_threshold) {
                return (Decision::Drift, change);
            }
        }
        if self.refresh_every > 0 && self.since >= self.refresh_every {
            return (Decision::Scheduled, change);
        }
        (Decision::Reused, change)
    }

    /// Restores the next frame (see [`Sequence`]).
    pub fn restore(&mut self, input: &Input) -> Result<Restoration> {
        let shape = (input.image.height, input.image.width);
        let sig = (self.cut_threshold > 0.0 && self.cut_threshold < 1.0)
            .then(|| Signature::of(input.image.data, shape.0, shape.1));
        let (decision, change) = self.decide(sig.as_ref());
        let res = match decision {
            Decision::Reused => self.reuse(input, shape)?,
            _ => {
                let mut res = restore_with(input, &self.params, &mut self.pool)?;
                let smoothed = match (&self.state, decision) {
                    (Some(old), Decision::Scheduled | Decision::Drift) if self.smoothing < 1.0 => {
                        let w = self.smoothing;
                        Some(zip3(old.veiling_light, res.veiling_light, |o, r| o + w * (r - o)))
                    }
                    _ => None,
                };
                if let Some(a) = smoothed.filter(|a: &[f32; 3]| *a != res.veiling_light) {
                    // the new type with the smoothed A
                    let params = with_estimates(&self.params, &res.water_type, a);
                    let again = restore_with(input, &params, &mut self.pool)?;
                    res = Restoration { scores: res.scores, excluded: res.excluded, ..again };
                }
                self.state = Some(Estimates {
                    water_type: res.water_type.clone(),
                    veiling_light: res.veiling_light,
                    water_mask: res.veiling_mask.clone(),
                    shape,
                });
                self.since = 1;
                self.estimated.clone_from(&sig);
                res
            }
        };
        self.previous = sig;
        self.decision = decision;
        self.change = change;
        Ok(res)
    }

    /// A frame restored with the last estimates.
    fn reuse(&mut self, input: &Input, shape: (usize, usize)) -> Result<Restoration> {
        let Some(state) = self.state.as_mut() else {
            return Err(crate::error::Error::Internal("a reused frame without estimates".into()));
        };
        let params = with_estimates(&self.params, &state.water_type, state.veiling_light);
        let kept = (self.reuse_water_mask && state.shape == shape).then_some(state.water_mask.as_slice());
        let frame = Input { water_mask: input.water_mask.or(kept), ..*input };
        let mut res = restore_with(&frame, &params, &mut self.pool)?;
        if self.reuse_water_mask && kept.is_none() && input.water_mask.is_none() {
            // a frame of another size: its own water region, for this and later frames
            state.water_mask = res.veiling_mask.clone();
            state.shape = shape;
        }
        self.since += 1;
        res.flags.push(Flag::EstimatesReused);
        Ok(res)
    }
}

/// `params` for a frame restored with one water type and a given A.
fn with_estimates(params: &Params, water_type: &WaterType, a: [f32; 3]) -> Params {
    Params { water_types: vec![water_type.clone()], veiling_light: Some(a), ..params.clone() }
}
