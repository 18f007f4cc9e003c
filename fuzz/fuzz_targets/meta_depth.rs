//! Fuzz target over the distance-map readers (`uwhl::files::depth::fuzzing::depth`:
//! .npy, 16-bit PNG, TIFF and BigTIFF, OpenEXR, COLMAP): any panic, abort,
//! timeout or allocation past libFuzzer's limit is a bug. Seeded from
//! `fuzz/meta_seeds/depth/` (written by `fuzz/make_meta_seeds.py`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| uwhl::files::depth::fuzzing::depth(data));
