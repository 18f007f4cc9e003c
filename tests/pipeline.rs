//! End-to-end tests of the Rust API on a scene rendered through the model of
//! METHOD §0 (I = t J + (1 - t) A) with known water type, distances and water.

mod common;

use uwhl::{restore, Error, ImageRef, Input, Params, WaterType};

struct Scene {
    h: usize,
    w: usize,
    img: Vec<f32>,
    z: Vec<f64>,
    water: Vec<bool>,
}

/// Water above row h/3; below, a textured seabed whose distance grows
/// towards the horizon, plus nearer blocks. Type II, beta_B = 0.2 / m.
fn scene(h: usize, w: usize) -> Scene {
    let wt = WaterType::by_name("II").unwrap();
    let a = [0.03f64, 0.24, 0.33];
    let beta_b = 0.2;
    let palette = [
        [0.7, 0.3, 0.2],
        [0.2, 0.6, 0.3],
        [0.3, 0.3, 0.7],
        [0.6, 0.6, 0.5],
        [0.15, 0.15, 0.15],
    ];
    let mut s: u64 = 42;
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 40) as f64 / (1u64 << 24) as f64
    };
    let (mut img, mut z, mut water) = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let horizon = h / 3;
            let is_water = y < horizon;
            let mut d = if is_water {
                f64::INFINITY
            } else {
                1.5 + 9.0 * (h - y) as f64 / (h - horizon) as f64
            };
            if !is_water && (x / 12) % 3 == 1 && y > h / 2 {
                d = (d * 0.5).max(1.0);
            }
            let j = palette[(x / 5 + y / 5 + (x * y) / 97) % palette.len()];
            let tb = if d.is_finite() {
                (-beta_b * d).exp()
            } else {
                0.0
            };
            let t = [tb.powf(1.0 / wt.beta_br), tb.powf(1.0 / wt.beta_bg), tb];
            for c in 0..3 {
                let v = t[c] * j[c] + (1.0 - t[c]) * a[c] + 0.002 * (rnd() - 0.5);
                img.push(v.clamp(0.0, 1.0) as f32);
            }
            z.push(d);
            water.push(is_water);
        }
    }
    Scene {
        h,
        w,
        img,
        z,
        water,
    }
}

/// rho(z, -ln t) over the object pixels (METHOD §11).
fn rho(s: &Scene, t: &[f32]) -> f64 {
    let (zz, lt): (Vec<f64>, Vec<f64>) = s
        .z
        .iter()
        .zip(t)
        .filter(|(z, _)| z.is_finite())
        .map(|(z, t)| (*z, -(*t as f64).ln()))
        .unzip();
    common::pearson(&zz, &lt)
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
    for (c, t) in [0.03f32, 0.24, 0.33].iter().enumerate() {
        assert!(
            (res.veiling_light[c] - t).abs() < 0.01,
            "{:?}",
            res.veiling_light
        );
    }
    let rho = rho(&s, &res.transmission);
    assert!(rho > 0.6, "rho = {rho}");
    assert!(res
        .image
        .iter()
        .chain(&res.radiance)
        .all(|v| (0.0..=1.0).contains(v)));
    assert!(res.transmission.iter().all(|&t| t > 0.0 && t <= 1.0));
}

#[test]
fn bit_identical_for_1_2_4_threads() {
    let s = scene(60, 80);
    let input = Input {
        image: ImageRef::new(&s.img, s.h, s.w).unwrap(),
        mask: None,
        water_mask: None,
    };
    let run = |n| {
        restore(
            &input,
            &Params {
                threads: Some(n),
                ..Params::default()
            },
        )
        .unwrap()
    };
    let base = run(1);
    for n in [2, 4, 1] {
        let r = run(n);
        assert!(r
            .image
            .iter()
            .zip(&base.image)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(r
            .transmission
            .iter()
            .zip(&base.transmission)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(
            r.scores.iter().map(|s| s.1.to_bits()).collect::<Vec<_>>(),
            base.scores
                .iter()
                .map(|s| s.1.to_bits())
                .collect::<Vec<_>>()
        );
        assert_eq!(r.water_type, base.water_type);
    }
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
        assert!(rho(&s, &r.transmission) > 0.6, "subsample {sub}");
    }
}
