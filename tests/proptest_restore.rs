//! Property tests of `restore` (proptest): over random shapes (1x1 up to odd
//! sizes), values (0, 1, subnormals, exactly equal channels, constant
//! images, a single bright pixel), masks and parameters, `restore` returns
//! Ok with finite outputs in [0, 1] or a typed error; it never panics and
//! never reports an internal error.
//!
//! Case counts (per `cargo test` run): 512 random images, 384 degenerate
//! images, 384 mask/parameter combinations; `UWHL_PROPTEST_SCALE=K`
//! multiplies them for long runs by hand. Failing inputs are saved by
//! proptest under `tests/proptest_restore.proptest-regressions`.

use proptest::prelude::*;
use uwhl::{restore, Error, ImageRef, Input, Params, WaterType, JERLOV};

/// One value in [0, 1], biased toward the edge cases.
fn value() -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => 0.0f32..=1.0,
        1 => Just(0.0f32),
        1 => Just(1.0f32),
        1 => Just(f32::MIN_POSITIVE / 2.0), // subnormal
        1 => Just(f32::from_bits(1)),       // the smallest subnormal
        1 => Just(1.0 - f32::EPSILON / 2.0),
    ]
}

/// A shape from 1x1 to 23x23 (odd sizes included; sides under 4 are errors).
fn shape() -> impl Strategy<Value = (usize, usize)> {
    (1usize..=23, 1usize..=23)
}

/// The properties of a result: Ok with in-range outputs of the right size,
/// or a typed error that is not `Internal`.
fn check(r: Result<uwhl::Restoration, Error>, h: usize, w: usize) -> Result<(), TestCaseError> {
    match r {
        Ok(res) => {
            prop_assert_eq!(res.image.len(), h * w * 3);
            prop_assert_eq!(res.radiance.len(), h * w * 3);
            prop_assert_eq!(res.transmission.len(), h * w);
            prop_assert!(res.image.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
            prop_assert!(res.radiance.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
            prop_assert!(res.transmission.iter().all(|t| t.is_finite() && *t > 0.0 && *t <= 1.0));
            prop_assert!(res.veiling_light.iter().all(|a| a.is_finite() && *a > 0.0 && *a <= 1.0));
            prop_assert!(res.scores.iter().all(|(_, s)| !s.is_nan()));
            prop_assert_eq!(res.veiling_mask.len(), h * w);
        }
        Err(Error::Internal(m)) => return Err(TestCaseError::fail(format!("internal error: {m}"))),
        Err(_) => {}
    }
    Ok(())
}

fn run(data: &[f32], h: usize, w: usize, mask: Option<&[bool]>, water: Option<&[bool]>, p: &Params) -> Result<(), TestCaseError> {
    let image = match ImageRef::new(data, h, w) {
        Ok(i) => i,
        Err(Error::TooSmall { .. }) => {
            prop_assert!(h < 4 || w < 4);
            return Ok(());
        }
        Err(e) => return Err(TestCaseError::fail(format!("unexpected {e}"))),
    };
    let input = Input {
        image,
        mask,
        water_mask: water,
    };
    check(restore(&input, p), h, w)
}

/// `n` cases, times `UWHL_PROPTEST_SCALE` when set.
fn cases(n: u32) -> u32 {
    let k = std::env::var("UWHL_PROPTEST_SCALE")
        .ok()
        .and_then(|v| v.parse::<u32>().ok())
        .unwrap_or(1);
    n.saturating_mul(k.max(1))
}

fn small_params() -> Params {
    Params {
        sphere_points: 64,
        threads: Some(1),
        ..Params::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(512), ..ProptestConfig::default() })]

    /// Random images of random shapes, every value independently drawn.
    #[test]
    fn random_images((h, w) in shape(), seed in any::<u64>(), vals in prop::collection::vec(value(), 64)) {
        // tile the drawn values over the image with a seeded stride so that
        // every pixel is one of the edge-biased draws
        let n = h * w * 3;
        let stride = (seed % 61 + 1) as usize;
        let data: Vec<f32> = (0..n).map(|i| vals[(i * stride + (seed as usize % 64)) % vals.len()]).collect();
        run(&data, h, w, None, None, &small_params())?;
    }
}

/// Degenerate images: constant, gray (equal channels), one bright pixel on
/// black, black with one subnormal, two-valued.
#[derive(Debug, Clone)]
enum Degenerate {
    Constant(f32),
    Gray(Vec<f32>),
    OneBright(usize, [f32; 3]),
    Subnormal(usize),
    TwoValued(f32, f32, u64),
}

fn degenerate() -> impl Strategy<Value = Degenerate> {
    prop_oneof![
        value().prop_map(Degenerate::Constant),
        prop::collection::vec(value(), 1..40).prop_map(Degenerate::Gray),
        (any::<usize>(), [value(), value(), value()]).prop_map(|(i, c)| Degenerate::OneBright(i, c)),
        any::<usize>().prop_map(Degenerate::Subnormal),
        (value(), value(), any::<u64>()).prop_map(|(a, b, s)| Degenerate::TwoValued(a, b, s)),
    ]
}

