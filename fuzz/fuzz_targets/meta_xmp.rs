//! Fuzz target over one metadata reader (`uwhl::files::exif::fuzzing::xmp`):
//! any panic, abort, timeout or allocation past libFuzzer's limit is a bug.
//! Seeded from `fuzz/meta_seeds/xmp/` (written by `fuzz/make_seeds.py`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| uwhl::files::exif::fuzzing::xmp(data));
