//! Recovery of the radiance with the artifact clamp (METHOD §7) and the
//! per-channel display stretch (METHOD §8).

use crate::kernels::fastmath::{exp2_clamped, log2_pos};
use crate::kernels::util::{ChannelStretch, Normalize};
use crate::method::water::WaterType;
#[cfg(any(test, feature = "internals"))]
use {
    crate::method::image::ImageRef,
    crate::kernels::util::{channel_percentiles, masked_min_max},
    rayon::prelude::*,
};

/// Lowest transmission of any channel (METHOD §7).
pub const T_FLOOR: f32 = 0.1;

#[cfg(any(test, feature = "internals"))]
/// t_B clamped to [0.1^beta_BR, 1] (METHOD §7) for one refined value.
#[inline]
pub fn clamp_tb(t: f32, wt: &WaterType) -> f32 {
    Recovery::new([1.0; 3], wt).clamp_tb(t)
}

#[cfg(any(test, feature = "internals"))]
/// Per-channel transmissions (t_R, t_G, t_B) from a clamped t_B (METHOD §7).
#[inline]
pub fn channel_t(tb: f32, wt: &WaterType) -> [f32; 3] {
    Recovery::new([1.0; 3], wt).channel_t(tb)
}

/// The per-pixel recovery of METHOD §7 for one water type and veiling light.
#[derive(Debug, Clone, Copy)]
pub struct Recovery {
    a: [f32; 3],
    /// lower clamp of t_B: 0.1^beta_BR (at most 1)
    tb_lo: f32,
    /// 1 / beta_BR, 1 / beta_BG
    inv_beta: [f64; 2],
}

impl Recovery {
    /// The constants for water type `wt` and veiling light `a`.
    pub fn new(a: [f32; 3], wt: &WaterType) -> Self {
        Self {
            a,
            tb_lo: T_FLOOR.powf(wt.beta_br as f32).min(1.0),
            inv_beta: [1.0 / wt.beta_br, 1.0 / wt.beta_bg],
        }
    }

    /// t_B = clamp(t_refined, 0.1^beta_BR, 1).
    #[inline(always)]
    pub fn clamp_tb(&self, t: f32) -> f32 {
        t.clamp(self.tb_lo, 1.0)
    }

    /// (t_R, t_G, t_B) from a clamped t_B: t_c = clamp(t_B^(1/beta_Bc), 0.1, 1).
    #[inline(always)]
    pub fn channel_t(&self, tb: f32) -> [f32; 3] {
        // t_B^(1/beta) = 2^(log2(t_B) / beta): one log2 for both channels
        // (the values of fastmath::pow_pos for t_B in (0, 1]: t_B >=
        // 0.1^beta_BR > 0, and 1 gives 1 exactly)
        let l = log2_pos(f64::from(tb));
        let pw = |ib: f64| exp2_clamped(ib * l) as f32;
        [pw(self.inv_beta[0]).clamp(T_FLOOR, 1.0), pw(self.inv_beta[1]).clamp(T_FLOOR, 1.0), tb]
    }

    /// J_c = A_c + (I_c - A_c) / t_c before the artifact clamp.
    #[inline(always)]
    pub fn radiance(&self, p: [f32; 3], t: [f32; 3]) -> [f32; 3] {
        let a = self.a;
        [
            a[0] + (p[0] - a[0]) / t[0],
            a[1] + (p[1] - a[1]) / t[1],
            a[2] + (p[2] - a[2]) / t[2],
        ]
    }
}

/// METHOD §7 for one row: from the refined transmission `q`, the clamped t_B
/// (to `tb`), t_R (to `tr`) and J before the artifact clamp (to `j`).
/// Compiled for baseline x86-64 and for AVX2, picked at run time; the
/// same bits either way ([`crate::kernels::fastmath`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
pub fn recover_values(rec: &Recovery, q: &[f32], px: &[[f32; 3]], j: &mut [[f32; 3]], tb: &mut [f32], tr: &mut [f32]) {
    for (((qv, p), o), (b, r)) in q.iter().zip(px).zip(j.iter_mut()).zip(tb.iter_mut().zip(tr.iter_mut())) {
        let t = rec.clamp_tb(*qv);
        let tc = rec.channel_t(t);
        *o = rec.radiance(*p, tc);
        *b = t;
        *r = tc[0];
    }
}

/// The artifact clamp of METHOD §7's last line with the statistics over the
/// masked-in pixels' channels:
/// J -= max(min J, -0.08); J = max(J, 0); J /= min(max J, 1.6); J = min(J, 1).
/// A non-decreasing map of J (so it commutes with ranking).
#[derive(Debug, Clone, Copy)]
pub struct ArtifactClamp {
    shift: f32,
    div: Option<f32>,
}

impl ArtifactClamp {
    /// From the min and max of J (before the clamp) over the masked-in
    /// pixels' channels: (inf, -inf) when there is none.
    pub fn new(lo: f32, hi: f32) -> Self {
        let shift = if lo.is_finite() { lo.max(-0.08) } else { 0.0 };
        // max of the shifted, clipped values (f32 subtraction is monotone)
        let top = (hi - shift).max(0.0);
        let div = top.min(1.6);
        Self {
            shift,
            div: (div > 0.0).then_some(div),
        }
    }

    /// The clamped value of one J value.
    #[inline(always)]
    pub fn apply(&self, v: f32) -> f32 {
        let v = (v - self.shift).max(0.0);
        // Without a divisor (every masked-in value at or below the shift),
        // masked-out pixels can still be above 1: the final clip to 1 holds
        // for them too (METHOD §7; found by the property test).
        // v / 1 == v: the same values as a branch, and loops vectorize
        (v / self.div.unwrap_or(1.0)).min(1.0)
    }
}

