//! The Rust API's determinism test: `restore` gives bit-identical results
//! for 1, 2 and 8 threads and across repeated runs in one process, for the
//! plain scene, with an estimation mask, with the subsampled guided filter
//! and with fast selection. (The binary and the Python face have one each:
//! tests/binary.rs, tests/python/test_api.py.)

mod common;

use uwhl::{restore, ImageRef, Input, Params, Restoration, Selection};

/// Every output of a restoration: its f32 values as bits, the scores as
/// bits, the water region, and the names (type, flags, excluded).
type Fingerprint = (Vec<u32>, Vec<u64>, Vec<bool>, String);

fn fingerprint(r: &Restoration) -> Fingerprint {
    let floats = [&r.image[..], &r.radiance, &r.transmission, &r.veiling_light];
    (
        floats.iter().flat_map(|v| v.iter().map(|x| x.to_bits())).collect(),
        r.scores.iter().map(|s| s.1.to_bits()).collect(),
        r.veiling_mask.clone(),
        format!("{} {:?} {:?}", r.water_type.name, r.flags, r.excluded),
    )
}

#[test]
fn bit_identical_for_1_2_8_threads_and_repeated_runs() {
    let (h, w) = (64, 90);
    let chart: Vec<bool> = (0..h * w)
        .map(|i| !((40..55).contains(&(i / w)) && (10..40).contains(&(i % w))))
        .collect();
    let cases: [(usize, usize, Option<&[bool]>, Params); 5] = [
        (97, 131, None, Params::default()),
        (h, w, Some(&chart), Params::default()),
        (97, 131, None, Params { guided_subsample: 3, ..Params::default() }),
        (150, 170, None, Params { guided_subsample: 5, ..Params::default() }),
        (300, 1100, None, Params { selection: Some(Selection::Fast), ..Params::default() }),
    ];
    for (h, w, mask, params) in cases {
        let img = common::scene(h, w, 99);
        let input = Input { image: ImageRef::new(&img, h, w).unwrap(), mask, water_mask: None };
        let run = |n: usize| fingerprint(&restore(&input, &Params { threads: Some(n), ..params.clone() }).unwrap());
        let base = run(1);
        for n in [2, 8, 1, 8, 2] {
            assert!(run(n) == base, "{h}x{w} {params:?}: {n} threads differ from 1 thread");
        }
    }
}
