//! Initial transmission from haze-lines (SPEC 4 / DECISIONS S4).

use crate::filters::box_mean;
use crate::image::ImageRef;
use crate::sphere::SphereIndex;
use crate::water::WaterType;
use rayon::prelude::*;

/// Lower clamp of t~ (SPEC 4.4).
pub const T_MIN: f32 = 0.01;
/// Factor applied after clustering (SPEC 4.6).
pub const T_SCALE: f32 = 0.9;
/// Cluster id of pixels that have none (r == 0 or masked out).
const NO_CLUSTER: u32 = u32::MAX;

/// sgn(d) |d|^p.
#[inline]
pub fn signed_pow(d: f32, p: f32) -> f32 {
    if d == 0.0 {
        0.0
    } else {
        d.signum() * d.abs().powf(p)
    }
}

/// The medium-compensated vector of SPEC 0 / 4.1 for one pixel.
#[inline]
pub fn compensated(px: [f32; 3], a: [f32; 3], wt: &WaterType) -> [f32; 3] {
    [
        signed_pow(a[0] - px[0], wt.beta_br as f32),
        signed_pow(a[1] - px[1], wt.beta_bg as f32),
        a[2] - px[2],
    ]
}

/// t~ for every pixel (SPEC 4.1-4.6): haze-line clusters on masked-in
/// pixels, r / r_max clamped to [0.01, 1], masked-out pixels filled by
/// [`fill_masked`], then scaled by 0.9.
pub fn initial_transmission(
    img: &ImageRef,
    a: [f32; 3],
    wt: &WaterType,
    index: &SphereIndex,
    mask: Option<&[bool]>,
) -> Vec<f32> {
    let n = img.len();
    let w = img.width;
    // Per pixel: radius and cluster.
    let mut radius = vec![0f32; n];
    let mut cluster = vec![NO_CLUSTER; n];
    radius
        .par_chunks_mut(w)
        .zip(cluster.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (rr, cc))| {
            for x in 0..w {
                let i = y * w + x;
                if mask.is_some_and(|m| !m[i]) {
                    continue;
                }
                let v = compensated(img.px(i), a, wt);
                let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                rr[x] = r;
                if r > 0.0 && r.is_finite() {
                    cc[x] = index.nearest(&[v[0] / r, v[1] / r, v[2] / r]) as u32;
                }
            }
        });
    // r_max per cluster: max is exact and order-free, so any split is deterministic.
    let k = index.len();
    let rmax = radius
        .par_chunks(w * 16)
        .zip(cluster.par_chunks(w * 16))
        .map(|(rr, cc)| {
            let mut m = vec![0f32; k];
            for (&r, &c) in rr.iter().zip(cc) {
                if c != NO_CLUSTER {
                    let slot = &mut m[c as usize];
                    *slot = slot.max(r);
                }
            }
            m
        })
        .reduce(
            || vec![0f32; k],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x = x.max(*y));
                a
            },
        );
    let mut t: Vec<f32> = radius
        .par_iter()
        .zip(&cluster)
        .map(|(&r, &c)| {
            if c == NO_CLUSTER {
                1.0
            } else {
                let m = rmax[c as usize];
                if m > 0.0 {
                    (r / m).clamp(T_MIN, 1.0)
                } else {
                    1.0
                }
            }
        })
        .collect();
    if let Some(m) = mask {
        fill_masked(&mut t, m, img.height, w);
    }
    t.par_iter_mut().for_each(|v| *v *= T_SCALE);
    t
}

