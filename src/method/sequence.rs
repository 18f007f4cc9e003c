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

/// A restorer for the frames of one sequence (see the module documentation).
///
/// Frame k (counting from 0 after [`Sequence::new`] or [`Sequence::reset`])
/// runs the whole method with the given [`Params`] (water type selection,
/// water region and A estimated unless given) when k is a multiple of
/// `refresh_every` (only k = 0 when it is 0, the default); every other
/// frame uses the last such frame's water type and A (METHOD §9 and METHOD §3 are
/// skipped; METHOD §4-8 run on the frame) and, with `reuse_water_mask`, its
/// water region (a frame of another size detects its own). A failed frame
/// changes nothing. The same frames give the same bits as [`crate::restore`]
/// called with those estimates.
#[derive(Debug)]
pub struct Sequence {
    params: Params,
    /// re-estimate every this many frames (0: only on the first frame)
    pub refresh_every: usize,
    /// reuse the estimating frame's water region as well (saves the water
    /// detection; right for a camera that holds its attitude)
    pub reuse_water_mask: bool,
    state: Option<Estimates>,
    since: usize,
    pool: Buffers,
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
            state: None,
            since: 0,
            pool: Buffers::kept(),
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
    }

    /// Whether the next frame runs the estimation.
    pub fn estimates_next(&self) -> bool {
        self.state.is_none() || (self.refresh_every > 0 && self.since >= self.refresh_every)
    }

    /// Restores the next frame (see [`Sequence`]).
    pub fn restore(&mut self, input: &Input) -> Result<Restoration> {
        let shape = (input.image.height, input.image.width);
        let due = self.estimates_next();
        let state = match &mut self.state {
            Some(s) if !due => s,
            _ => {
                let res = restore_with(input, &self.params, &mut self.pool)?;
                self.state = Some(Estimates {
                    water_type: res.water_type.clone(),
                    veiling_light: res.veiling_light,
                    water_mask: res.veiling_mask.clone(),
                    shape,
                });
                self.since = 1;
                return Ok(res);
            }
        };
        let params = Params {
            water_types: vec![state.water_type.clone()],
            veiling_light: Some(state.veiling_light),
            ..self.params.clone()
        };
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
