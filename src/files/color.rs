//! Pixel conventions of the I/O layers (docs/OUTPUTS.md): the sRGB transfer
//! curves, quantisation, the colour map of t, the `--max-side` factor and
//! the optional reference preprocessing of METHOD §2.
//!
//! These are not part of the method (the core takes and returns linear
//! data); they live in the crate so that the Python package (through
//! `uwhl_rs._core`) and the `uwhl-rs` binary use one implementation and
//! write identical files.

use crate::kernels::util::{channel_percentiles, percentiles};
use rayon::prelude::*;

/// The inverse sRGB curve (IEC 61966-2-1): an encoded value in [0, 1] to linear.
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB curve (IEC 61966-2-1): a linear value in [0, 1] to encoded.
pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A lookup table from every code of an unsigned integer image with
/// maximum `max_code` to f32 in [0, 1], through the inverse sRGB curve when
/// `linearize`.
fn decode_table(max_code: u32, linearize: bool) -> Vec<f32> {
    let m = f64::from(max_code);
    (0..=max_code)
        .into_par_iter()
        .map(|c| {
            let v = f64::from(c) / m;
            (if linearize { srgb_to_linear(v) } else { v }) as f32
        })
        .collect()
}

/// Codes to f32 through `lut` (built for the code type's full range).
fn decode_with<C: Copy + Into<u32> + Sync>(codes: &[C], lut: &[f32]) -> Vec<f32> {
    codes
        .par_iter()
        .map(|&c| lut.get(c.into() as usize).copied().unwrap_or(0.0))
        .collect()
}

/// Decodes 8-bit codes to f32 in [0, 1] (linearised when `linearize`).
pub fn decode_u8(codes: &[u8], linearize: bool) -> Vec<f32> {
    decode_with(codes, &decode_table(u32::from(u8::MAX), linearize))
}

/// Decodes 16-bit codes to f32 in [0, 1] (linearised when `linearize`).
pub fn decode_u16(codes: &[u16], linearize: bool) -> Vec<f32> {
    decode_with(codes, &decode_table(u32::from(u16::MAX), linearize))
}

/// One value to a code in 0..=max: clip to [0, 1] (NaN -> 0), the sRGB
/// curve when `srgb`, then `floor(v * max + 0.5)`.
pub fn quantize_one(v: f32, max: f64, srgb: bool) -> u16 {
    let x = if v.is_nan() {
        0.0
    } else {
        f64::from(v).clamp(0.0, 1.0)
    };
    let e = if srgb { linear_to_srgb(x) } else { x };
    // e * max + 0.5 >= 0.5: truncation is the floor (and needs no libm
    // call on baseline x86-64, which has no rounding instruction)
    (e * max + 0.5).min(max) as u16
}

/// Values in [0, 1] to 8-bit codes (docs/OUTPUTS.md): the codes of
/// [`quantize_one`].
pub fn quantize_u8(data: &[f32], srgb: bool) -> Vec<u8> {
    quantize_with(data, 255, srgb, |c| c as u8)
}

/// Values in [0, 1] to 16-bit codes (docs/OUTPUTS.md): the codes of
/// [`quantize_one`].
pub fn quantize_u16(data: &[f32], srgb: bool) -> Vec<u16> {
    quantize_with(data, 65535, srgb, |c| c)
}

/// Values per work item of the quantiser and the colour map.
const CHUNK: usize = 1 << 14;

/// [`quantize_one`] over `data` in parallel chunks; with the sRGB curve,
/// through the tables of [`SrgbCodes`] (the same codes, 3x faster than a
/// libm power per value: criterion `outputs/`, 1080p).
fn quantize_with<C: Copy + Default + Send>(data: &[f32], max: u16, srgb: bool, cast: impl Fn(u16) -> C + Sync) -> Vec<C> {
    let mut out = vec![C::default(); data.len()];
    let table = if srgb { Some(SrgbCodes::get(max)) } else { None };
    out.par_chunks_mut(CHUNK).zip(data.par_chunks(CHUNK)).for_each(|(o, d)| match table {
        Some(t) => o.iter_mut().zip(d).for_each(|(o, &v)| *o = cast(t.code(v))),
        None => o.iter_mut().zip(d).for_each(|(o, &v)| *o = cast(quantize_one(v, f64::from(max), false))),
    });
    out
}

/// The f32 bits of 2^-9 (below the sRGB curve's breakpoint 0.0031308:
/// smaller values are on its linear piece).
const NODE_BASE: u32 = 0x3b00_0000;
/// Interpolation nodes every 2^13 f32 steps: 1024 per octave.
const NODE_SHIFT: u32 = 13;

