//! `uwhl-rs`: the standalone restoration command (feature `cli`). All the
//! work is in [`uwhl::cli`]; this file reads the process arguments and
//! exits with the documented code (see `uwhl-rs --help`).

#![forbid(unsafe_code)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::io::Write;
use std::process::ExitCode;
use uwhl::cli::{help, init_threads, install_interrupt_handler, parse, report, run_batch, run_demo, run_stream, Command};

fn main() -> ExitCode {
    let json_errors = std::env::args_os().any(|a| a == "--json-errors");
    let mut stdout = std::io::stdout().lock();
    let mut stderr = std::io::stderr().lock();
    let code = match parse(std::env::args_os().skip(1)) {
        Ok(Command::Help) => {
            let _ = stdout.write_all(help().as_bytes());
            0
        }
        Ok(Command::Version) => {
            let _ = writeln!(stdout, "uwhl-rs {}", env!("CARGO_PKG_VERSION"));
            0
        }
        Ok(Command::Demo(d)) => match run_demo(&d, &mut stdout) {
            Ok(code) => code,
            Err(e) => {
                report(&mut stderr, false, None, &e);
                e.kind.exit_code()
            }
        },
        Ok(Command::Run(opts)) => {
            init_threads(opts.params.threads);
            if opts.stream {
                // unlocked (the lock is not Send): lines are read on a second thread
                let mut stdin = std::io::BufReader::new(std::io::stdin());
                run_stream(&opts, &mut stdin, &mut stdout, &mut stderr)
            } else {
                if let Err(e) = install_interrupt_handler() {
                    let _ = writeln!(stderr, "uwhl-rs: cannot handle SIGINT ({e}); an interrupt ends the run at once");
                }
                run_batch(&opts, &mut stdout, &mut stderr)
            }
        }
        Err(e) => {
            report(&mut stderr, json_errors, None, &e);
            if !json_errors {
                let _ = writeln!(stderr, "Try 'uwhl-rs --help'.");
            }
            e.kind.exit_code()
        }
    };
    let _ = stdout.flush();
    ExitCode::from(code)
}