fn render(d: &Degenerate, h: usize, w: usize) -> Vec<f32> {
    let n = h * w;
    match d {
        Degenerate::Constant(v) => vec![*v; n * 3],
        Degenerate::Gray(vals) => (0..n).flat_map(|i| [vals[i % vals.len()]; 3]).collect(),
        Degenerate::OneBright(k, c) => {
            let mut v = vec![0.0; n * 3];
            let i = k % n;
            v[3 * i..3 * i + 3].copy_from_slice(c);
            v
        }
        Degenerate::Subnormal(k) => {
            let mut v = vec![0.0; n * 3];
            v[k % (n * 3)] = f32::from_bits(1);
            v
        }
        Degenerate::TwoValued(a, b, s) => (0..n * 3)
            .map(|i| if (s >> (i % 64)) & 1 == 1 { *a } else { *b })
            .collect(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(384), ..ProptestConfig::default() })]

    #[test]
    fn degenerate_images((h, w) in shape(), d in degenerate()) {
        let data = render(&d, h, w);
        run(&data, h, w, None, None, &small_params())?;
    }
}

/// A candidate list: a non-empty subset of the Jerlov table, possibly with
/// a custom type of extreme ratios.
fn water_types() -> impl Strategy<Value = Vec<WaterType>> {
    (
        1u16..1024,
        prop::option::of((uwhl::method::water::MIN_RATIO..=uwhl::method::water::MAX_RATIO, uwhl::method::water::MIN_RATIO..=uwhl::method::water::MAX_RATIO)),
    )
        .prop_map(|(bits, custom)| {
            let mut v: Vec<WaterType> = JERLOV
                .iter()
                .enumerate()
                .filter(|(k, _)| bits >> k & 1 == 1)
                .map(|(_, &(n, br, bg))| WaterType::new(n, br, bg).unwrap())
                .collect();
            if let Some((br, bg)) = custom {
                v.push(WaterType::new("custom", br, bg).unwrap());
            }
            v
        })
}

#[derive(Debug, Clone)]
enum MaskKind {
    None,
    Random(u64),
    AllFalse,
    OneTrue(usize),
    AllTrue,
}

fn mask_kind() -> impl Strategy<Value = MaskKind> {
    prop_oneof![
        3 => Just(MaskKind::None),
        3 => any::<u64>().prop_map(MaskKind::Random),
        1 => Just(MaskKind::AllFalse),
        1 => any::<usize>().prop_map(MaskKind::OneTrue),
        1 => Just(MaskKind::AllTrue),
    ]
}

fn make_mask(k: &MaskKind, n: usize) -> Option<Vec<bool>> {
    match k {
        MaskKind::None => None,
        MaskKind::Random(s) => Some((0..n).map(|i| !(s.rotate_left(i as u32 % 64) ^ i as u64).is_multiple_of(3)).collect()),
        MaskKind::AllFalse => Some(vec![false; n]),
        MaskKind::OneTrue(k) => Some((0..n).map(|i| i == k % n).collect()),
        MaskKind::AllTrue => Some(vec![true; n]),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(384), ..ProptestConfig::default() })]

    /// Masks, water masks and every parameter of `Params` over their range
    /// and beyond (radius 0 and larger than the image, eps from 1e-12 to 1e6,
    /// 1 to 700 sphere points, given A including tiny components, the
    /// guided filter exact, automatic or subsampled up to past the image size).
    #[test]
    fn masks_and_parameters(
        (h, w) in (4usize..=19, 4usize..=19),
        seed in any::<u64>(),
        mask in mask_kind(),
        water in mask_kind(),
        types in water_types(),
        a in prop::option::of([1e-7f32..=1.0, 1e-7f32..=1.0, 1e-7f32..=1.0]),
        radius in prop::option::of(0usize..=25),
        eps in prop_oneof![Just(1e-12f64), Just(1e-3), Just(1.0), Just(1e6), 1e-9f64..10.0],
        points in 1usize..=700,
        threads in 1usize..=3,
        subsample in prop_oneof![3 => Just(1usize), 1 => Just(0usize), 2 => 2usize..=25],
    ) {
        let data = {
            let mut rng = seed;
            (0..h * w * 3).map(|_| {
                rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (rng >> 40) as f32 / (1u64 << 24) as f32
            }).collect::<Vec<f32>>()
        };
        let n = h * w;
        let (m, wm) = (make_mask(&mask, n), make_mask(&water, n));
        let p = Params {
            water_types: types,
            veiling_light: a,
            guided_radius: radius,
            guided_eps: eps,
            sphere_points: points,
            threads: Some(threads),
            guided_subsample: subsample,
            ..Params::default()
        };
        run(&data, h, w, m.as_deref(), wm.as_deref(), &p)?;
    }
}
