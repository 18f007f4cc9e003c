//! Inlined powers for the per-pixel passes: x^p = 2^(p log2 x), with log2
//! and 2^y evaluated by short polynomials in f64 and the result rounded to
//! f32. `powf` from the C library is an out-of-line call with special-case
//! handling; these are a few multiply-adds that the compiler keeps in the
//! loop. They also split the power in two, so that a logarithm shared by
//! several powers (the ten water types' exponents of the same pixel, or
//! t_R and t_G from one t_B) is computed once.
//!
//! Accuracy (tested below against f64 `powf` on a dense grid and random
//! values): the relative error of [`log2`] and [`exp2`] before rounding to
//! f32 is below 1e-12, so [`pow`] returns the correctly rounded f32 result
//! except where the exact value lies within about 1e-12 of a rounding
//! boundary; its error is at most one unit in the last place of f32
//! (2^-23 relative), the same bound as the C library's `powf`.
//!
//! Domain: `log2` takes finite x > 0 (subnormal x too); `exp2` takes any
//! finite y and returns 0 below the f32 range and +inf above it, like `powf`.

/// ln 2.
const LN2: f64 = std::f64::consts::LN_2;
/// log2(e).
const LOG2_E: f64 = std::f64::consts::LOG2_E;

/// log2(x) for finite x > 0, with relative error below 1e-12 (absolute
/// below 1e-12 near x = 1). Other x: NaN for x < 0 or NaN, -inf for 0,
/// +inf for +inf (as `f64::log2`).
#[inline(always)]
pub fn log2(x: f32) -> f64 {
    if !(f32::MIN_POSITIVE..f32::INFINITY).contains(&x) {
        // zero, subnormal, negative, infinite or NaN: rare, exact path
        return f64::from(x).log2();
    }
    let bits = x.to_bits();
    // x = 2^e * m with m in [1, 2), then m in [sqrt(1/2), sqrt(2))
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f64::from(f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000));
    if m > std::f64::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    // ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.1716:
    // 2 (s + s^3/3 + ... + s^13/13); the first omitted term is < 4e-13
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let poly = 1.0
        + s2 * (1.0 / 3.0
            + s2 * (1.0 / 5.0
                + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0 + s2 * (1.0 / 11.0 + s2 * (1.0 / 13.0))))));
    f64::from(e) + 2.0 * s * poly * LOG2_E
}

/// 2^y rounded to f32, relative error below 1e-12 before the rounding:
/// 0 below 2^-150 and +inf above the f32 range (as `powf`); NaN for NaN.
#[inline(always)]
pub fn exp2(y: f64) -> f32 {
    if !(y > -126.0 && y < 128.0) {
        // the f32 subnormal range, overflow, NaN: rare, exact path
        return y.exp2() as f32;
    }
    let n = y.round();
    // 2^f = e^(f ln 2) with |f ln 2| <= 0.347: Taylor to degree 11 (the
    // first omitted term is < 2e-14)
    let x = (y - n) * LN2;
    let p = 1.0
        + x * (1.0
            + x * (1.0 / 2.0
                + x * (1.0 / 6.0
                    + x * (1.0 / 24.0
                        + x * (1.0 / 120.0
                            + x * (1.0 / 720.0
                                + x * (1.0 / 5040.0
                                    + x * (1.0 / 40320.0
                                        + x * (1.0 / 362_880.0
                                            + x * (1.0 / 3_628_800.0 + x * (1.0 / 39_916_800.0)))))))))));
    // n in -126..=128: 2^n is a normal f64
    let scale = f64::from_bits(((n as i64 + 1023) as u64) << 52);
    (p * scale) as f32
}

