//! Sequence mode (`uwhl::Sequence`): frames that reuse the estimates give
//! the same bits as `restore` called with those estimates (although their
//! work buffers hold the previous frames' values), the refresh schedule,
//! frames of another size, failed frames, reset, and a rendered scene's
//! known veiling light and distances recovered on a reused frame.

mod common;

use uwhl::Flag;
use uwhl::{restore, ImageRef, Input, Params, Restoration, Sequence, WaterType};

fn input<'a>(img: &'a [f32], h: usize, w: usize, water: Option<&'a [bool]>) -> Input<'a> {
    Input {
        image: ImageRef::new(img, h, w).unwrap(),
        mask: None,
        water_mask: water,
    }
}

/// Every output as bits, the water region and the names.
fn bits(r: &Restoration) -> (Vec<u32>, Vec<bool>, String) {
    let floats = [&r.image[..], &r.radiance, &r.transmission, &r.veiling_light];
    (
        floats.iter().flat_map(|v| v.iter().map(|x| x.to_bits())).collect(),
        r.veiling_mask.clone(),
        format!("{} {:?}", r.water_type.name, r.scores),
    )
}

/// `restore` of a frame with the sequence's current estimates.
fn with_estimates(seq: &Sequence, img: &[f32], h: usize, w: usize, water: Option<&[bool]>) -> Restoration {
    let e = seq.estimates().unwrap();
    let p = Params {
        water_types: vec![e.water_type.clone()],
        veiling_light: Some(e.veiling_light),
        ..seq.params().clone()
    };
    restore(&input(img, h, w, water), &p).unwrap()
}

#[test]
fn reused_frames_equal_restore_with_the_estimates() {
    let (h, w) = (60, 90);
    // three frames of one scene with different noise
    let frames: Vec<Vec<f32>> = (1..4).map(|s| common::scene(h, w, s)).collect();
    for sub in [1, 0] {
        for reuse_water in [false, true] {
            let params = Params { guided_subsample: sub, threads: Some(2), ..Params::default() };
            let mut seq = Sequence::new(params.clone());
            seq.reuse_water_mask = reuse_water;
            assert!(seq.estimates().is_none() && seq.estimates_next());
            let first = seq.restore(&input(&frames[0], h, w, None)).unwrap();
            // the estimating frame is a plain restore
            assert_eq!(bits(&first), bits(&restore(&input(&frames[0], h, w, None), &params).unwrap()));
            assert_eq!(first.scores.len(), 10);
            assert!(!first.flags.contains(&Flag::EstimatesReused));
            assert_eq!(seq.buffer_bytes(), 32 * h * w);
            for f in &frames[1..] {
                let got = seq.restore(&input(f, h, w, None)).unwrap();
                let water = reuse_water.then_some(first.veiling_mask.as_slice());
                let want = with_estimates(&seq, f, h, w, water);
                assert_eq!(bits(&got), bits(&want), "subsample {sub}, reuse_water {reuse_water}");
                assert_eq!(got.water_type.name, first.water_type.name);
                assert_eq!(got.veiling_light, first.veiling_light);
                assert_eq!(got.scores.len(), 1);
                assert!(got.flags.contains(&Flag::EstimatesReused));
            }
        }
    }
}

#[test]
fn reused_frame_recovers_the_rendered_veiling_light_and_distances() {
    // the rendered truth: A and the distances of the object pixels
    let (h, w) = (90, 120);
    let iii = WaterType::by_name("III").unwrap();
    let mut seq = Sequence::new(Params::default());
    seq.restore(&input(&common::scene(h, w, 5), h, w, None)).unwrap();
    let truth = common::render(h, w, &iii, 6);
    let res = seq.restore(&input(&truth.img, h, w, None)).unwrap();
    let a = res.veiling_light;
    for (got, want) in a.iter().zip(truth.a) {
        assert!((got - want).abs() < 0.02, "A {a:?}, true {:?}", truth.a);
    }
    let rho = common::rho(&truth, &res.transmission);
    assert!(rho > 0.8, "rho(z, -ln t_B) = {rho}");
}

#[test]
fn reuse_water_mask_switched_on_after_the_estimating_frame() {
    // the field is public: turned on after frame 0, frame 1 takes frame 0's region
    let (h, w) = (40, 60);
    let mut seq = Sequence::new(Params::default());
    let first = seq.restore(&input(&common::scene(h, w, 8), h, w, None)).unwrap();
    seq.reuse_water_mask = true;
    let f1 = common::scene(h, w, 9);
    let got = seq.restore(&input(&f1, h, w, None)).unwrap();
    assert_eq!(bits(&got), bits(&with_estimates(&seq, &f1, h, w, Some(&first.veiling_mask))));
}

#[test]
fn refresh_every_n_frames() {
    let (h, w) = (40, 60);
    let img = common::scene(h, w, 7);
    let mut seq = Sequence::new(Params::default());
    seq.refresh_every = 2;
    let pattern: Vec<(usize, bool)> = (0..5)
        .map(|_| {
            let r = seq.restore(&input(&img, h, w, None)).unwrap();
            (r.scores.len(), r.flags.contains(&Flag::EstimatesReused))
        })
        .collect();
    assert_eq!(pattern, vec![(10, false), (1, true), (10, false), (1, true), (10, false)]);
}

#[test]
fn frames_of_another_size_detect_their_own_water_region() {
    let mut seq = Sequence::new(Params::default());
    seq.reuse_water_mask = true;
    let big = common::scene(60, 90, 1);
    let small = common::scene(48, 72, 2);
    let first = seq.restore(&input(&big, 60, 90, None)).unwrap();
    // another size: the reused type and A, its own water region
    let r1 = seq.restore(&input(&small, 48, 72, None)).unwrap();
    assert_eq!(bits(&r1), bits(&with_estimates(&seq, &small, 48, 72, None)));
    assert_eq!(r1.water_type.name, first.water_type.name);
    // the next frame of that size reuses that region
    let r2 = seq.restore(&input(&small, 48, 72, None)).unwrap();
    assert_eq!(bits(&r2), bits(&with_estimates(&seq, &small, 48, 72, Some(&r1.veiling_mask))));
    assert_eq!(seq.buffer_bytes(), 32 * 48 * 72);
}

#[test]
fn a_failed_frame_changes_nothing_and_reset_forgets() {
    let (h, w) = (40, 60);
    let good = common::scene(h, w, 3);
    let mut bad = good.clone();
    bad[3 * (5 * w + 7) + 1] = f32::NAN;
    let mut seq = Sequence::new(Params::default());
    // failing first frame: still nothing estimated
    let e = seq.restore(&input(&bad, h, w, None)).unwrap_err();
    assert!(e.to_string().contains("non-finite"), "{e}");
    assert!(seq.estimates().is_none() && seq.estimates_next());
    let first = seq.restore(&input(&good, h, w, None)).unwrap();
    let a = seq.estimates().unwrap().veiling_light;
    assert!(seq.restore(&input(&bad, h, w, None)).is_err());
    assert_eq!(seq.estimates().unwrap().veiling_light, a);
    let next = seq.restore(&input(&good, h, w, None)).unwrap();
    assert!(next.flags.contains(&Flag::EstimatesReused));
    assert_eq!(next.water_type.name, first.water_type.name);
    seq.reset();
    assert!(seq.estimates().is_none() && seq.estimates_next());
    assert_eq!(seq.buffer_bytes(), 0);
    let again = seq.restore(&input(&good, h, w, None)).unwrap();
    assert_eq!(bits(&again), bits(&first));
}
