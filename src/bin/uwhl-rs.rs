//! `uwhl-rs`: the standalone restoration command (feature `cli`). All the
//! work is in [`uwhl::cli`]; this file reads the process arguments and
//! exits with the documented code (see `uwhl-rs --help`).

// deny, not forbid: the exceptions are the start-up hook below (a
// `link_section`, which the unsafe_code lint counts), the allocator's
// setting and SIGXFSZ's disposition, allowed where they are
#![deny(unsafe_code)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::io::Write;
use std::process::ExitCode;
use uwhl::cli::{
    demo_help, end_at_once_on_signals, help, init_threads, install_interrupt_handler, parse, report, run_batch, run_demo, run_frames, run_stream,
    Command,
};

/// Whether stdout was closed when the process started (`>&-`). Rust's
/// runtime puts /dev/null on a closed standard descriptor before `main`,
/// so every write then succeeds and stream mode's lines would be lost
/// without a word; only a check that runs before it can tell.
#[cfg(target_os = "linux")]
mod closed_stdout {
    use std::sync::atomic::{AtomicBool, Ordering};

    static CLOSED: AtomicBool = AtomicBool::new(false);

    extern "C" fn check() {
        // without /proc there is no telling: taken as open
        let fds = std::path::Path::new("/proc/self/fd");
        if fds.is_dir() && std::fs::symlink_metadata(fds.join("1")).is_err() {
            CLOSED.store(true, Ordering::Relaxed);
        }
    }

    // run by the loader's start-up code, before the Rust runtime's
    #[allow(unsafe_code)]
    #[used]
    #[link_section = ".init_array"]
    static CHECK: extern "C" fn() = check;

    /// What [`check`] found.
    pub fn closed() -> bool {
        CLOSED.load(Ordering::Relaxed)
    }
}

#[cfg(not(target_os = "linux"))]
mod closed_stdout {
    /// Not known here: taken as open.
    pub fn closed() -> bool {
        false
    }
}

/// A file past `ulimit -f` is then a write error (EFBIG) the run reports
/// and recovers from (a summary.csv row taken back), as Python's runtime
/// has it, not a signal that kills the process in the middle of a write.
fn ignore_file_size_signal() {
    // SAFETY: sets one signal's disposition to "ignore", first in main,
    // before the process starts another thread; no handler runs.
    #[allow(unsafe_code)]
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// Makes freed image buffers leave the process at once, so that its
/// resident size follows what it holds and `--max-memory` can bound it.
///
/// glibc serves a large allocation from its own mapping and unmaps it on
/// free, but after the first such free it raises that threshold (up to
/// 32 MiB on 64-bit), and later buffers of the same size come from the
/// heap, whose freed pages can stay resident: a stream of 0.3 MP frames
/// peaked up to 1 MB over its budget on some runs, depending on which
/// thread freed first. A fixed threshold of 128 KiB keeps every buffer of
/// an image on its own mapping; its cost, a page fault per page first
/// touched, is in docs/PERFORMANCE.md.
fn release_freed_buffers_promptly() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets a parameter of the allocator, and it runs
    // first in main, before the process starts another thread.
    #[allow(unsafe_code)]
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 << 10);
    }
}

/// Whether the signal `sig` is ignored (SIG_IGN) now, before the run
/// installs a handler: one ignored at start stays ignored.
fn ignored_now(sig: i32) -> bool {
    #[cfg(unix)]
    // SAFETY: with a null new action sigaction only writes the current one
    // into `old`, a zeroed struct of its own type
    #[allow(unsafe_code)]
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
    #[cfg(not(unix))]
    false
}

fn main() -> ExitCode {
    release_freed_buffers_promptly();
    ignore_file_size_signal();
    let json_errors = std::env::args_os().any(|a| a == "--json-errors");
    // the handles, not their locks: a line another thread writes (a
    // dependency's own message) would wait for ever on a lock held for the
    // whole run, and the run for that thread
    let mut stdout = std::io::stdout();
    let mut stderr = std::io::stderr();
    let code = match parse(std::env::args_os().skip(1)) {
        Ok(Command::Help) => {
            let _ = stdout.write_all(help().as_bytes());
            0
        }
        Ok(Command::DemoHelp) => {
            let _ = stdout.write_all(demo_help().as_bytes());
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
            if (opts.stream || opts.raw_frames.is_some()) && closed_stdout::closed() {
                // each frame's outcome is only its line (or the frame itself) on stdout: restoring frames nobody
                // hears of is refused
                let what = if opts.stream {
                    "stream mode writes each frame's JSON line there"
                } else {
                    "--raw-frames writes the frames (-o -) or each frame's JSON line (-o DIR) there"
                };
                let e = uwhl::Failure::new(uwhl::Kind::Write, format!("stdout is closed: {what}; nothing was restored"));
                report(&mut stderr, opts.json_errors, None, &e);
                e.kind.exit_code()
            } else {
                // a stream and raw frames (a pipe) end at once on a signal; a batch lets the input being written finish
                let handled = if opts.stream || opts.raw_frames.is_some() {
                    let dir = (opts.outdir.as_os_str() != "-").then(|| opts.outdir.clone());
                    end_at_once_on_signals(dir, &ignored_now)
                } else {
                    install_interrupt_handler(&ignored_now)
                };
                if let Err(e) = handled {
                    let _ = writeln!(stderr, "uwhl-rs: cannot handle SIGINT and SIGTERM ({e}); either ends the run at once");
                }
                if opts.raw_frames.is_some() {
                    // the frames are read and written as they come
                    let mut stdin = std::io::stdin().lock();
                    run_frames(&opts, &mut stdin, &mut stdout, &mut stderr)
                } else if opts.stream {
                    // unlocked (the lock is not Send): lines are read on a second thread
                    let mut stdin = std::io::BufReader::new(std::io::stdin());
                    run_stream(&opts, &mut stdin, &mut stdout, &mut stderr)
                } else {
                    run_batch(&opts, &mut stdout, &mut stderr)
                }
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