/// x^p for finite x > 0 (0 for x == 0 and p > 0), within one f32 ulp.
#[inline(always)]
pub fn pow(x: f32, p: f32) -> f32 {
    if x == 0.0 {
        return if p > 0.0 { 0.0 } else { x.powf(p) };
    }
    exp2(f64::from(p) * log2(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative error of an f32 result against the f64 value, in f32 ulps
    /// of the exact value.
    fn ulps(got: f32, exact: f64) -> f64 {
        if exact == 0.0 {
            return if got == 0.0 { 0.0 } else { f64::INFINITY };
        }
        let ulp = (exact.abs() as f32).to_bits();
        let ulp = f64::from(f32::from_bits(ulp + 1)) - f64::from(f32::from_bits(ulp));
        (f64::from(got) - exact).abs() / ulp
    }

    fn lcg(s: &mut u64) -> f64 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*s >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn log2_matches_f64_log2() {
        // every 97th f32 from 1e-30 to 1e30, plus exact powers of two
        let (lo, hi) = (1e-30f32.to_bits(), 1e30f32.to_bits());
        let mut worst = 0f64;
        for b in (lo..hi).step_by(97) {
            let x = f32::from_bits(b);
            let exact = f64::from(x).log2();
            let err = (log2(x) - exact).abs() / exact.abs().max(1.0);
            worst = worst.max(err);
        }
        assert!(worst < 1e-12, "worst relative error {worst:e}");
        for e in -126..128 {
            assert_eq!(log2(2f32.powi(e)), f64::from(e), "2^{e}");
        }
        assert_eq!(log2(f32::from_bits(1)), -149.0);
        assert_eq!(log2(1.0), 0.0);
        assert!(log2(0.0) == f64::NEG_INFINITY && log2(-1.0).is_nan() && log2(f32::NAN).is_nan());
        // subnormals take the exact path
        assert_eq!(log2(1e-40), f64::from(1e-40f32).log2());
    }

    #[test]
    fn exp2_matches_f64_exp2() {
        let mut s = 1u64;
        let mut worst = 0f64;
        for _ in 0..2_000_000 {
            let y = -125.9 + 253.8 * lcg(&mut s);
            let exact = y.exp2();
            let got = exp2(y);
            // compare before the f32 rounding: reconstruct from the f64 path
            worst = worst.max(ulps(got, exact));
        }
        assert!(worst <= 0.5 + 1e-6, "worst {worst} ulps");
        for n in -125..128 {
            assert_eq!(exp2(f64::from(n)), 2f32.powi(n), "2^{n}");
        }
        assert_eq!(exp2(-200.0), 0.0);
        assert_eq!(exp2(200.0), f32::INFINITY);
        assert!(exp2(f64::NAN).is_nan());
        assert_eq!(exp2(-140.0), 2f32.powi(-140));
    }

    #[test]
    fn pow_within_one_ulp_and_mostly_correctly_rounded() {
        // the exponents the method uses: beta ratios in [0.03, 30] and their
        // inverses, 1/2.2, 2.4; bases in (0, 1] as in SPEC 4, 7 and the guide
        let mut s = 7u64;
        let (mut worst, mut differ, mut total) = (0f64, 0usize, 0usize);
        for _ in 0..3_000_000 {
            let x = (lcg(&mut s).powi(3)) as f32;
            let p = (0.03 + 30.0 * lcg(&mut s)) as f32;
            if x == 0.0 {
                continue;
            }
            let exact = f64::from(x).powf(f64::from(p));
            if exact < f64::from(f32::MIN_POSITIVE) {
                continue;
            }
            let got = pow(x, p);
            worst = worst.max(ulps(got, exact));
            total += 1;
            if got != exact as f32 {
                differ += 1;
            }
        }
        // 0.5 ulp from the rounding plus < 1e-11 relative before it
        assert!(worst <= 0.501, "worst {worst} ulps");
        // correctly rounded unless within ~1e-12 of a boundary
        assert!(differ * 100_000 < total, "{differ} of {total} not correctly rounded");
        assert_eq!(pow(0.0, 0.7), 0.0);
        assert_eq!(pow(1.0, 0.7), 1.0);
        assert_eq!(pow(0.25, 0.5), 0.5);
        assert_eq!(pow(4.0, 1.5), 8.0);
    }
}
