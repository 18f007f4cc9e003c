//! # uwhl — underwater single-image color restoration with haze-lines
//!
//! An implementation of Berman, Levy, Avidan & Treibitz, "Underwater Single
//! Image Color Restoration Using Haze-Lines and a New Quantitative Dataset"
//! (IEEE TPAMI 2020), following `SPEC.md` (section numbers in the docs
//! below, "SPEC n") and the choices recorded in `docs/DECISIONS.md`.
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

pub mod boxsum;
pub mod clahe;
pub mod error;
pub mod filters;
pub mod guided;
pub mod hazelines;
pub mod image;
pub mod matting;
pub mod pipeline;
pub mod rank;
pub mod recover;
pub mod select;
pub mod sphere;
pub mod util;
pub mod veiling;
pub mod water;

#[cfg(feature = "python")]
mod python;

pub use error::{Error, Result};
pub use image::ImageRef;
pub use pipeline::{restore, Input, Params, Restoration};
pub use water::{jerlov_types, WaterType, JERLOV};