/// The exact code thresholds of [`quantize_one`] with the sRGB curve for
/// codes 0..=max: `lo[c]` is the smallest f32 in [0, 1] whose code is at
/// least c (`quantize_one` is monotone in its value: the curve and the
/// rounding are), and `lo[max + 1]` = +inf.
///
/// A code is found in two steps: an estimate within one code, from the
/// curve (times max) linearly interpolated between nodes 2^-10 of an
/// octave apart (interpolation error below 1e-7 relative, 0.01 of a
/// 16-bit code), then one comparison with each neighbouring threshold.
struct SrgbCodes {
    lo: Vec<f32>,
    /// the curve times max at the f32 with bits NODE_BASE + (k << NODE_SHIFT)
    node: Vec<f32>,
    max: u16,
}

impl SrgbCodes {
    /// The tables for 8- and 16-bit codes, built once per process (about
    /// 70000 evaluations of the curve).
    fn get(max: u16) -> &'static SrgbCodes {
        static U8: std::sync::OnceLock<SrgbCodes> = std::sync::OnceLock::new();
        static U16: std::sync::OnceLock<SrgbCodes> = std::sync::OnceLock::new();
        let cell = if max == 255 { &U8 } else { &U16 };
        cell.get_or_init(|| SrgbCodes::new(max))
    }

    fn new(max: u16) -> Self {
        let m = f64::from(max);
        let code = |x: f32| quantize_one(x, m, true);
        let lo = (0..=max)
            .into_par_iter()
            .map(|c| {
                if c == 0 {
                    return 0.0;
                }
                // start at the inverse curve of the code's lower edge and
                // step by ulps to the first value with code >= c
                let mut x = (srgb_to_linear((f64::from(c) - 0.5) / m) as f32).clamp(0.0, 1.0);
                while x > 0.0 && code(prev_f32(x)) >= c {
                    x = prev_f32(x);
                }
                while x < 1.0 && code(x) < c {
                    x = next_f32(x);
                }
                x
            })
            .chain(rayon::iter::once(f32::INFINITY))
            .collect();
        let nodes = ((0x3f80_0000 - NODE_BASE) >> NODE_SHIFT) + 2;
        let node = (0..nodes)
            .map(|k| (linear_to_srgb(f64::from(f32::from_bits(NODE_BASE + (k << NODE_SHIFT)))) * m) as f32)
            .collect();
        Self { lo, node, max }
    }

    /// The code of `v`: [`quantize_one`]'s with the sRGB curve.
    #[inline(always)]
    fn code(&self, v: f32) -> u16 {
        // NaN, negatives and -0.0 -> +0.0 (whose bits index the tables)
        let x = if v > 0.0 { v.min(1.0) } else { 0.0 };
        let b = x.to_bits();
        let est = if b < NODE_BASE {
            12.92 * f32::from(self.max) * x
        } else {
            let k = ((b - NODE_BASE) >> NODE_SHIFT) as usize;
            let frac = (b & ((1 << NODE_SHIFT) - 1)) as f32 * (1.0 / (1 << NODE_SHIFT) as f32);
            match (self.node.get(k), self.node.get(k + 1)) {
                (Some(&n0), Some(&n1)) => n0 + frac * (n1 - n0),
                _ => f32::from(self.max),
            }
        };
        // within one code of the exact one (saturating cast: >= 0 here)
        let c = usize::from(((est + 0.5) as u16).min(self.max));
        let down = self.lo.get(c).is_some_and(|&t| x < t);
        let up = self.lo.get(c + 1).is_some_and(|&t| x >= t);
        (c + usize::from(up) - usize::from(down & (c > 0))) as u16
    }
}

/// The next f32 toward +inf (for finite x >= 0).
fn next_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() + 1)
}

/// The next f32 toward 0 (for finite x > 0).
fn prev_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() - 1)
}

/// The nine viridis anchors of the transmission colour map, t = 0, 1/8, ..., 1.
pub const VIRIDIS: [[f64; 3]; 9] = [
    [68.0, 1.0, 84.0],
    [71.0, 44.0, 122.0],
    [59.0, 81.0, 139.0],
    [44.0, 113.0, 142.0],
    [33.0, 145.0, 140.0],
    [39.0, 173.0, 129.0],
    [92.0, 200.0, 99.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 37.0],
];

