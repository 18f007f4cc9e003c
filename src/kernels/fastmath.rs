//! Powers that vectorize: x^p = 2^(p log2 x) from a polynomial log2 and
//! exp2 evaluated in f64, with plain IEEE operations only (no table, no
//! libm call, no fused multiply-add). A loop of them compiles to SIMD
//! code, and because every operation is an exactly specified f64
//! operation, the SIMD and scalar builds give bit-identical results
//! (METHOD appendix, same bits on every CPU).
//!
//! Error: the f64 value before the final rounding to f32 is within 1e-10
//! (relative) of x^p for every x and p the pipeline forms (|p log2 x| up
//! to 200), so the f32 result is the correctly rounded power or the f32
//! next to it (tested against f64 `powf`).

/// 2^52 + 2^51: adding it rounds an f64 of magnitude below 2^51 to an
/// integer (ties to even) held in the low mantissa bits.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

/// 2^52.
const TWO52: f64 = 4_503_599_627_370_496.0;

/// ln 2.
const LN2: f64 = std::f64::consts::LN_2;

/// log2 of a positive, finite, normal f64 (every positive f32 is one).
/// x = 2^e m with m in [sqrt(1/2), sqrt(2)); ln m = 2 atanh(t),
/// t = (m - 1) / (m + 1), |t| <= 0.1716, from its series to t^11
/// (truncation below 6e-11 relative).
#[inline(always)]
pub fn log2_pos(x: f64) -> f64 {
    let bits = x.to_bits();
    // the biased exponent as an f64 without an integer conversion (which
    // AVX2 lacks for 64-bit lanes): 2^52 + biased, minus 2^52
    let biased = f64::from_bits(0x4330_0000_0000_0000 | ((bits >> 52) & 0x7ff)) - TWO52;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    // fold m from [1, 2) into [sqrt(1/2), sqrt(2))
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { m * 0.5 } else { m };
    let e = biased - if big { 1022.0 } else { 1023.0 };
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    // Estrin's scheme (short dependency chains: the loops are latency bound)
    let t4 = t2 * t2;
    let t8 = t4 * t4;
    let s = (1.0 + t2 * (1.0 / 3.0)) + t4 * (1.0 / 5.0 + t2 * (1.0 / 7.0)) + t8 * (1.0 / 9.0 + t2 * (1.0 / 11.0));
    e + (2.0 / LN2) * t * s
}

/// 2^y for y in [-200, 200] (clamped to it): 2^n 2^f with n = round(y),
/// |f| <= 1/2, 2^f = e^(f ln 2) from its Taylor series to degree 9
/// (truncation below 1e-11 relative); 2^n (a normal f64 for every n in
/// the range) is built from its exponent bits.
#[inline(always)]
pub fn exp2_clamped(y: f64) -> f64 {
    let y = y.clamp(-200.0, 200.0);
    let k = y + ROUND_MAGIC;
    let n = k - ROUND_MAGIC;
    let z = (y - n) * LN2;
    // Estrin's scheme (short dependency chains: the loops are latency bound)
    let z2 = z * z;
    let z4 = z2 * z2;
    let z8 = z4 * z4;
    let p01 = 1.0 + z;
    let p23 = 1.0 / 2.0 + z * (1.0 / 6.0);
    let p45 = 1.0 / 24.0 + z * (1.0 / 120.0);
    let p67 = 1.0 / 720.0 + z * (1.0 / 5040.0);
    let p89 = 1.0 / 40320.0 + z * (1.0 / 362_880.0);
    let p = ((p01 + z2 * p23) + z4 * (p45 + z2 * p67)) + z8 * p89;
    // the low 52 bits of k hold 2^51 + n, n in [-200, 200]: adding
    // 1023 - 2^51 leaves n + 1023 there, the biased exponent of 2^n (a
    // normal f64); the shift drops k's own exponent bits. Unsigned lane
    // operations only (AVX2 has no 64-bit arithmetic shift).
    let scale = f64::from_bits(k.to_bits().wrapping_add(1023u64.wrapping_sub(1 << 51)) << 52);
    p * scale
}

