//! The transmission lower bound and the Mahalanobis soft matting with the
//! water region (SPEC 5 / DECISIONS S5).

use crate::image::ImageRef;
use crate::util::{det_sum, det_sums, REDUCE_ROWS};
use crate::water::WaterType;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Floor of the lower bound (SPEC 5).
pub const LB_FLOOR: f32 = 0.1;

/// The lower bound t_LB of SPEC 5 for one pixel.
#[inline]
pub fn lower_bound_px(px: [f32; 3], a: [f32; 3], wt: &WaterType) -> f32 {
    let r = (1.0 - px[0] / a[0]).max(0.0).powf(wt.beta_br as f32);
    let g = (1.0 - px[1] / a[1]).max(0.0).powf(wt.beta_bg as f32);
    let b = (1.0 - px[2] / a[2]).max(0.0);
    r.max(g).max(b).max(LB_FLOOR)
}

/// t_LB for every pixel (SPEC 5).
pub fn lower_bound(img: &ImageRef, a: [f32; 3], wt: &WaterType) -> Vec<f32> {
    (0..img.len())
        .into_par_iter()
        .map(|i| lower_bound_px(img.px(i), a, wt))
        .collect()
}

/// Squared Mahalanobis distances (as MATLAB's `mahal`) of every pixel to the
/// colors of the VL pixels (mean, covariance with n - 1, ridge-regularised:
/// C + (1e-6 trace(C) / 3 + 1e-12) I). None with fewer than 2 VL pixels.
pub fn mahalanobis_sq(img: &ImageRef, vl: &[bool]) -> Option<Vec<f32>> {
    let n = img.len();
    let chunk = img.width * REDUCE_ROWS;
    let count = vl.iter().filter(|&&b| b).count();
    if count < 2 {
        return None;
    }
    let s = det_sums::<3, _>(n, chunk, |i, acc| {
        if vl[i] {
            let p = img.px(i);
            for c in 0..3 {
                acc[c] += p[c] as f64;
            }
        }
    });
    let mu = Vector3::new(
        s[0] / count as f64,
        s[1] / count as f64,
        s[2] / count as f64,
    );
    let cs = det_sums::<6, _>(n, chunk, |i, acc| {
        if vl[i] {
            let p = img.px(i);
            let d = [
                p[0] as f64 - mu[0],
                p[1] as f64 - mu[1],
                p[2] as f64 - mu[2],
            ];
            acc[0] += d[0] * d[0];
            acc[1] += d[0] * d[1];
            acc[2] += d[0] * d[2];
            acc[3] += d[1] * d[1];
            acc[4] += d[1] * d[2];
            acc[5] += d[2] * d[2];
        }
    });
    let k = (count - 1) as f64;
    let mut cov = Matrix3::new(
        cs[0], cs[1], cs[2], cs[1], cs[3], cs[4], cs[2], cs[4], cs[5],
    ) / k;
    let lambda = 1e-6 * cov.trace() / 3.0 + 1e-12;
    cov += Matrix3::identity() * lambda;
    let inv = cov.try_inverse()?;
    Some(
        (0..n)
            .into_par_iter()
            .map(|i| {
                let p = img.px(i);
                let d = Vector3::new(
                    p[0] as f64 - mu[0],
                    p[1] as f64 - mu[1],
                    p[2] as f64 - mu[2],
                );
                (d.transpose() * inv * d)[(0, 0)] as f32
            })
            .collect(),
    )
}

/// Matting weights w of SPEC 5 (1 = water, 0 = object) from the squared
/// distances `d`, with the thresholds taken over the VL pixels:
/// thr_water = m + 2 s, thr_notwater = M + s.
pub fn matting_weights(d: &[f32], vl: &[bool], width: usize) -> Vec<f32> {
    let n = d.len();
    let chunk = width.max(1) * REDUCE_ROWS;
    let count = vl.iter().filter(|&&b| b).count().max(1) as f64;
    let mean = det_sum(n, chunk, |i| if vl[i] { d[i] as f64 } else { 0.0 }) / count;
    let var = det_sum(n, chunk, |i| {
        if vl[i] {
            (d[i] as f64 - mean).powi(2)
        } else {
            0.0
        }
    }) / (count - 1.0).max(1.0);
    let s = var.sqrt();
    let max = d
        .iter()
        .zip(vl)
        .filter(|(_, &b)| b)
        .map(|(&v, _)| v as f64)
        .fold(f64::NEG_INFINITY, f64::max);
    let thr_water = mean + 2.0 * s;
    let thr_not = max + s;
    let span = thr_not - thr_water;
    d.par_iter()
        .map(|&v| {
            let v = v as f64;
            if span > 0.0 {
                (1.0 - ((v - thr_water) / span).clamp(0.0, 1.0)) as f32
            } else if v <= thr_water {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lower_bound_by_hand() {
        // I = (0.05, 0.2, 0.3), A = (0.1, 0.4, 0.6), betas (0.5, 2):
        // R: (1 - 0.5)^0.5 = 0.7071; G: (0.5)^2 = 0.25; B: 0.5 -> 0.7071
        let wt = WaterType::new("x", 0.5, 2.0).unwrap();
        let v = lower_bound_px([0.05, 0.2, 0.3], [0.1, 0.4, 0.6], &wt);
        assert!((v - 0.5f32.sqrt()).abs() < 1e-6);
        // brighter than A in every channel: the floor 0.1
        assert_eq!(lower_bound_px([0.5, 0.5, 0.7], [0.1, 0.4, 0.6], &wt), 0.1);
    }

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
        // VL distances 1, 2, 3: m = 2, s = 1, M = 3 -> thr_water 4, thr_not 4 + 0 ... = M + s = 4
        // equal thresholds: a hard step at 4.
        let d = [1.0f32, 2.0, 3.0, 4.0, 4.5];
        let vl = [true, true, true, false, false];
        assert_eq!(matting_weights(&d, &vl, 5), vec![1.0, 1.0, 1.0, 1.0, 0.0]);
        // VL distances 0, 0, 6: m = 2, s = sqrt(12) = 3.4641, M = 6:
        // thr_water = 8.9282, thr_not = 9.4641: d = 9.1962 -> w = 0.5
        let d = [0.0f32, 0.0, 6.0, 9.196152, 20.0, 1.0];
        let vl = [true, true, true, false, false, false];
        let w = matting_weights(&d, &vl, 6);
        assert!(
            (w[3] - 0.5).abs() < 1e-4 && w[4] == 0.0 && w[5] == 1.0,
            "{w:?}"
        );
    }
}
