//! Recovery of the radiance with the artifact clamp (SPEC 7) and the
//! per-channel display stretch (SPEC 8).

use crate::image::ImageRef;
use crate::util::{
    masked_channel, masked_min_max, normalize_masked, percentiles, stretch_channels,
};
use crate::water::WaterType;
use rayon::prelude::*;

/// Lowest transmission of any channel (SPEC 7).
pub const T_FLOOR: f32 = 0.1;

/// t_B clamped to [0.1^beta_BR, 1] (SPEC 7) for one refined value.
#[inline]
pub fn clamp_tb(t: f32, wt: &WaterType) -> f32 {
    let lo = T_FLOOR.powf(wt.beta_br as f32).min(1.0);
    t.clamp(lo, 1.0)
}

/// Per-channel transmissions (t_R, t_G, t_B) from a clamped t_B (SPEC 7).
#[inline]
pub fn channel_t(tb: f32, wt: &WaterType) -> [f32; 3] {
    [
        tb.powf(1.0 / wt.beta_br as f32).clamp(T_FLOOR, 1.0),
        tb.powf(1.0 / wt.beta_bg as f32).clamp(T_FLOOR, 1.0),
        tb,
    ]
}

/// Recovers J = A + (I - A) / t_c (SPEC 7) from the refined transmission and
/// applies the artifact clamp (statistics over masked-in pixels). Returns
/// (J interleaved, clamped t_B).
pub fn recover(
    img: &ImageRef,
    a: [f32; 3],
    t_refined: &[f32],
    wt: &WaterType,
    mask: Option<&[bool]>,
) -> (Vec<f32>, Vec<f32>) {
    let tb: Vec<f32> = t_refined.par_iter().map(|&t| clamp_tb(t, wt)).collect();
    let mut j = vec![0f32; img.data.len()];
    j.par_chunks_mut(3).enumerate().for_each(|(i, o)| {
        let t = channel_t(tb[i], wt);
        let p = img.px(i);
        for c in 0..3 {
            o[c] = a[c] + (p[c] - a[c]) / t[c];
        }
    });
    artifact_clamp(&mut j, mask);
    (j, tb)
}

/// SPEC 7's last line, min and max over the masked-in pixels' channels
/// (all pixels without a mask), applied to every pixel:
/// J -= max(min J, -0.08); J = max(J, 0); J /= min(max J, 1.6); J = min(J, 1).
pub fn artifact_clamp(j: &mut [f32], mask: Option<&[bool]>) {
    let (lo, _) = masked_min_max(j, mask);
    let shift = if lo.is_finite() { lo.max(-0.08) } else { 0.0 };
    j.par_iter_mut().for_each(|v| *v = (*v - shift).max(0.0));
    let (_, hi) = masked_min_max(j, mask);
    let div = hi.min(1.6);
    if div > 0.0 {
        j.par_iter_mut().for_each(|v| *v = (*v / div).min(1.0));
    }
}