/// x^p for an f32 x >= 0 and an exponent p > 0 (0^p = 0, 1^p = 1 exactly,
/// +inf^p = +inf); see the module documentation for the error.
#[inline(always)]
pub fn pow_pos(x: f32, p: f64) -> f32 {
    let v = exp2_clamped(p * log2_pos(f64::from(x))) as f32;
    if x == 0.0 {
        0.0
    } else if x == f32::INFINITY {
        f32::INFINITY
    } else {
        v
    }
}

/// sgn(d) |d|^p for p > 0 (METHOD §4.1's compensation), 0 for d = 0.
#[inline(always)]
pub fn signed_pow(d: f32, p: f64) -> f32 {
    pow_pos(d.abs(), p).copysign(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f32 nearest to the exact power (f64 powf is within 1 ulp of
    /// f64, far below f32 resolution).
    fn reference(x: f32, p: f64) -> f32 {
        (f64::from(x)).powf(p) as f32
    }

    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    #[test]
    fn exact_cases() {
        for p in [0.3, 0.5, 1.0, 1.7, 2.0, 5.0, 20.0] {
            assert_eq!(pow_pos(0.0, p), 0.0);
            assert_eq!(pow_pos(1.0, p), 1.0);
            assert_eq!(pow_pos(f32::INFINITY, p), f32::INFINITY);
            assert_eq!(signed_pow(-0.0, p), 0.0);
        }
        // powers of two with integer exponents are exact
        assert_eq!(pow_pos(0.5, 2.0), 0.25);
        assert_eq!(pow_pos(8.0, 1.0 / 3.0), 2.0);
        assert_eq!(pow_pos(0.25, 0.5), 0.5);
        assert_eq!(signed_pow(-0.25, 0.5), -0.5);
        assert_eq!(log2_pos(1.0), 0.0);
        assert_eq!(exp2_clamped(0.0), 1.0);
        assert_eq!(exp2_clamped(-3.0), 0.125);
    }

    #[test]
    fn within_one_ulp_of_the_exact_power() {
        // deterministic sweep: x over the whole positive f32 range, dense in
        // [1e-6, 2]; p over the exponents the types use and beyond
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut worst = 0;
        let mut off = 0usize;
        let n = 400_000;
        for i in 0..n {
            let x = if i % 4 == 0 {
                f32::from_bits((next() % 0x7f80_0000) as u32)
            } else {
                (next() % 2_000_000) as f32 * 1e-6 + 1e-6
            };
            let p = 0.05 + (next() % 10_000) as f64 * 5e-4;
            let (a, b) = (pow_pos(x, p), reference(x, p));
            if b == 0.0 || b.is_infinite() || !b.is_normal() {
                // underflow / overflow: same class, and subnormals within 1 ulp
                assert!(ulps(a, b) <= 1, "x {x:e} p {p}: {a:e} vs {b:e}");
                continue;
            }
            let u = ulps(a, b);
            worst = worst.max(u);
            off += usize::from(u > 0);
            assert!(u <= 1, "x {x:e} p {p}: {a:e} vs {b:e} ({u} ulp)");
        }
        // nearly always the correctly rounded value
        assert!(off * 1000 < n, "{off} of {n} not correctly rounded");
        assert!(worst <= 1);
    }

    #[test]
    fn log2_and_exp2_accuracy() {
        for i in 1..20_000 {
            let x = i as f64 * 1.37e-3;
            let e = (log2_pos(x) - x.log2()).abs();
            assert!(e <= 1e-10 * x.log2().abs().max(1.0), "log2 {x}: {e:e}");
            let y = (i as f64 - 10_000.0) * 0.0193;
            let r = (exp2_clamped(y) / y.exp2() - 1.0).abs();
            assert!(r <= 2e-11, "exp2 {y}: {r:e}");
        }
        // clamp: far below and above stay finite f64 (and round to 0 / inf in f32)
        assert_eq!(exp2_clamped(-1e9) as f32, 0.0);
        assert_eq!(exp2_clamped(1e9) as f32, f32::INFINITY);
    }
}