#[cfg(any(test, feature = "internals"))]
/// Recovers J = A + (I - A) / t_c (METHOD §7) from the refined transmission
/// through the row kernel `restore` runs ([`recover_values`]) and applies
/// the artifact clamp (statistics over masked-in pixels). Returns (J
/// interleaved, clamped t_B).
pub fn recover(
    img: &ImageRef,
    a: [f32; 3],
    t_refined: &[f32],
    wt: &WaterType,
    mask: Option<&[bool]>,
) -> (Vec<f32>, Vec<f32>) {
    let rec = Recovery::new(a, wt);
    let w = img.width.max(1);
    let mut j = vec![0f32; img.data.len()];
    let mut tb = vec![0f32; t_refined.len()];
    let mut tr = vec![0f32; t_refined.len()];
    j.par_chunks_mut(3 * w)
        .zip(tb.par_chunks_mut(w))
        .zip(tr.par_chunks_mut(w))
        .zip(t_refined.par_chunks(w).zip(img.data.par_chunks(3 * w)))
        .for_each(|(((jr, br), rr), (q, px))| {
            recover_values(&rec, q, px.as_chunks::<3>().0, jr.as_chunks_mut::<3>().0, br, rr);
        });
    artifact_clamp(&mut j, mask);
    (j, tb)
}

#[cfg(any(test, feature = "internals"))]
/// METHOD §7's artifact clamp in place (see [`ArtifactClamp`]).
pub fn artifact_clamp(j: &mut [f32], mask: Option<&[bool]>) {
    let (lo, hi) = masked_min_max(j, mask);
    let ac = ArtifactClamp::new(lo, hi);
    j.par_iter_mut().for_each(|v| *v = ac.apply(*v));
}

/// Fractions of the display stretch's percentiles (METHOD §8).
pub const DISPLAY_QS: [f64; 2] = [0.001, 0.999];

/// The stretch limits of METHOD §8 from the 0.1% and 99.9% percentiles of
/// each channel: lo = min(p0.1, 0.2), hi = max(p99.9, 0.8 (0.9 for red)).
pub fn display_limits(pcts: &[Vec<f64>; 3]) -> ChannelStretch {
    let mut c = 0;
    ChannelStretch::new(pcts.clone().map(|p| {
        let top = if c == 0 { 0.9 } else { 0.8 };
        c += 1;
        let lo = p.first().copied().unwrap_or(0.0);
        let hi = p.get(1).copied().unwrap_or(0.0);
        Some((lo.min(0.2), hi.max(top)))
    }))
}

#[cfg(any(test, feature = "internals"))]
/// The display stretch of METHOD §8: global min-max, then per channel a linear
/// stretch between its 0.1% and 99.9% percentiles with the upper limit at
/// least 0.8 (0.9 for red) and the lower at most 0.2, clipped to [0, 1].
/// Limits come from the masked-in pixels (all without a mask), so that a
/// masked-out color chart cannot change them; they apply to every pixel.
pub fn display_stretch(j: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let norm = Normalize::masked(j, mask);
    let pcts = channel_percentiles(j, mask, &DISPLAY_QS, |_, v| norm.apply(v));
    display_limits(&pcts).map_rgb(j, |v| norm.apply(v))
}

/// A type's restored image before its final form: J before the artifact
/// clamp, and the maps that make the outputs from it.
pub(crate) struct Stretch {
    pub(crate) clamp: ArtifactClamp,
    pub(crate) norm: Normalize,
    pub(crate) limits: ChannelStretch,
}

impl Stretch {
    /// The displayed value of channel c of J (METHOD §7 clamp, METHOD §8 stretch).
    #[inline(always)]
    pub(crate) fn apply(&self, c: usize, j: f32) -> f32 {
        self.limits.apply(c, self.norm.apply(self.clamp.apply(j)))
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_kernel_gives_the_per_pixel_bits() {
        // recover_values runs its AVX2 build where the CPU has it; the
        // per-pixel functions here are the baseline build (METHOD appendix, same bits on every CPU)
        let n = 4099;
        let noise = crate::kernels::util::test_noise(4 * n, 11);
        let px: Vec<[f32; 3]> = noise.chunks_exact(3).take(n).map(|c| [c[0], c[1], c[2]]).collect();
        let q: Vec<f32> = noise.iter().skip(3 * n).map(|v| v * 1.2 - 0.1).collect();
        for name in ["I", "II", "5C", "9C"] {
            let rec = Recovery::new([0.1, 0.4, 0.5], &WaterType::by_name(name).unwrap());
            let (mut j, mut tb, mut tr) = (vec![[0f32; 3]; n], vec![0f32; n], vec![0f32; n]);
            recover_values(&rec, &q, &px, &mut j, &mut tb, &mut tr);
            for i in 0..n {
                let t = rec.clamp_tb(q[i]);
                let tc = rec.channel_t(t);
                assert_eq!(tb[i].to_bits(), t.to_bits());
                assert_eq!(tr[i].to_bits(), tc[0].to_bits());
                assert_eq!(j[i].map(f32::to_bits), rec.radiance(px[i], tc).map(f32::to_bits));
            }
        }
    }

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
        // the one masked-in value is 0: no divisor, yet masked-out values are clipped to 1
        let mut m = vec![0.0f32, 0.0, 0.0, 3.0, 0.5, f32::INFINITY];
        artifact_clamp(&mut m, Some(&[true, false]));
        assert_eq!(m, vec![0.0, 0.0, 0.0, 1.0, 0.5, 1.0]);
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
