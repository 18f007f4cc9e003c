//! He et al.'s guided filter with a color guide (SPEC 6). Everything that
//! depends only on the guide (window means, inverse regularised covariances)
//! is computed once per image in [`GuideStats::new`] and reused for every
//! water type by [`GuideStats::filter`].

use crate::filters::box_mean;
use rayon::prelude::*;

/// Guide-only terms of the color guided filter.
pub struct GuideStats {
    h: usize,
    w: usize,
    r: usize,
    /// the guide, interleaved RGB
    guide: Vec<f32>,
    /// window means of the three guide channels
    mean: [Vec<f32>; 3],
    /// (Sigma + eps U)^-1, symmetric: xx, xy, xz, yy, yz, zz
    inv: [Vec<f32>; 6],
}

/// Inverse of a symmetric 3x3 matrix given as (a, b, c, d, e, f) =
/// [[a b c] [b d e] [c e f]]; None if singular.
pub fn inv_sym3(m: [f64; 6]) -> Option<[f64; 6]> {
    let [a, b, c, d, e, f] = m;
    let c00 = d * f - e * e;
    let c01 = c * e - b * f;
    let c02 = b * e - c * d;
    let det = a * c00 + b * c01 + c * c02;
    if det.abs() < 1e-300 || !det.is_finite() {
        return None;
    }
    let c11 = a * f - c * c;
    let c12 = b * c - a * e;
    let c22 = a * d - b * b;
    Some([
        c00 / det,
        c01 / det,
        c02 / det,
        c11 / det,
        c12 / det,
        c22 / det,
    ])
}

