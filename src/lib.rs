//! # uwhl — underwater single-image color restoration with haze-lines
//!
//! An implementation of Berman, Levy, Avidan & Treibitz, "Underwater Single
//! Image Color Restoration Using Haze-Lines and a New Quantitative Dataset"
//! (IEEE TPAMI 2020), as `docs/METHOD.md` describes it (its section numbers
//! are cited in the docs below as "METHOD §n").
//!
//! ```
//! use uwhl::{restore, ImageRef, Input, Params};
//! // a 16x16 scene: water on top, a two-tone object below
//! let mut data = Vec::new();
//! for y in 0..16 {
//!     for x in 0..16 {
//!         let p = if y < 5 { [0.05, 0.3, 0.45] } else if x % 4 < 2 { [0.3, 0.35, 0.3] } else { [0.1, 0.25, 0.3] };
//!         data.extend_from_slice(&p);
//!     }
//! }
//! let input = Input { image: ImageRef::new(&data, 16, 16).unwrap(), mask: None, water_mask: None };
//! let res = restore(&input, &Params::default()).unwrap();
//! assert_eq!(res.transmission.len(), 256);
//! assert!(res.image.iter().all(|v| (0.0..=1.0).contains(v)));
//! ```
//!
//! The core never panics on input data: every failure is an [`Error`].

#![cfg_attr(not(feature = "python"), forbid(unsafe_code))]
#![warn(missing_docs)]
// Vehicle-grade rules: no unwrap/expect/panic/indexing on outside data, in
// this file, every core module below and the `cli` module.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

/// Declares the stage modules: every one forbids unsafe code even when the
/// pyo3 bindings (which expand to unsafe code) are built into the crate,
/// and all are under the crate's panic lints above. They are private: the
/// API is the `pub use` list below. The feature `internals` (benches,
/// fuzzing, the Python cross-check hooks; never in release wheels) makes
/// them public.
macro_rules! stage_modules {
    ($($m:ident),* $(,)?) => {
        $(
            #[cfg(feature = "internals")]
            #[forbid(unsafe_code)]
            #[allow(missing_docs)]
            pub mod $m;
            #[cfg(not(feature = "internals"))]
            #[forbid(unsafe_code)]
            mod $m;
        )*
    };
}

stage_modules! {
    boxsum, budget, error, fastmath, filters, guided, hazelines, image, jobs, matting, params, pipeline, rank, recover,
    select, sequence, sphere, stretch, util, veiling, water,
}

/// sRGB curves, quantisation and the transmission colour map of
/// docs/OUTPUTS.md, shared by both commands.
#[forbid(unsafe_code)]
pub mod color;
/// The one table of parameters and command options (docs/CLI.md).
#[forbid(unsafe_code)]
pub mod options;
/// Method profiles and their steps (METHOD §12).
#[forbid(unsafe_code)]
pub mod profile;

/// The rendered scene of `uwhl-rs demo` (and, included by path, of the Rust tests).
#[cfg(feature = "cli")]
#[forbid(unsafe_code)]
mod scene;

#[cfg(all(any(feature = "cli", feature = "python"), feature = "internals"))]
#[forbid(unsafe_code)]
pub mod commit;
#[cfg(all(any(feature = "cli", feature = "python"), not(feature = "internals")))]
#[forbid(unsafe_code)]
mod commit;

/// The input's metadata carried into the corrected photo, and the
/// restoration recorded in XMP (both commands).
#[cfg(any(feature = "cli", feature = "python"))]
#[forbid(unsafe_code)]
pub mod metadata;

/// Inputs tagged with another colour profile converted to the working space.
#[cfg(any(feature = "cli", feature = "python"))]
#[forbid(unsafe_code)]
pub mod icc;

/// The standalone `uwhl-rs` command (feature `cli`): decoding with limits,
/// outputs and sidecar, batch and stream modes.
#[cfg(feature = "cli")]
#[forbid(unsafe_code)]
pub mod cli;

// The bindings check numpy shapes before indexing; they are not yet under
// the panic lints.
#[cfg(feature = "python")]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod python;
#[cfg(feature = "python")]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod python_color;
#[cfg(all(feature = "python", feature = "internals"))]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod python_hooks;

pub use crate::error::{Error, Result};
pub use crate::image::ImageRef;
pub use crate::params::{channel_transmissions, default_radius, memory_estimate, Flag, Input, Params, Restoration, Selection, Stage};
pub use crate::pipeline::restore;
pub use crate::profile::{Method, TypeChoice, WhiteBalance};
pub use crate::sequence::{Estimates, Sequence};
pub use crate::water::{jerlov_types, WaterType, JERLOV};