/// The display stretch of SPEC 8: global min-max, then per channel a linear
/// stretch between its 0.1% and 99.9% percentiles with the upper limit at
/// least 0.8 (0.9 for red) and the lower at most 0.2, clipped to [0, 1].
/// Limits come from the masked-in pixels (all without a mask), so that a
/// masked-out color chart cannot change them; they apply to every pixel.
pub fn display_stretch(j: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let x = normalize_masked(j, mask);
    let limits = [0, 1, 2].map(|c| {
        let p = percentiles(masked_channel(&x, c, mask), &[0.001, 0.999]);
        let top = if c == 0 { 0.9 } else { 0.8 };
        Some((p[0].min(0.2), p[1].max(top)))
    });
    stretch_channels(&x, limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transmissions_by_hand() {
        let wt = WaterType::new("x", 0.5, 2.0).unwrap();
        // lower clamp of t_B: 0.1^0.5 = 0.3162
        assert!((clamp_tb(0.05, &wt) - 0.1f32.sqrt()).abs() < 1e-6);
        assert_eq!(clamp_tb(1.3, &wt), 1.0);
        // t_B = 0.64: t_R = 0.64^2 = 0.4096, t_G = 0.64^0.5 = 0.8
        let t = channel_t(0.64, &wt);
        assert!((t[0] - 0.4096).abs() < 1e-6 && (t[1] - 0.8).abs() < 1e-6 && t[2] == 0.64);
    }

    #[test]
    fn recovery_of_one_pixel_by_hand() {
        // Render I = t J + (1 - t) A with t = (0.4096, 0.8, 0.64) and recover J.
        let wt = WaterType::new("x", 0.5, 2.0).unwrap();
        let a = [0.1f32, 0.4, 0.6];
        let jt = [0.5f32, 0.3, 0.2];
        let t = [0.4096f32, 0.8, 0.64];
        let mut d = Vec::new();
        for k in 0..16 {
            // pixel 0 is the test pixel; the rest is water (I = A) so that
            // the artifact clamp's min and max come from known values.
            for c in 0..3 {
                d.push(if k == 0 {
                    t[c] * jt[c] + (1.0 - t[c]) * a[c]
                } else {
                    a[c]
                });
            }
        }
        let img = ImageRef::new(&d, 4, 4).unwrap();
        let mut tr = vec![1.0f32; 16];
        tr[0] = 0.64;
        let (j, tb) = recover(&img, a, &tr, &wt, None);
        assert_eq!(tb[0], 0.64);
        // before the clamp: J0 = (0.5, 0.3, 0.2), water = A; min 0.1 -> shift 0.1;
        // max 0.5 (water's B: 0.6 - 0.1) -> divide by 0.5
        let expect = [(0.5 - 0.1) / 0.5, (0.3 - 0.1) / 0.5, (0.2 - 0.1) / 0.5];
        for c in 0..3 {
            assert!(
                (j[c] - expect[c]).abs() < 1e-5,
                "{c}: {} vs {}",
                j[c],
                expect[c]
            );
        }
    }

    #[test]
    fn masked_out_values_do_not_set_the_limits() {
        // pixel 1 is masked out and extreme: min/max come from pixel 0 only
        let mut j = vec![0.2f32, 0.4, 0.6, -3.0, 9.0, 0.5];
        artifact_clamp(&mut j, Some(&[true, false]));
        // shift 0.2 -> (0, 0.2, 0.4); max 0.4 -> (0, 0.5, 1)
        for (a, b) in j[..3].iter().zip([0.0f32, 0.5, 1.0]) {
            assert!((a - b).abs() < 1e-6, "{j:?}");
        }
        let s = display_stretch(
            &[0.2, 0.4, 0.6, 0.2, 0.4, 0.6, 5.0, 5.0, 5.0],
            Some(&[true, true, false]),
        );
        let t = display_stretch(
            &[0.2, 0.4, 0.6, 0.2, 0.4, 0.6, -1.0, 0.0, 1.0],
            Some(&[true, true, false]),
        );
        assert_eq!(&s[..6], &t[..6]);
    }

    #[test]
    fn artifact_clamp_cases() {
        let mut j = vec![-0.5f32, 0.0, 2.0, 1.0];
        // shift by -0.08 -> (-0.42, 0.08, 2.08, 1.08) -> clip 0 -> divide by 1.6 -> min 1
        artifact_clamp(&mut j, None);
        let e = [0.0, 0.08 / 1.6, 1.0, 1.08 / 1.6];
        for (a, b) in j.iter().zip(e) {
            assert!((a - b).abs() < 1e-6);
        }
        let mut z = vec![0.0f32; 4];
        artifact_clamp(&mut z, None);
        assert!(z.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn stretch_limits_by_hand() {
        // 1000 gray pixels k / 999 * 0.1 + 0.05: global min-max gives x = k / 999;
        // per channel p0.1% sits at position 0.999 -> 0.001, p99.9% at 998.001
        // -> 998.001 / 999; lo = min(0.001, 0.2), hi = max(0.998999, 0.8 or 0.9).
        let j: Vec<f32> = (0..1000)
            .flat_map(|k| [k as f32 / 999.0 * 0.1 + 0.05; 3])
            .collect();
        let s = display_stretch(&j, None);
        let (lo, hi) = (0.001f64, 998.001f64 / 999.0);
        for k in 0..1000 {
            let x = k as f64 / 999.0;
            let e = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
            for c in 0..3 {
                assert!((s[3 * k + c] as f64 - e).abs() < 1e-5, "k={k} c={c}");
            }
        }
        // limits are forced: a channel concentrated in [0.3, 0.5] keeps lo <= 0.2, hi >= 0.8
        let mut q = vec![0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0];
        q.extend((0..1000).flat_map(|k| [0.3 + 0.2 * k as f32 / 999.0; 3]));
        let s = display_stretch(&q, None);
        // a value 0.4 (mid) maps to (0.4 - 0.2) / (0.8 - 0.2) = 1/3 in G and B, (0.2 / 0.7) in R
        let mid = 6 + 3 * 500;
        let x = q[mid] as f64;
        assert!((s[mid + 1] as f64 - (x - 0.2) / 0.6).abs() < 1e-5);
        assert!((s[mid] as f64 - (x - 0.2) / 0.7).abs() < 1e-5);
        assert!(display_stretch(&[0.3f32; 6], None)
            .iter()
            .all(|&v| v == 0.0));
    }
}
