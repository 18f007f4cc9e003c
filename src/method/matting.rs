//! The Mahalanobis soft matting with the water region (METHOD §5) and the
//! blend of the initial transmission with its lower bound (METHOD §4.6,
//! §5). The lower bound itself is computed in the haze-lines pass
//! ([`crate::method::hazelines`]).

use crate::method::hazelines::T_MIN;
use crate::method::image::ImageRef;
use crate::kernels::util::{det_sum, det_sums, REDUCE_ROWS};
use nalgebra::Matrix3;
use rayon::prelude::*;

/// The soft matting of METHOD §5 as a model of the water's colors: the VL
/// pixels' mean and regularised inverse covariance, and the two thresholds
/// on the squared Mahalanobis distance. Weights are computed per pixel when
/// needed (no per-pixel plane is stored).
#[derive(Debug, Clone, Copy)]
pub struct Matting {
    mu: [f64; 3],
    /// inverse covariance, row-major
    inv: [f64; 9],
    thr_water: f64,
    /// 1 / (thr_notwater - thr_water), or 0 when the thresholds coincide
    inv_span: f64,
}

impl Matting {
    /// Fits the model to the VL pixels of `img` (METHOD §5): mean and
    /// covariance (n - 1) of their colors, ridge C + (1e-6 trace(C) / 3 +
    /// 1e-12) I, and over their own distances d: thr_water = m + 2 s,
    /// thr_notwater = M + s. None with fewer than 2 VL pixels or a singular
    /// matrix.
    pub fn fit(img: &ImageRef, vl: &[bool]) -> Option<Self> {
        let n = img.len();
        let chunk = img.width * REDUCE_ROWS;
        let count = vl.iter().filter(|&&b| b).count();
        if count < 2 || vl.len() != n {
            return None;
        }
        let pixels = img.data.as_chunks::<3>().0;
        let px = |i: usize| -> [f64; 3] {
            pixels.get(i).copied().unwrap_or([0.0; 3]).map(f64::from)
        };
        let in_vl = |i: usize| vl.get(i).copied().unwrap_or(false);
        let s = det_sums::<3, _>(n, chunk, |i, acc| {
            if in_vl(i) {
                let p = px(i);
                acc.iter_mut().zip(p).for_each(|(a, v)| *a += v);
            }
        });
        let mu = s.map(|v| v / count as f64);
        let cs = det_sums::<6, _>(n, chunk, |i, acc| {
            if in_vl(i) {
                let p = px(i);
                let d = [p[0] - mu[0], p[1] - mu[1], p[2] - mu[2]];
                let prods = [d[0] * d[0], d[0] * d[1], d[0] * d[2], d[1] * d[1], d[1] * d[2], d[2] * d[2]];
                acc.iter_mut().zip(prods).for_each(|(a, v)| *a += v);
            }
        });
        let k = (count - 1) as f64;
        let mut cov = Matrix3::new(
            cs[0], cs[1], cs[2], cs[1], cs[3], cs[4], cs[2], cs[4], cs[5],
        ) / k;
        let lambda = 1e-6 * cov.trace() / 3.0 + 1e-12;
        cov += Matrix3::identity() * lambda;
        let inv = cov.try_inverse()?;
        let mut model = Self {
            mu,
            // m<row><col> fields of the 3x3 matrix
            inv: [
                inv.m11, inv.m12, inv.m13, inv.m21, inv.m22, inv.m23, inv.m31, inv.m32, inv.m33,
            ],
            thr_water: 0.0,
            inv_span: 0.0,
        };
        let (tw, tn) = thresholds(vl, img.width, |i| model.distance_px(px(i)) as f64);
        model.set_thresholds(tw, tn);
        Some(model)
    }

    fn set_thresholds(&mut self, thr_water: f64, thr_not: f64) {
        self.thr_water = thr_water;
        let inv = 1.0 / (thr_not - thr_water);
        self.inv_span = if inv > 0.0 && inv.is_finite() { inv } else { 0.0 };
    }