/// One t in [0, 1] (clipped; NaN -> 0) to its 8-bit RGB colour.
pub fn colormap_one(t: f32) -> [u8; 3] {
    let t = if t.is_nan() {
        0.0
    } else {
        f64::from(t).clamp(0.0, 1.0)
    };
    let x = t * 8.0;
    // x >= 0: truncation is the floor (no libm call)
    let i = (x as usize).min(7);
    let f = x - i as f64;
    let lo = VIRIDIS.get(i).copied().unwrap_or(VIRIDIS[0]);
    let hi = VIRIDIS.get(i + 1).copied().unwrap_or(VIRIDIS[8]);
    let mut out = [0u8; 3];
    for ((o, l), h) in out.iter_mut().zip(lo).zip(hi) {
        // between two anchors in 0..=255, plus 0.5: truncation is the floor
        *o = (l + f * (h - l) + 0.5).min(255.0) as u8;
    }
    out
}

/// A transmission map to interleaved 8-bit RGB (dark = far, yellow = near).
pub fn colormap(t: &[f32]) -> Vec<u8> {
    let mut out = vec![[0u8; 3]; t.len()];
    out.par_chunks_mut(CHUNK)
        .zip(t.par_chunks(CHUNK))
        .for_each(|(o, d)| o.iter_mut().zip(d).for_each(|(o, &v)| *o = colormap_one(v)));
    out.into_flattened()
}

/// The block size of `--max-side n`: `ceil(max(h, w) / n)`, 1 when the image fits.
pub fn max_side_factor(h: usize, w: usize, n: usize) -> usize {
    h.max(w).div_ceil(n.max(1)).max(1)
}

/// METHOD §2, reference preprocessing of an sRGB input (kept as-is, not
/// linearised): per channel the 1% and 99% percentiles (over masked-in
/// pixels), each pulled 80% of the way toward the mean of the three
/// channels' limits, then a linear stretch clipped to [0, 1]. A channel
/// whose limits coincide is left unchanged.
pub fn reference_srgb_stretch(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let lims = channel_percentiles(data, mask, &[0.01, 0.99], |_, v| v);
    let lim = |c: usize, k: usize| lims.get(c).and_then(|l| l.get(k)).copied().unwrap_or(0.0);
    let mean = |k: usize| (lim(0, k) + lim(1, k) + lim(2, k)) / 3.0;
    let pulled = [0, 1, 2].map(|c| {
        let lo = lim(c, 0) + 0.8 * (mean(0) - lim(c, 0));
        let hi = lim(c, 1) + 0.8 * (mean(1) - lim(c, 1));
        (hi - lo > 1e-12).then_some((lo, hi))
    });
    apply_limits(data, pulled)
}

/// METHOD §2, reference preprocessing of a raw input (already white balanced
/// by the decoder): scale so the 99.999th percentile of the per-pixel
/// channel maximum is 1, then stretch each channel from 0 to its 99.9th
/// percentile (clipping the top 0.1%), clipped to [0, 1].
pub fn reference_raw_stretch(data: &[f32]) -> Vec<f32> {
    let maxes: Vec<f32> = data
        .par_chunks_exact(3)
        .map(|p| p.iter().copied().fold(f32::MIN, f32::max))
        .collect();
    let top = percentiles(maxes, &[0.99999])
        .first()
        .copied()
        .unwrap_or(1.0);
    let scale = if top > 1e-12 { 1.0 / top } else { 1.0 };
    let scaled: Vec<f32> = data
        .par_iter()
        .map(|&v| (f64::from(v) * scale).clamp(0.0, 1.0) as f32)
        .collect();
    let tops = channel_percentiles(&scaled, None, &[0.999], |_, v| v);
    let limits = [0, 1, 2].map(|c| {
        let hi = tops.get(c).and_then(|t| t.first()).copied().unwrap_or(1.0);
        (hi > 1e-12).then_some((0.0, hi))
    });
    apply_limits(&scaled, limits)
}

