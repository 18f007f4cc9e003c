//! Determinism: `restore` gives bit-identical results for 1, 2 and 8
//! threads and across repeated runs in one process, with and without a mask.

mod common;

use uwhl::{restore, ImageRef, Input, Params, Restoration};

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

fn check(h: usize, w: usize, mask: Option<&[bool]>) {
    check_with(h, w, mask, 1);
}

fn check_with(h: usize, w: usize, mask: Option<&[bool]>, guided_subsample: usize) {
    let img = common::scene(h, w, 99);
    let input = Input {
        image: ImageRef::new(&img, h, w).unwrap(),
        mask,
        water_mask: None,
    };
    let run = |n: usize| {
        let p = Params {
            threads: Some(n),
            guided_subsample,
            ..Params::default()
        };
        fingerprint(&restore(&input, &p).unwrap())
    };
    let base = run(1);
    for n in [2, 8, 1, 8, 2, 1] {
        assert!(
            run(n) == base,
            "{h}x{w}, subsample {guided_subsample}: {n} threads differ from 1 thread"
        );
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

#[test]
fn bit_identical_with_the_subsampled_guided_filter() {
    check_with(97, 131, None, 3);
    check_with(150, 170, None, 5);
}