    /// Squared Mahalanobis distance of one color (f64 arithmetic, f32 result).
    #[inline(always)]
    fn distance_px(&self, p: [f64; 3]) -> f32 {
        let d = [p[0] - self.mu[0], p[1] - self.mu[1], p[2] - self.mu[2]];
        let [m0, m1, m2, m3, m4, m5, m6, m7, m8] = self.inv;
        let row = |v: [f64; 3]| -> f64 { v[0] * d[0] + v[1] * d[1] + v[2] * d[2] };
        (d[0] * row([m0, m1, m2]) + d[1] * row([m3, m4, m5]) + d[2] * row([m6, m7, m8])) as f32
    }

    /// Squared Mahalanobis distance of a pixel to the water's colors.
    #[inline(always)]
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        self.distance_px([p[0] as f64, p[1] as f64, p[2] as f64])
    }

    /// The weight w of METHOD §5 (1 = water, 0 = object) for a distance d:
    /// 1 - clamp((d - thr_water) / (thr_notwater - thr_water), 0, 1), or a
    /// hard step at thr_water when the thresholds coincide.
    #[inline(always)]
    pub fn weight_of(&self, d: f32) -> f32 {
        let v = d as f64;
        if self.inv_span > 0.0 {
            (1.0 - ((v - self.thr_water) * self.inv_span).clamp(0.0, 1.0)) as f32
        } else if v <= self.thr_water {
            1.0
        } else {
            0.0
        }
    }

    /// The weight of a pixel.
    #[inline(always)]
    pub fn weight(&self, p: [f32; 3]) -> f32 {
        self.weight_of(self.distance(p))
    }
}

/// The matting thresholds of METHOD §5 from the distances `d(i)` of the VL
/// pixels: m = mean, s = std (n - 1), M = max; (m + 2 s, M + s).
pub fn thresholds<F: Fn(usize) -> f64 + Sync>(vl: &[bool], width: usize, d: F) -> (f64, f64) {
    let n = vl.len();
    let chunk = width.max(1) * REDUCE_ROWS;
    let in_vl = |i: usize| vl.get(i).copied().unwrap_or(false);
    let count = vl.iter().filter(|&&b| b).count().max(1) as f64;
    let mean = det_sum(n, chunk, |i| if in_vl(i) { d(i) } else { 0.0 }) / count;
    let var = det_sum(n, chunk, |i| if in_vl(i) { (d(i) - mean).powi(2) } else { 0.0 })
        / (count - 1.0).max(1.0);
    let max = (0..n)
        .into_par_iter()
        .filter(|&i| in_vl(i))
        .map(&d)
        .reduce(|| f64::NEG_INFINITY, f64::max);
    let sd = var.sqrt();
    (mean + 2.0 * sd, max + sd)
}

#[cfg(any(test, feature = "internals"))]
/// Squared Mahalanobis distances (as MATLAB's `mahal`) of every pixel to the
/// colors of the VL pixels (see [`Matting::fit`]). None with fewer than 2
/// VL pixels.
pub fn mahalanobis_sq(img: &ImageRef, vl: &[bool]) -> Option<Vec<f32>> {
    let m = Matting::fit(img, vl)?;
    Some(img.data.as_chunks::<3>().0.par_iter().map(|&p| m.distance(p)).collect())
}

#[cfg(any(test, feature = "internals"))]
/// Matting weights w of METHOD §5 (1 = water, 0 = object) of every pixel
/// (see [`Matting::weight`]). None with fewer than 2 VL pixels.
pub fn matting_weights(img: &ImageRef, vl: &[bool]) -> Option<Vec<f32>> {
    let m = Matting::fit(img, vl)?;
    Some(img.data.as_chunks::<3>().0.par_iter().map(|&p| m.weight(p)).collect())
}