/// Fills masked-out pixels (mask false) by normalised convolution with a
/// growing radius 1, 2, 4, ... (DECISIONS S4): each still-unfilled pixel
/// takes box(w t) / box(w) at the first radius where box(w) > 0.
pub fn fill_masked(t: &mut [f32], mask: &[bool], h: usize, w: usize) {
    let wts: Vec<f32> = mask.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
    if !mask.iter().any(|&b| b) {
        return;
    }
    let wt: Vec<f32> = t.iter().zip(&wts).map(|(v, m)| v * m).collect();
    let mut filled: Vec<bool> = mask.to_vec();
    let mut rad = 1usize;
    while filled.iter().any(|&f| !f) {
        let num = box_mean(&wt, h, w, rad);
        let den = box_mean(&wts, h, w, rad);
        t.par_iter_mut()
            .zip(filled.par_iter_mut())
            .enumerate()
            .for_each(|(i, (v, f))| {
                if !*f && den[i] > 0.0 {
                    *v = num[i] / den[i];
                    *f = true;
                }
            });
        if rad > h.max(w) {
            break;
        }
        rad *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compensated_vector_by_hand() {
        // A - I = (0.09, -0.04, 0.1); 0.09^0.5 = 0.3; -(0.04^0.5) = -0.2
        let wt = WaterType::new("x", 0.5, 0.5).unwrap();
        let v = compensated([0.01, 0.54, 0.2], [0.1, 0.5, 0.3], &wt);
        assert!(
            (v[0] - 0.3).abs() < 1e-6 && (v[1] + 0.2).abs() < 1e-6 && (v[2] - 0.1).abs() < 1e-6
        );
    }

    #[test]
    fn one_haze_line_gives_relative_distances() {
        // Pixels on one haze-line: I = t J + (1 - t) A with the same J, so v is
        // parallel with |v| proportional to t (SPEC 0), up to t_B: r / r_max = t / t_max.
        let a = [0.1f32, 0.4, 0.5];
        let j = [0.8f32, 0.6, 0.2];
        let wt = WaterType::new("x", 1.0, 1.0).unwrap();
        let ts = [1.0f32, 0.5, 0.25, 0.75];
        let mut d = Vec::new();
        for y in 0..4 {
            for _ in 0..4 {
                for c in 0..3 {
                    d.push(ts[y] * j[c] + (1.0 - ts[y]) * a[c]);
                }
            }
        }
        let img = ImageRef::new(&d, 4, 4).unwrap();
        let idx = SphereIndex::new(500).unwrap();
        let t = initial_transmission(&img, a, &wt, &idx, None);
        for y in 0..4 {
            assert!(
                (t[y * 4] - 0.9 * ts[y]).abs() < 1e-5,
                "{} vs {}",
                t[y * 4],
                0.9 * ts[y]
            );
        }
    }

    #[test]
    fn pixels_equal_to_a_get_one() {
        let a = [0.2f32, 0.3, 0.4];
        let mut d = vec![0.2f32, 0.3, 0.4].repeat(16);
        d[0] = 0.9;
        let img = ImageRef::new(&d, 4, 4).unwrap();
        let t = initial_transmission(
            &img,
            a,
            &WaterType::by_name("II").unwrap(),
            &SphereIndex::new(50).unwrap(),
            None,
        );
        assert!(t.iter().all(|&v| (v - 0.9).abs() < 1e-6));
    }

    #[test]
    fn fill_takes_neighbour_values() {
        // left half 0.2, right half 0.6, a masked hole in the middle of each
        let (h, w) = (8, 8);
        let mut t: Vec<f32> = (0..h * w)
            .map(|i| if i % w < 4 { 0.2 } else { 0.6 })
            .collect();
        let mut m = vec![true; h * w];
        for y in 3..5 {
            for x in [1usize, 6] {
                m[y * w + x] = false;
                t[y * w + x] = 99.0;
            }
        }
        fill_masked(&mut t, &m, h, w);
        assert!((t[3 * w + 1] - 0.2).abs() < 1e-6);
        assert!((t[4 * w + 6] - 0.6).abs() < 1e-6);
        // a hole needing larger radii is still filled within the data range
        let mut m2 = vec![false; h * w];
        m2[0] = true;
        let mut t2 = vec![5.0f32; h * w];
        t2[0] = 0.3;
        fill_masked(&mut t2, &m2, h, w);
        assert!(t2.iter().all(|&v| (v - 0.3).abs() < 1e-6));
    }
}
