//! The standalone `uwhl-rs` command (feature `cli`): decoding with limits,
//! the memory plan, the outputs and sidecar of `docs/OUTPUTS.md`, batch and
//! stream modes. `src/bin/uwhl-rs.rs` only parses the process arguments and
//! exits with the code this module returns; keeping the work in the library
//! lets the fuzz target and the tests call the same decode + restore path.
//!
//! Nothing here panics on data from outside: every failure is a
//! [`Failure`](crate::error::Failure) of one [`Kind`](crate::error::Kind), and each kind has its own exit code.

macro_rules! cli_modules {
    ($($m:ident),* $(,)?) => {
        $(
            #[cfg(feature = "internals")]
            pub mod $m;
            #[cfg(not(feature = "internals"))]
            mod $m;
        )*
    };
}

cli_modules!(args, demo, frames, run);

/// The rendered scene of `uwhl-rs demo` (and, included by path, of the Rust tests).
mod scene;
// the scene names its water type as `super::WaterType`, here and in tests/common
use crate::method::water::WaterType;

pub use args::{demo_help, help, parse, Command, Demo, Format, Options, Preprocess, WaterChoice};
pub use demo::run_demo;
pub use frames::run_frames;
pub use run::{end_at_once_on_signals, init_threads, install_interrupt_handler, report, run_batch, run_stream};
pub use crate::error::{Failure, Kind};
