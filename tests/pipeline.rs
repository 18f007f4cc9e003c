//! End-to-end tests of the Rust API on a scene rendered through the model of
//! METHOD §0 (I = t J + (1 - t) A) with known water type, distances and water.

mod common;

use uwhl::{restore, Error, ImageRef, Input, Params, WaterType};

/// The test scene in type II with its truth.
fn scene(h: usize, w: usize) -> common::Rendered {
    common::render(h, w, &WaterType::by_name("II").unwrap(), 42)
}

#[test]
fn transmission_follows_distance_and_water_is_found() {
    let s = scene(90, 120);
    let input = Input {
        image: ImageRef::new(&s.img, s.h, s.w).unwrap(),
        mask: None,
        water_mask: None,
    };
    let res = restore(&input, &Params::default()).unwrap();
    // detected VL: only water, and all of the top quarter's water rows
    let inter = res
        .veiling_mask
        .iter()
        .zip(&s.water)
        .filter(|(v, w)| **v && **w)
        .count();
    let vl = res.veiling_mask.iter().filter(|&&v| v).count();
    assert!(
        vl > 0 && inter as f64 / vl as f64 > 0.98,
        "VL {vl}, in water {inter}"
    );
    assert!(
        vl >= (s.h / 4) * s.w * 9 / 10,
        "VL covers too little of the top quarter: {vl}"
    );
    // A is the water color
    for (c, t) in s.a.iter().enumerate() {
        assert!(
            (res.veiling_light[c] - t).abs() < 0.01,
            "{:?}",
            res.veiling_light
        );
    }
    let rho = common::rho(&s, &res.transmission);
    assert!(rho > 0.6, "rho = {rho}");
    assert!(res
        .image
        .iter()
        .chain(&res.radiance)
        .all(|v| (0.0..=1.0).contains(v)));
    assert!(res.transmission.iter().all(|&t| t > 0.0 && t <= 1.0));
}

#[test]
fn errors_not_panics() {
    let s = scene(20, 24);
    let input = Input {
        image: ImageRef::new(&s.img, s.h, s.w).unwrap(),
        mask: None,
        water_mask: None,
    };
    let p = |f: fn(&mut Params)| {
        let mut p = Params::default();
        f(&mut p);
        restore(&input, &p)
    };
    assert!(matches!(
        p(|p| p.guided_eps = 0.0),
        Err(Error::Param {
            name: "guided_eps",
            ..
        })
    ));
    assert!(matches!(
        p(|p| p.guided_subsample = 25),
        Err(Error::Param {
            name: "guided_subsample",
            ..
        })
    ));
    assert!(matches!(
        p(|p| p.sphere_points = 0),
        Err(Error::Param {
            name: "sphere_points",
            ..
        })
    ));
    assert!(matches!(
        p(|p| p.threads = Some(0)),
        Err(Error::Param {
            name: "threads",
            ..
        })
    ));
    assert!(matches!(
        p(|p| p.max_memory = 10),
        Err(Error::Memory { .. })
    ));
    assert!(matches!(
        p(|p| p.water_types.clear()),
        Err(Error::WaterType(_))
    ));
    assert!(matches!(
        p(|p| p.veiling_light = Some([0.1, 0.0, 0.2])),
        Err(Error::Param {
            name: "veiling_light",
            ..
        })
    ));
    let bad_mask = vec![false; s.h * s.w];
    let i2 = Input {
        mask: Some(&bad_mask),
        ..input
    };
    assert!(matches!(
        restore(&i2, &Params::default()),
        Err(Error::Mask { name: "mask", .. })
    ));
    let all = vec![true; s.h * s.w];
    let i3 = Input {
        water_mask: Some(&all),
        ..input
    };
    assert!(matches!(
        restore(&i3, &Params::default()),
        Err(Error::Mask {
            name: "water_mask",
            ..
        })
    ));
}

#[test]
fn subsampled_guided_filter_stays_close_to_the_exact_one() {
    // He and Sun's approximation on the rendered scene: the same water type,
    // t_B within a small distance of the exact filter's, the distance
    // correlation kept (METHOD §11)
    let s = scene(240, 320);
    let input = Input {
        image: ImageRef::new(&s.img, s.h, s.w).unwrap(),
        mask: None,
        water_mask: None,
    };
    let exact = restore(&input, &Params::default()).unwrap();
    assert_eq!(exact.guided_subsample, 1);
    for sub in [2usize, 4, 0] {
        let r = restore(&input, &Params { guided_subsample: sub, ..Params::default() }).unwrap();
        // radius 60: automatic = 60 / 32 = 1 (exact), so 0 must equal the exact run
        let expect = if sub == 0 { 1 } else { sub };
        assert_eq!(r.guided_subsample, expect);
        assert_eq!(r.water_type, exact.water_type, "subsample {sub}");
        let d: Vec<f32> = r.transmission.iter().zip(&exact.transmission).map(|(a, b)| (a - b).abs()).collect();
        let max = d.iter().copied().fold(0f32, f32::max);
        let mean = d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        if expect == 1 {
            assert_eq!(max, 0.0);
        } else {
            assert!(max > 0.0, "subsample {sub} changed nothing");
            assert!(max < 0.05 && mean < 6e-3, "subsample {sub}: max {max}, mean {mean}");
        }
        assert!(common::rho(&s, &r.transmission) > 0.6, "subsample {sub}");
    }
}
