//! Fuzz target over the binary's decode + restore path: the first byte
//! picks options, the rest is a PNG/JPEG/TIFF file (see
//! `uwhl::files::pipeline::fuzz_one`). Any panic, abort, leak or timeout is a bug;
//! errors are fine. Crashing inputs go to `fuzz/regressions/` and are
//! replayed by `tests/fuzz_regressions.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    uwhl::cli::run::init_threads(Some(1));
    if let Err(e) = uwhl::files::pipeline::fuzz_one(data) {
        assert!(e.kind != uwhl::Kind::Internal, "{e}");
    }
});