impl GuideStats {
    /// Precomputes the guide statistics for radius `r` and regulariser `eps`
    /// (eps > 0 keeps every per-pixel matrix positive definite).
    pub fn new(guide: Vec<f32>, h: usize, w: usize, r: usize, eps: f64) -> Self {
        let n = h * w;
        let chan =
            |c: usize| -> Vec<f32> { (0..n).into_par_iter().map(|i| guide[3 * i + c]).collect() };
        let ch = [chan(0), chan(1), chan(2)];
        let mean = [
            box_mean(&ch[0], h, w, r),
            box_mean(&ch[1], h, w, r),
            box_mean(&ch[2], h, w, r),
        ];
        const PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let mut prod_means: Vec<Vec<f32>> = Vec::with_capacity(6);
        for &(i, j) in &PAIRS {
            let p: Vec<f32> = (0..n)
                .into_par_iter()
                .map(|k| ch[i][k] * ch[j][k])
                .collect();
            prod_means.push(box_mean(&p, h, w, r));
        }
        let mut inv: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0f32; n]);
        {
            let [i0, i1, i2, i3, i4, i5] = &mut inv;
            let (m0, m1, m2) = (&mean[0], &mean[1], &mean[2]);
            let pm = &prod_means;
            (i0, i1, i2, i3, i4, i5)
                .into_par_iter()
                .enumerate()
                .for_each(|(k, (o0, o1, o2, o3, o4, o5))| {
                    let mu = [m0[k] as f64, m1[k] as f64, m2[k] as f64];
                    let mut s = [0f64; 6];
                    for (q, &(i, j)) in PAIRS.iter().enumerate() {
                        s[q] = pm[q][k] as f64 - mu[i] * mu[j];
                    }
                    s[0] += eps;
                    s[3] += eps;
                    s[5] += eps;
                    // Positive definite for eps > 0 (a covariance plus eps I).
                    let v = inv_sym3(s).unwrap_or([1.0 / eps, 0.0, 0.0, 1.0 / eps, 0.0, 1.0 / eps]);
                    *o0 = v[0] as f32;
                    *o1 = v[1] as f32;
                    *o2 = v[2] as f32;
                    *o3 = v[3] as f32;
                    *o4 = v[4] as f32;
                    *o5 = v[5] as f32;
                });
        }
        Self {
            h,
            w,
            r,
            guide,
            mean,
            inv,
        }
    }

    /// The radius the statistics were computed for.
    pub fn radius(&self) -> usize {
        self.r
    }

    /// Filters the plane `p` (SPEC 6): a = (Sigma + eps U)^-1 cov(I, p),
    /// b = mean_p - a . mean_I, q = mean(a) . I + mean(b).
    pub fn filter(&self, p: &[f32]) -> Vec<f32> {
        let (h, w, r, n) = (self.h, self.w, self.r, self.h * self.w);
        let g = &self.guide;
        let mean_p = box_mean(p, h, w, r);
        let ip = |c: usize| -> Vec<f32> {
            let v: Vec<f32> = (0..n)
                .into_par_iter()
                .map(|k| g[3 * k + c] * p[k])
                .collect();
            box_mean(&v, h, w, r)
        };
        let mip = [ip(0), ip(1), ip(2)];
        let mut a: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0f32; n]);
        let mut b = vec![0f32; n];
        {
            let [a0, a1, a2] = &mut a;
            let (mean, inv) = (&self.mean, &self.inv);
            (a0, a1, a2, &mut b)
                .into_par_iter()
                .enumerate()
                .for_each(|(k, (o0, o1, o2, ob))| {
                    let mu = [mean[0][k] as f64, mean[1][k] as f64, mean[2][k] as f64];
                    let mp = mean_p[k] as f64;
                    let cov = [
                        mip[0][k] as f64 - mu[0] * mp,
                        mip[1][k] as f64 - mu[1] * mp,
                        mip[2][k] as f64 - mu[2] * mp,
                    ];
                    let m = [
                        inv[0][k] as f64,
                        inv[1][k] as f64,
                        inv[2][k] as f64,
                        inv[3][k] as f64,
                        inv[4][k] as f64,
                        inv[5][k] as f64,
                    ];
                    let ax = m[0] * cov[0] + m[1] * cov[1] + m[2] * cov[2];
                    let ay = m[1] * cov[0] + m[3] * cov[1] + m[4] * cov[2];
                    let az = m[2] * cov[0] + m[4] * cov[1] + m[5] * cov[2];
                    *o0 = ax as f32;
                    *o1 = ay as f32;
                    *o2 = az as f32;
                    *ob = (mp - ax * mu[0] - ay * mu[1] - az * mu[2]) as f32;
                });
        }
        let ma = [
            box_mean(&a[0], h, w, r),
            box_mean(&a[1], h, w, r),
            box_mean(&a[2], h, w, r),
        ];
        let mb = box_mean(&b, h, w, r);
        (0..n)
            .into_par_iter()
            .map(|k| {
                (ma[0][k] as f64 * g[3 * k] as f64
                    + ma[1][k] as f64 * g[3 * k + 1] as f64
                    + ma[2][k] as f64 * g[3 * k + 2] as f64
                    + mb[k] as f64) as f32
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise_guide(h: usize, w: usize) -> Vec<f32> {
        let mut s: u32 = 12345;
        (0..h * w * 3)
            .map(|_| {
                s = s.wrapping_mul(1103515245).wrapping_add(12345);
                (s >> 8) as f32 / (1u32 << 24) as f32
            })
            .collect()
    }

    #[test]
    fn inverse_of_symmetric_matrix() {
        let m = [4.0, 1.0, 0.5, 3.0, 0.2, 2.0];
        let v = inv_sym3(m).unwrap();
        let full = |a: [f64; 6]| [[a[0], a[1], a[2]], [a[1], a[3], a[4]], [a[2], a[4], a[5]]];
        let (a, b) = (full(m), full(v));
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| a[i][k] * b[k][j]).sum();
                assert!((p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(inv_sym3([0.0; 6]).is_none());
    }

    #[test]
    fn constant_input_is_returned() {
        let (h, w) = (12, 15);
        let gs = GuideStats::new(noise_guide(h, w), h, w, 3, 1e-3);
        let q = gs.filter(&vec![0.42f32; h * w]);
        assert!(q.iter().all(|&v| (v - 0.42).abs() < 1e-5), "{:?}", &q[..5]);
    }

    #[test]
    fn linear_function_of_the_guide_is_returned() {
        // p = 0.3 I_R - 0.2 I_G + 0.5 I_B + 0.1 lies in the model's span: with
        // a tiny eps the filter returns it (up to eps effects).
        let (h, w) = (16, 14);
        let g = noise_guide(h, w);
        let p: Vec<f32> = (0..h * w)
            .map(|k| 0.3 * g[3 * k] - 0.2 * g[3 * k + 1] + 0.5 * g[3 * k + 2] + 0.1)
            .collect();
        let gs = GuideStats::new(g, h, w, 2, 1e-6);
        let q = gs.filter(&p);
        let err = p
            .iter()
            .zip(&q)
            .map(|(a, b)| (a - b).abs())
            .fold(0f32, f32::max);
        assert!(err < 2e-3, "max error {err}");
    }
}
