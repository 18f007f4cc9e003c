//! The standalone `uwhl-rs` command (feature `cli`): decoding with limits,
//! the memory plan, the outputs and sidecar of `docs/OUTPUTS.md`, batch and
//! stream modes. `src/bin/uwhl-rs.rs` only parses the process arguments and
//! exits with the code this module returns; keeping the work in the library
//! lets the fuzz target and the tests call the same decode + restore path.
//!
//! Nothing here panics on data from outside: every failure is a
//! [`CliError`](crate::cli::CliError) of one [`Kind`](crate::cli::Kind), and each kind has its own exit code.

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

cli_modules!(args, decode, demo, output, run, sidecar, summary);

pub use args::{help, parse, Command, Demo, Format, Options, Preprocess, WaterChoice};
pub use demo::run_demo;
pub use run::{init_threads, install_interrupt_handler, report, run_batch, run_stream};

use std::fmt;

/// What went wrong, as far as the caller of the command needs to know; each
/// kind has its own exit code (documented in `--help` and the README).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// Bad command line or option values (exit 2).
    Usage,
    /// An input that cannot be read, decoded or restored (exit 3).
    Input,
    /// An input over `--max-pixels` or `--max-memory` (exit 4).
    Budget,
    /// An output that cannot be written (exit 5).
    Write,
    /// A bug: a state the program believes impossible (exit 6).
    Internal,
}

impl Kind {
    /// The process exit code of this kind; larger is more severe.
    pub fn exit_code(self) -> u8 {
        crate::options::exit_code(self.name())
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

    /// The kind of an error of the core: bad parameters are the caller's,
    /// bad data the input's, over-budget the budget's.
    pub fn of_core(e: &crate::Error) -> Kind {
        use crate::error::Category as C;
        match e.category() {
            C::UnreadableInput => Kind::Input,
            C::BadArguments => Kind::Usage,
            C::OverBudget => Kind::Budget,
            C::Internal => Kind::Internal,
        }
    }
}

/// An error of the command: its kind and a message that names the problem.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CliError {
    /// what kind of failure (sets the exit code)
    pub kind: Kind,
    /// a human-readable message
    pub message: String,
}

impl CliError {
    /// An error of `kind` with `message`.
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
    pub fn to_json(&self, input: Option<&str>) -> serde_json::Value {
        serde_json::json!({
            "error": self.kind.name(),
            "input": input,
            "message": self.message,
            "exit_code": self.kind.exit_code(),
        })
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for CliError {}

impl From<crate::Error> for CliError {
    fn from(e: crate::Error) -> Self {
        Self::new(Kind::of_core(&e), e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_in_the_exit_code_table() {
        for k in [Kind::Usage, Kind::Input, Kind::Budget, Kind::Write, Kind::Internal] {
            assert!(crate::options::EXIT_CODES.iter().any(|(c, n, _)| *n == k.name() && *c == k.exit_code()), "{k:?}");
        }
        assert_eq!(
            [Kind::Usage, Kind::Input, Kind::Budget, Kind::Write, Kind::Internal].map(Kind::exit_code),
            [2, 3, 4, 5, 6]
        );
    }

    #[test]
    fn core_errors_keep_their_category() {
        let param = crate::Error::Param { name: "guided_eps", msg: "x".into() };
        let memory = crate::Error::Memory { height: 1, width: 1, needed: 2, limit: 1 };
        assert_eq!(Kind::of_core(&param), Kind::Usage);
        assert_eq!(Kind::of_core(&memory), Kind::Budget);
        assert_eq!(Kind::of_core(&crate::Error::Constant(0.5)), Kind::Input);
        assert_eq!(Kind::of_core(&crate::Error::Internal("x".into())), Kind::Internal);
    }
}
