//! Pixel conventions of the I/O layers (docs/OUTPUTS.md): the sRGB transfer
//! curves, quantisation, the colour map of t, the `--max-side` factor and
//! the optional reference preprocessing of SPEC 2.
//!
//! These are not part of the method (the core takes and returns linear
//! data); they live in the crate so that the Python package (through
//! `uwhl_rs._core`) and the `uwhl-rs` binary use one implementation and
//! write identical files.

use crate::util::{channel_percentiles, percentiles};
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
    (e * max + 0.5).floor().clamp(0.0, max) as u16
}

/// Values in [0, 1] to 8-bit codes (docs/OUTPUTS.md).
pub fn quantize_u8(data: &[f32], srgb: bool) -> Vec<u8> {
    data.par_iter()
        .map(|&v| quantize_one(v, 255.0, srgb) as u8)
        .collect()
}

/// Values in [0, 1] to 16-bit codes (docs/OUTPUTS.md).
pub fn quantize_u16(data: &[f32], srgb: bool) -> Vec<u16> {
    data.par_iter()
        .map(|&v| quantize_one(v, 65535.0, srgb))
        .collect()
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
    let i = (x.floor() as usize).min(7);
    let f = x - i as f64;
    let lo = VIRIDIS.get(i).copied().unwrap_or(VIRIDIS[0]);
    let hi = VIRIDIS.get(i + 1).copied().unwrap_or(VIRIDIS[8]);
    let mut out = [0u8; 3];
    for ((o, l), h) in out.iter_mut().zip(lo).zip(hi) {
        *o = (l + f * (h - l) + 0.5).floor().clamp(0.0, 255.0) as u8;
    }
    out
}

/// A transmission map to interleaved 8-bit RGB (dark = far, yellow = near).
pub fn colormap(t: &[f32]) -> Vec<u8> {
    t.par_iter().flat_map_iter(|&v| colormap_one(v)).collect()
}

/// The block size of `--max-side n`: `ceil(max(h, w) / n)`, 1 when the image fits.
pub fn max_side_factor(h: usize, w: usize, n: usize) -> usize {
    h.max(w).div_ceil(n.max(1)).max(1)
}

/// SPEC 2, reference preprocessing of an sRGB input (kept as-is, not
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

/// SPEC 2, reference preprocessing of a raw input (already white balanced
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