/// `(v - lo) / (hi - lo)` clipped to [0, 1] per channel; `None` leaves the
/// channel as it is.
fn apply_limits(data: &[f32], limits: [Option<(f64, f64)>; 3]) -> Vec<f32> {
    data.par_chunks_exact(3)
        .flat_map_iter(|p| {
            let mut o = [0f32; 3];
            for ((o, &v), l) in o.iter_mut().zip(p).zip(limits) {
                *o = match l {
                    Some((lo, hi)) => ((f64::from(v) - lo) / (hi - lo)).clamp(0.0, 1.0) as f32,
                    None => v,
                };
            }
            o
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curves_match_the_standard_points() {
        // IEC 61966-2-1: 18% linear gray encodes to 0.4613561 (118/255 = 0.4627)
        assert!((linear_to_srgb(0.18) - 0.461_356_1).abs() < 1e-6);
        // the two pieces meet at the breakpoints
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-12);
        assert!((srgb_to_linear(0.040_450_001) - 0.003_130_8).abs() < 1e-6);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-12);
        assert_eq!(srgb_to_linear(0.0), 0.0);
    }

    #[test]
    fn decode_then_encode_is_identity_on_every_16_bit_code() {
        let codes: Vec<u16> = (0..=u16::MAX).collect();
        let lin = decode_u16(&codes, true);
        let back = quantize_u16(&lin, true);
        assert_eq!(back, codes);
        let codes8: Vec<u8> = (0..=u8::MAX).collect();
        assert_eq!(quantize_u8(&decode_u8(&codes8, true), true), codes8);
    }

    /// Values that exercise the sRGB quantiser: specials, out of range,
    /// the curve's breakpoint, a deterministic spread over all f32 in
    /// [0, 1], and a few ulps around every code threshold of both depths.
    fn quantizer_probes() -> Vec<f32> {
        let mut v = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0, -0.0, 0.0, 1e-45, 1e-38, 1.0, 1.0000001, 2.0];
        let bp = 0.003_130_8f32;
        v.extend((0..64).map(|k| f32::from_bits(bp.to_bits() - 32 + k)));
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..400_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            v.push(f32::from_bits((state % 0x3f80_0001) as u32));
        }
        for max in [255u16, 65535] {
            for &t in SrgbCodes::get(max).lo.iter().skip(1).filter(|t| t.is_finite()) {
                v.extend((0..7).map(|k| f32::from_bits(t.to_bits() + k - 3)));
            }
        }
        v
    }

    #[test]
    fn srgb_code_thresholds_are_the_first_value_of_each_code() {
        for max in [255u16, 65535] {
            let t = SrgbCodes::get(max);
            assert_eq!(t.lo.len(), usize::from(max) + 2);
            assert_eq!(t.lo.last(), Some(&f32::INFINITY));
            for (c, &x) in t.lo.iter().enumerate().take(usize::from(max) + 1).skip(1) {
                assert!(quantize_one(x, f64::from(max), true) >= c as u16, "{max}: code {c} at {x:e}");
                assert!(quantize_one(prev_f32(x), f64::from(max), true) < c as u16, "{max}: code {c} below {x:e}");
            }
            // the codes' first values by the curve's inverse: a half step below each code
            let c = usize::from(max) / 2;
            let want = srgb_to_linear((c as f64 - 0.5) / f64::from(max));
            assert!((f64::from(t.lo[c]) - want).abs() <= 1e-7 * want, "{} vs {want}", t.lo[c]);
        }
    }

    #[test]
    fn fast_srgb_quantiser_gives_the_codes_of_the_formula() {
        let v = quantizer_probes();
        let want8: Vec<u8> = v.iter().map(|&x| quantize_one(x, 255.0, true) as u8).collect();
        let want16: Vec<u16> = v.iter().map(|&x| quantize_one(x, 65535.0, true)).collect();
        let first_difference = |a: &[u16], b: &[u16]| a.iter().zip(b).position(|(x, y)| x != y);
        let got8: Vec<u16> = quantize_u8(&v, true).into_iter().map(u16::from).collect();
        let want8: Vec<u16> = want8.into_iter().map(u16::from).collect();
        let d = first_difference(&got8, &want8);
        assert!(d.is_none(), "8 bits: {:?}", d.map(|i| (v[i], got8[i], want8[i])));
        let got16 = quantize_u16(&v, true);
        let d = first_difference(&got16, &want16);
        assert!(d.is_none(), "16 bits: {:?}", d.map(|i| (v[i], got16[i], want16[i])));
        // and the formula itself by hand: 18% gray -> 0.4613561 -> 118 / 30235
        assert_eq!(quantize_u8(&[0.18], true), vec![118]);
        assert_eq!(quantize_u16(&[0.18], true), vec![30235]);
    }

    /// Every f32 in [0, 1] (about 1.07e9 values) through both depths: the
    /// proof that the thresholds give the formula's codes everywhere
    /// (`quantize_one` is monotone). About a minute in release mode; run
    /// with `cargo test --release -- --ignored every_f32`.
    #[test]
    #[ignore]
    fn every_f32_in_the_unit_interval_gets_the_formulas_code() {
        (0u32..=0x3f80_0000 >> 16).into_par_iter().for_each(|hi| {
            let v: Vec<f32> = (hi << 16..(hi + 1) << 16).map(f32::from_bits).filter(|&x| x <= 1.0).collect();
            let q8 = quantize_u8(&v, true);
            let q16 = quantize_u16(&v, true);
            for ((&x, &a), &b) in v.iter().zip(&q8).zip(&q16) {
                assert_eq!(a as u16, quantize_one(x, 255.0, true), "{x:e}");
                assert_eq!(b, quantize_one(x, 65535.0, true), "{x:e}");
            }
        });
    }

    #[test]
    fn quantize_clips_and_rounds_half_up() {
        assert_eq!(quantize_u8(&[-1.0, 2.0, f32::NAN, 0.5], false), vec![0, 255, 0, 128]);
        // 1.5 / 255 is exactly a half step: rounds up
        assert_eq!(quantize_one(1.5 / 255.0, 255.0, false), 2);
    }

    #[test]
    fn colormap_hits_anchors_and_interpolates() {
        assert_eq!(colormap_one(0.0), [68, 1, 84]);
        assert_eq!(colormap_one(1.0), [253, 231, 37]);
        assert_eq!(colormap_one(0.5), [33, 145, 140]);
        // halfway between anchors 7 and 8: (170+253)/2 = 211.5 -> 212
        assert_eq!(colormap_one(15.0 / 16.0), [212, 226, 44]);
        assert_eq!(colormap_one(f32::NAN), [68, 1, 84]);
        assert_eq!(colormap(&[0.0, 1.0]), vec![68, 1, 84, 253, 231, 37]);
        // more values than one work item, in order
        let t: Vec<f32> = (0..40_000).map(|i| (i % 997) as f32 / 996.0).collect();
        let want: Vec<u8> = t.iter().flat_map(|&v| colormap_one(v)).collect();
        assert_eq!(colormap(&t), want);
    }

    #[test]
    fn max_side_factor_is_the_smallest_fitting_block() {
        assert_eq!(max_side_factor(100, 200, 1024), 1);
        assert_eq!(max_side_factor(3000, 4000, 1024), 4); // 4000/4 = 1000
        assert_eq!(max_side_factor(3000, 4096, 1024), 4);
        assert_eq!(max_side_factor(3000, 4097, 1024), 5);
        assert_eq!(max_side_factor(5, 5, 0), 5);
    }

    #[test]
    fn reference_srgb_stretch_pulls_limits_toward_their_mean() {
        // 101 pixels: channel c takes values c*0.01 + k/1000, k = 0..100, so
        // its 1%/99% limits are c*0.01 + 0.001 and c*0.01 + 0.099.
        let mut d = Vec::new();
        for k in 0..=100 {
            for c in 0..3 {
                d.push(c as f32 * 0.01 + k as f32 / 1000.0);
            }
        }
        let s = reference_srgb_stretch(&d, None);
        // mean limits: 0.011 and 0.109; channel 0 pulled: lo = 0.001 + 0.8*0.01 = 0.009
        let (lo, hi) = (0.009, 0.107);
        let want = ((d[3 * 50] as f64 - lo) / (hi - lo)).clamp(0.0, 1.0);
        assert!((s[3 * 50] as f64 - want).abs() < 1e-5, "{} vs {want}", s[150]);
        // every channel's window is 0.2*0.098 + 0.8*0.098 wide after pulling
        let spans: Vec<f64> = (0..3)
            .map(|c| (s[3 * 60 + c] - s[3 * 40 + c]) as f64)
            .collect();
        assert!(spans.iter().all(|v| (v - 0.02 / 0.098).abs() < 1e-4), "{spans:?}");
    }

    #[test]
    fn reference_raw_stretch_scales_top_to_one() {
        // a dark raw frame: values up to 0.25 in every channel
        let d: Vec<f32> = (0..3000).map(|i| (i % 1000) as f32 / 4000.0).collect();
        let s = reference_raw_stretch(&d);
        let max = s.iter().copied().fold(0.0f32, f32::max);
        assert_eq!(max, 1.0);
        // the median value 0.125 lands near 0.5 (scaled by about 4)
        let mid = s[500 * 3];
        assert!((mid - 0.5).abs() < 0.01, "{mid}");
        assert!(s.iter().all(|v| (0.0..=1.0).contains(v)));
    }
}
