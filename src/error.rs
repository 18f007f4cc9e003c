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
    #[error("image too small: {width} pixels wide and {height} high ({height}x{width}, height x width); the method needs at least {min} pixels on each side")]
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
    /// A distance map that cannot be this image's (METHOD §13).
    #[error("bad distance: {0}")]
    Distance(String),
    /// A parameter out of its domain.
    #[error("bad parameter {name}: {msg}")]
    Param {
        /// parameter name
        name: &'static str,
        /// what is wrong
        msg: String,
    },
    /// The estimated working memory exceeds the configured limit.
    #[error("image of {width}x{height} pixels needs about {needed} bytes of working memory, over the limit of {limit} bytes (raise max_memory or downscale the image)")]
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
    #[error("image of {width}x{height} pixels needs about {needed} bytes of working memory, which the system cannot give now (free memory, a container limit or ulimit -v); downscale the image or free memory")]
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

/// What kind of failure an error is: the one classification that the
/// Python exceptions and both commands' exit codes follow (docs/CLI.md).
/// Every failure gets its kind where it is raised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// bad command line, option values, parameter, mask or water type
    /// (Python `ParameterError`; exit 2)
    Usage,
    /// an input that cannot be found, read, decoded or restored (Python
    /// `ImageError`; exit 3)
    Input,
    /// over `--max-pixels`, the memory budget or what the system gives
    /// (Python `MemoryError`; exit 4)
    Budget,
    /// an output that cannot be written (exit 5)
    Write,
    /// a bug: a state the program believes impossible (Python
    /// `RuntimeError`; exit 6)
    Internal,
}

/// Every exit code of both commands: code, kind name (`--json-errors`'s
/// `error`), meaning (docs/CLI.md).
pub const EXIT_CODES: &[(u8, &str, &str)] = &[
    (0, "ok", "every input restored, or skipped because its sidecar exists"),
    (2, "bad_arguments", "bad arguments or option values; nothing was read"),
    (3, "unreadable_input", "an input could not be found, read, decoded or restored"),
    (4, "over_budget", "an input is over --max-pixels or --max-memory"),
    (5, "write_failed", "an output could not be written"),
    (6, "internal", "internal error (a bug; please report it)"),
    (7, "unreachable", "the Dask scheduler or the storage could not be reached, or refused the credentials"),
    (130, "interrupted", "interrupted (SIGINT or SIGTERM); run the same command again to resume"),
];

/// A number as a message shows it: as Rust writes it when that is short,
/// else in scientific notation (1e300 is not 301 digits on a console).
pub fn shown_number(v: f64) -> String {
    let plain = v.to_string();
    if plain.len() <= 24 {
        plain
    } else {
        format!("{v:.6e}")
    }
}

/// The exit code of the failure kind `name` of [`EXIT_CODES`] (that of
/// `internal` for a name the table lacks).
pub fn exit_code(name: &str) -> u8 {
    let find = |n: &str| EXIT_CODES.iter().find(|(_, k, _)| *k == n).map(|(c, _, _)| *c);
    find(name).or_else(|| find("internal")).unwrap_or(1)
}

impl Kind {
    /// The process exit code of this kind; larger is more severe.
    pub fn exit_code(self) -> u8 {
        exit_code(self.name())
    }

    /// The machine-readable name used in `--json-errors` objects.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Usage => "bad_arguments",
            Kind::Input => "unreadable_input",
            Kind::Budget => "over_budget",
            Kind::Write => "write_failed",
            Kind::Internal => "internal",
        }
    }
}

impl Error {
    /// The kind of this error: bad parameters are the caller's, bad data
    /// the input's, over-budget the budget's.
    pub fn kind(&self) -> Kind {
        match self {
            Error::Shape(_)
            | Error::TooSmall { .. }
            | Error::NonFinite { .. }
            | Error::OutOfRange { .. }
            | Error::Constant(_) => Kind::Input,
            Error::Mask { .. } | Error::WaterType(_) | Error::Distance(_) | Error::Param { .. } => Kind::Usage,
            Error::Memory { .. } | Error::Unavailable { .. } => Kind::Budget,
            Error::Internal(_) => Kind::Internal,
        }
    }
}

/// A failure of one input or of a command: its kind (the exit code) and a
/// message that names the problem. The files layer and both commands
/// report every failure as one of these.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure {
    /// what kind of failure (sets the exit code)
    pub kind: Kind,
    /// a human-readable message
    pub message: String,
}

impl Failure {
    /// A failure of `kind` with `message`.
    pub fn new(kind: Kind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }

    /// A usage error.
    pub fn usage(message: impl Into<String>) -> Self {
        Self::new(Kind::Usage, message)
    }

    /// The one-line JSON object of `--json-errors` and of stream mode.
    #[cfg(any(feature = "cli", feature = "python"))]
    pub fn to_json(&self, input: Option<&str>) -> serde_json::Value {
        serde_json::json!({
            "error": self.kind.name(),
            "input": input,
            "message": self.message,
            "exit_code": self.kind.exit_code(),
        })
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Failure {}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Self::new(e.kind(), e.to_string())
    }
}

/// Result alias of the core.
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_in_the_exit_code_table() {
        for k in [Kind::Usage, Kind::Input, Kind::Budget, Kind::Write, Kind::Internal] {
            assert!(EXIT_CODES.iter().any(|(c, n, _)| *n == k.name() && *c == k.exit_code()), "{k:?}");
        }
        assert_eq!(
            [Kind::Usage, Kind::Input, Kind::Budget, Kind::Write, Kind::Internal].map(Kind::exit_code),
            [2, 3, 4, 5, 6]
        );
    }

    #[test]
    fn core_errors_keep_their_kind() {
        let param = Error::Param { name: "guided_eps", msg: "x".into() };
        let memory = Error::Memory { height: 1, width: 1, needed: 2, limit: 1 };
        assert_eq!(param.kind(), Kind::Usage);
        assert_eq!(memory.kind(), Kind::Budget);
        assert_eq!(Error::Constant(0.5).kind(), Kind::Input);
        assert_eq!(Error::Internal("x".into()).kind(), Kind::Internal);
        assert_eq!(Failure::from(param).kind, Kind::Usage);
    }
}