/// METHOD §4.4-5 for a run of pixels: t~ = clamp(r / r_max, 0.01, 1) from the
/// radius in `p` and the cluster in `aux` (`rm`: r_max by cluster + 1,
/// entry 0 for "no cluster", t~ = 1), or t~ as given in `p` when `tilde`
/// is false; then t = max(scale t~, t_LB) (scale: `t_scale`, METHOD §4.6), blended with t_LB by the matting
/// weight. Compiled for baseline x86-64, AVX2 and AVX-512, picked at run
/// time; the same bits on each (METHOD appendix, same bits on every CPU, F7).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
pub(crate) fn blend_row(p: &mut [f32], aux: &[[f32; 2]], px: &[[f32; 3]], rm: &[f32], matting: Option<&Matting>, tilde: bool, scale: f32) {
    let last = rm.len().saturating_sub(1);
    let tt = |v: f32, x: &[f32; 2]| -> f32 {
        let t = if tilde {
            let k = ((x[1] + 1.0).max(0.0) as usize).min(last);
            match rm.get(k) {
                Some(&m) if m > 0.0 => (v / m).clamp(T_MIN, 1.0),
                _ => 1.0,
            }
        } else {
            v
        };
        (t * scale).max(x[0])
    };
    match matting {
        Some(mt) => {
            for ((v, x), c) in p.iter_mut().zip(aux).zip(px) {
                let t = tt(*v, x);
                let wgt = mt.weight(*c);
                *v = wgt * x[0] + (1.0 - wgt) * t;
            }
        }
        None => {
            for (v, x) in p.iter_mut().zip(aux) {
                *v = tt(*v, x);
            }
        }
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mahalanobis_by_hand() {
        // VL: 4 pixels (0.1,0.2,0.3) +- (0.02, 0, 0) and +- (0, 0.04, 0) in a
        // 4x4 image; covariance (n-1 = 3): diag(2*0.0004/3, 2*0.0016/3, ~0).
        let mut d = vec![0.5f32; 48];
        let vlpx = [
            [0.12, 0.2, 0.3],
            [0.08, 0.2, 0.3],
            [0.1, 0.24, 0.3],
            [0.1, 0.16, 0.3],
        ];
        let mut vl = vec![false; 16];
        for (k, p) in vlpx.iter().enumerate() {
            d[3 * k..3 * k + 3].copy_from_slice(p);
            vl[k] = true;
        }
        // a test pixel at mu + (0.02, 0.04, 0)
        d[3 * 5..3 * 5 + 3].copy_from_slice(&[0.12, 0.24, 0.3]);
        let img = ImageRef::new(&d, 4, 4).unwrap();
        let m = mahalanobis_sq(&img, &vl).unwrap();
        // (0.02^2)/(0.0008/3) + (0.04^2)/(0.0032/3) = 1.5 + 1.5 = 3
        assert!((m[5] - 3.0).abs() < 1e-3, "{}", m[5]);
        assert!((m[0] - 1.5).abs() < 1e-3, "{}", m[0]);
        assert!(mahalanobis_sq(&img, &[false; 16]).is_none());
    }

    #[test]
    fn matting_weights_by_hand() {
        let weights = |d: &[f32], vl: &[bool]| -> Vec<f32> {
            let (thr_water, thr_not) = thresholds(vl, d.len(), |i| d[i] as f64);
            let mut m = Matting { mu: [0.0; 3], inv: [0.0; 9], thr_water: 0.0, inv_span: 0.0 };
            m.set_thresholds(thr_water, thr_not);
            d.iter().map(|&v| m.weight_of(v)).collect()
        };
        // VL distances 1, 2, 3: m = 2, s = 1, M = 3 -> thr_water 4, thr_not = M + s = 4:
        // equal thresholds: a hard step at 4.
        let d = [1.0f32, 2.0, 3.0, 4.0, 4.5];
        let vl = [true, true, true, false, false];
        assert_eq!(weights(&d, &vl), vec![1.0, 1.0, 1.0, 1.0, 0.0]);
        // VL distances 0, 0, 6: m = 2, s = sqrt(12) = 3.4641, M = 6:
        // thr_water = 8.9282, thr_not = 9.4641: d = 9.1962 -> w = 0.5
        let d = [0.0f32, 0.0, 6.0, 9.196152, 20.0, 1.0];
        let vl = [true, true, true, false, false, false];
        let w = weights(&d, &vl);
        assert!(
            (w[3] - 0.5).abs() < 1e-4 && w[4] == 0.0 && w[5] == 1.0,
            "{w:?}"
        );
    }
}
