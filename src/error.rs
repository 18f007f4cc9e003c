//! One error type for the whole core: every failure is a variant with a
//! message that names the problem. The core never panics on data that comes
//! from outside; bindings map these variants to Python exceptions in one place.

use thiserror::Error;

/// Everything that can go wrong in [`crate::restore`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// The image buffer does not describe an H x W x 3 image.
    #[error("bad image shape: {0}")]
    Shape(String),
    /// The image is too small for the method (it needs a neighbourhood).
    #[error("image too small: {height}x{width} pixels; at least {min}x{min} are needed")]
    TooSmall {
        /// rows
        height: usize,
        /// columns
        width: usize,
        /// minimum side
        min: usize,
    },
    /// A NaN or infinite value.
    #[error(
        "image has a non-finite value ({value}) at row {row}, column {col}, channel {channel}"
    )]
    NonFinite {
        /// the value (NaN or +-inf)
        value: f32,
        /// row
        row: usize,
        /// column
        col: usize,
        /// channel 0..3
        channel: usize,
    },
    /// A value outside [0, 1].
    #[error("image value {value} at row {row}, column {col}, channel {channel} is outside [0, 1]; the input must be linear RGB scaled to [0, 1]")]
    OutOfRange {
        /// the value
        value: f32,
        /// row
        row: usize,
        /// column
        col: usize,
        /// channel 0..3
        channel: usize,
    },
    /// Every value of the image is the same: there is no structure to restore.
    #[error("image is constant (every value is {0}): there is nothing to restore")]
    Constant(f32),
    /// A mask (estimation mask or water mask) is unusable.
    #[error("bad {name}: {msg}")]
    Mask {
        /// which mask
        name: &'static str,
        /// what is wrong
        msg: String,
    },
    /// An unknown or invalid water type.
    #[error("bad water type: {0}")]
    WaterType(String),
    /// A parameter out of its domain.
    #[error("bad parameter {name}: {msg}")]
    Param {
        /// parameter name
        name: &'static str,
        /// what is wrong
        msg: String,
    },
    /// The estimated working memory exceeds the configured limit.
    #[error("image of {height}x{width} pixels needs about {needed} bytes of working memory, over the limit of {limit} bytes (raise max_memory or downscale the image)")]
    Memory {
        /// rows
        height: usize,
        /// columns
        width: usize,
        /// estimated bytes
        needed: u64,
        /// configured limit
        limit: u64,
    },
    /// The system would not give the working memory now (free memory, a
    /// cgroup limit, `ulimit -v`), though it is within `max_memory`.
    #[error("image of {height}x{width} pixels needs about {needed} bytes of working memory, which the system cannot give now (free memory, a container limit or ulimit -v); downscale the image or free memory")]
    Unavailable {
        /// rows
        height: usize,
        /// columns
        width: usize,
        /// estimated bytes
        needed: u64,
    },
    /// A bug: a state the core believes impossible. Reported, never a panic.
    #[error("internal error (please report): {0}")]
    Internal(String),
}

/// Whose problem an [`Error`] is: the one classification that the Python
/// exceptions and both commands' exit codes follow (docs/CLI.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Category {
    /// the image cannot be restored (Python `ImageError`; exit 3)
    UnreadableInput,
    /// a parameter, mask or water type is invalid (Python `ParameterError`; exit 2)
    BadArguments,
    /// over the memory budget (Python `MemoryError`; exit 4)
    OverBudget,
    /// a bug (Python `RuntimeError`; exit 6)
    Internal,
}

impl Error {
    /// The category of this error.
    pub fn category(&self) -> Category {
        match self {
            Error::Shape(_)
            | Error::TooSmall { .. }
            | Error::NonFinite { .. }
            | Error::OutOfRange { .. }
            | Error::Constant(_) => Category::UnreadableInput,
            Error::Mask { .. } | Error::WaterType(_) | Error::Param { .. } => Category::BadArguments,
            Error::Memory { .. } | Error::Unavailable { .. } => Category::OverBudget,
            Error::Internal(_) => Category::Internal,
        }
    }
}

/// Result alias of the core.
pub type Result<T> = std::result::Result<T, Error>;
