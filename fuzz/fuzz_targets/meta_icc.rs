//! Fuzz target over one metadata reader (`uwhl::files::exif::fuzzing::icc`):
//! any panic, abort, timeout or allocation past libFuzzer's limit is a bug.
//! Seeded from `fuzz/meta_seeds/icc/` (written by `fuzz/make_seeds.py`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| uwhl::files::exif::fuzzing::icc(data));
