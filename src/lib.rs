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

// The layers, each a folder, imports pointing down only:
//
//     error      the one error enum, the failure kinds and their exit codes
//     kernels/   box sums, filters, order statistics, powers, deterministic reductions, memory
//     method/    restore() and Sequence, one file per METHOD section, params, profiles, water table
//     files/     the per-input path both commands share: option table, jobs, claims and commit,
//                memory plan, decoding and encoding, colour and ICC, metadata, sidecar, summary
//     cli/       the uwhl-rs binary: arguments from the table, batch and stream loops, demo
//     python/    the pyo3 bindings only

/// Declares modules of the layers below: every one forbids unsafe code even
/// when the pyo3 bindings (which expand to unsafe code) are built into the
/// crate, and all are under the crate's panic lints above. They are private:
/// the API is the `pub use` list below. The feature `internals` (benches,
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
            pub(crate) mod $m;
        )*
    };
}

/// The one error enum, the failure kinds and their exit codes.
#[forbid(unsafe_code)]
pub mod error;

/// Numerical building blocks of the method, independent of it.
#[forbid(unsafe_code)]
pub mod kernels;

/// The method of docs/METHOD.md: `restore`, `Sequence` and their stages.
#[forbid(unsafe_code)]
pub mod method;

/// Files in and out, the same for both commands (docs/OUTPUTS.md).
#[forbid(unsafe_code)]
pub mod files;

/// The standalone `uwhl-rs` command (feature `cli`): arguments, the batch
/// and stream loops, the demo.
#[cfg(feature = "cli")]
#[forbid(unsafe_code)]
pub mod cli;

// The bindings check numpy shapes before indexing; they are not yet under
// the panic lints.
#[cfg(feature = "python")]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod python;

pub use crate::error::{Error, Failure, Kind, Result};
pub use crate::method::image::ImageRef;
pub use crate::method::params::{channel_transmissions, default_radius, memory_estimate, Flag, Input, Params, Restoration, Selection, Stage};
pub use crate::method::pipeline::given::{resize_distance, restore_at_distance, DistanceUse};
pub use crate::method::pipeline::restore;
pub use crate::method::distance::WaterFit;
pub use crate::method::profile::{Method, TypeChoice, WhiteBalance};
pub use crate::method::sequence::{Decision, Estimates, Sequence, Signature, VIDEO_SCENE_CUT, VIDEO_SMOOTHING};
pub use crate::method::water::{jerlov_types, WaterType, JERLOV};
