//! Determinism: `restore` gives bit-identical results for 1, 2 and 8
//! threads and across repeated runs in one process, with and without a mask.

mod common;

use uwhl::{restore, ImageRef, Input, Params, Restoration};

/// Every output of a restoration as bits, for exact comparison.
fn fingerprint(r: &Restoration) -> (Vec<u32>, Vec<u32>, Vec<u32>, Vec<u64>, Vec<u32>, Vec<bool>, Vec<String>, String) {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    (
        bits(&r.image),
        bits(&r.radiance),
        bits(&r.transmission),
        r.scores.iter().map(|s| s.1.to_bits()).collect(),
        bits(&r.veiling_light),
        r.veiling_mask.clone(),
        [r.flags.clone(), r.excluded.clone()].concat(),
        r.water_type.name.clone(),
    )
}

fn check(h: usize, w: usize, mask: Option<&[bool]>) {
    let img = common::scene(h, w, 99);
    let input = Input {
        image: ImageRef::new(&img, h, w).unwrap(),
        mask,
        water_mask: None,
    };
    let run = |n: usize| {
        let p = Params {
            threads: Some(n),
            ..Params::default()
        };
        fingerprint(&restore(&input, &p).unwrap())
    };
    let base = run(1);
    for n in [2, 8, 1, 8, 2, 1] {
        assert!(run(n) == base, "{h}x{w}, {n} threads differ from 1 thread");
    }
}

#[test]
fn bit_identical_for_1_2_8_threads_and_repeated_runs() {
    check(97, 131, None);
}

#[test]
fn bit_identical_with_a_mask() {
    let (h, w) = (64, 90);
    let mask: Vec<bool> = (0..h * w)
        .map(|i| !((40..55).contains(&(i / w)) && (10..40).contains(&(i % w))))
        .collect();
    check(h, w, Some(&mask));
}
