//! Sequence mode (`uwhl::Sequence`): frames that reuse the estimates give
//! the same bits as `restore` called with those estimates (although their
//! work buffers hold the previous frames' values), the refresh schedule,
//! frames of another size, failed frames, reset, and a rendered scene's
//! known veiling light and distances recovered on a reused frame.

mod common;

use uwhl::Flag;
use uwhl::{restore, Decision, ImageRef, Input, Params, Restoration, Sequence, Signature, WaterType};

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

/// An image of constant colour `rgb` (h x w).
fn flat(h: usize, w: usize, rgb: [f32; 3]) -> Vec<f32> {
    (0..h * w).flat_map(|_| rgb).collect()
}

#[test]
fn signatures_compare_chromaticities_not_exposure() {
    let (h, w) = (40, 64);
    // left half chromaticity (0.5, 0.25): bin (8, 4); right half gray (1/3, 1/3): bin (5, 5)
    let mut img = flat(h, w, [0.2, 0.2, 0.2]);
    for y in 0..h {
        for x in 0..w / 2 {
            img[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[0.4, 0.2, 0.2]);
        }
    }
    let s = Signature::of(&img, h, w);
    assert_eq!(s.change(&s), 0.0);
    // brighter or darker by any factor (above the dark limit): the same chromaticities
    let bright: Vec<f32> = img.iter().map(|v| v * 2.0).collect();
    assert_eq!(s.change(&Signature::of(&bright, h, w)), 0.0);
    // half of the mass in a bin the other lacks: 0.5
    let gray = Signature::of(&flat(h, w, [0.2, 0.2, 0.2]), h, w);
    assert!((s.change(&gray) - 0.5).abs() < 1e-6, "{}", s.change(&gray));
    // nothing in common: 1; a frame too dark to tell: 1 against anything
    let blue = Signature::of(&flat(h, w, [0.02, 0.1, 0.5]), h, w);
    assert_eq!(gray.change(&blue), 1.0);
    let dark = Signature::of(&flat(h, w, [0.005, 0.005, 0.005]), h, w);
    assert_eq!(dark.change(&gray), 1.0);
}

/// `img` as if seen through other water: each channel scaled.
fn tinted(img: &[f32], k: [f32; 3]) -> Vec<f32> {
    img.iter().enumerate().map(|(i, v)| (v * k[i % 3]).min(1.0)).collect()
}

/// The window of `w` columns starting at column `x0` of an image `big_w` wide.
fn window(big: &[f32], h: usize, big_w: usize, x0: usize, w: usize) -> Vec<f32> {
    (0..h).flat_map(|y| big[3 * (y * big_w + x0)..3 * (y * big_w + x0 + w)].iter().copied()).collect()
}

#[test]
fn a_cut_estimates_afresh_and_a_pan_reuses() {
    let (h, w, big_w) = (48, 72, 120);
    let big = common::scene(h, big_w, 4);
    let params = Params { threads: Some(2), ..Params::default() };
    let mut seq = Sequence::new(params.clone());
    seq.cut_threshold = 0.3;
    // a pan of 4 px a frame through one water: one estimate, then reuse
    for k in 0..6 {
        let f = window(&big, h, big_w, 4 * k, w);
        let r = seq.restore(&input(&f, h, w, None)).unwrap();
        let (d, change) = seq.last_decision();
        let want = if k == 0 { Decision::First } else { Decision::Reused };
        assert_eq!(d, want, "frame {k}, change {change}");
        assert!(change < 0.3, "frame {k}: {change}");
        assert_eq!(r.flags.contains(&Flag::EstimatesReused), k > 0);
    }
    // a cut to greener water: estimated afresh, exactly as a first frame
    let other = tinted(&window(&big, h, big_w, 30, w), [0.3, 1.0, 0.45]);
    let got = seq.restore(&input(&other, h, w, None)).unwrap();
    let (d, change) = seq.last_decision();
    assert_eq!(d, Decision::Cut);
    assert!(change > 0.5, "{change}");
    assert_eq!(bits(&got), bits(&restore(&input(&other, h, w, None), &params).unwrap()));
    // and the frame after it reuses the new estimate
    let next = seq.restore(&input(&other, h, w, None)).unwrap();
    assert_eq!(seq.last_decision().0, Decision::Reused);
    assert_eq!(next.veiling_light, got.veiling_light);
    // without a threshold the cut is not seen
    let mut blind = Sequence::new(params);
    blind.restore(&input(&window(&big, h, big_w, 0, w), h, w, None)).unwrap();
    blind.restore(&input(&other, h, w, None)).unwrap();
    assert_eq!(blind.last_decision(), (Decision::Reused, 0.0));
}

#[test]
fn a_slow_drift_re_estimates_once_it_exceeds_the_threshold() {
    let (h, w) = (40, 60);
    let img = common::scene(h, w, 6);
    let mut seq = Sequence::new(Params::default());
    seq.cut_threshold = 0.3;
    let mut decisions = Vec::new();
    // the red channel fades by 8% a frame: no step is a cut, the sum is a drift
    for k in 0..12 {
        let f = tinted(&img, [0.92f32.powi(k), 1.0, 1.0]);
        seq.restore(&input(&f, h, w, None)).unwrap();
        decisions.push(seq.last_decision());
    }
    assert!(decisions.iter().all(|(d, c)| *d != Decision::Cut && *c < 0.3), "{decisions:?}");
    let drifts: Vec<usize> = decisions.iter().enumerate().filter(|(_, (d, _))| *d == Decision::Drift).map(|(k, _)| k).collect();
    assert!(!drifts.is_empty() && drifts[0] >= 2, "{decisions:?}");
}

#[test]
fn smoothing_moves_a_part_of_the_way_at_a_scheduled_refresh() {
    let (h, w) = (40, 60);
    let f0 = common::scene(h, w, 2);
    // the second estimate sees a bluer veiling light
    let f2 = tinted(&common::scene(h, w, 3), [0.9, 0.95, 1.2]);
    let params = Params { threads: Some(2), ..Params::default() };
    let mut seq = Sequence::new(params.clone());
    seq.refresh_every = 2;
    seq.smoothing = 0.25;
    let first = seq.restore(&input(&f0, h, w, None)).unwrap();
    seq.restore(&input(&f0, h, w, None)).unwrap();
    let got = seq.restore(&input(&f2, h, w, None)).unwrap();
    assert_eq!(seq.last_decision().0, Decision::Scheduled);
    let fresh = restore(&input(&f2, h, w, None), &params).unwrap();
    let a: [f32; 3] = std::array::from_fn(|c| first.veiling_light[c] + 0.25 * (fresh.veiling_light[c] - first.veiling_light[c]));
    assert_eq!(got.veiling_light, a);
    assert_ne!(a, fresh.veiling_light);
    // the frame is restore with the new type and the smoothed A; the scores are the estimate's
    let p = Params { water_types: vec![fresh.water_type.clone()], veiling_light: Some(a), ..params };
    let want = restore(&input(&f2, h, w, None), &p).unwrap();
    assert_eq!(bits(&Restoration { scores: want.scores.clone(), ..got }).0, bits(&want).0);
    assert_eq!(seq.estimates().unwrap().veiling_light, a);
}
