//! Files in and out, one implementation for both commands (the Python
//! wheel calls it through `_core`, the binary directly): the option table,
//! discovering and naming inputs, claims of output names and the commit,
//! the memory plan of one input, decoding and encoding, sRGB and ICC
//! colour, metadata carried into the photo, the sidecar and summary.csv.

/// The one table of parameters and command options (docs/CLI.md).
#[forbid(unsafe_code)]
pub mod options;

/// sRGB curves, quantisation and the transmission colour map of
/// docs/OUTPUTS.md, shared by both commands.
#[forbid(unsafe_code)]
pub mod color;

/// Transfer curves of video and raw-frame samples, both commands.
#[forbid(unsafe_code)]
pub mod transfer;

#[cfg(any(feature = "cli", feature = "python"))]
stage_modules! { budget, commit, jobs, settings, decode, depth, dive, encode, jpeg, nav, pipeline, sidecar, summary }

/// The input's metadata carried into the corrected photo, and the
/// restoration recorded in XMP (both commands).
#[cfg(any(feature = "cli", feature = "python"))]
#[forbid(unsafe_code)]
pub mod metadata;

/// Bounded readers of EXIF, XMP and ICC blocks, and the one reading of
/// orientation (both commands).
#[cfg(any(feature = "cli", feature = "python"))]
#[forbid(unsafe_code)]
pub mod exif;

/// Inputs tagged with another colour profile converted to the working space.
#[cfg(any(feature = "cli", feature = "python"))]
#[forbid(unsafe_code)]
pub mod icc;
