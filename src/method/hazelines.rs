//! Initial transmission from haze-lines (METHOD §4 / METHOD §4).

use crate::kernels::fastmath;
use crate::kernels::filters::box_mean;
use crate::method::image::ImageRef;
use crate::method::sphere::SphereIndex;
use crate::method::water::WaterType;
use rayon::prelude::*;

/// Lower clamp of t~ (METHOD §4.4).
pub const T_MIN: f32 = 0.01;
/// Factor applied after clustering by default (METHOD §4.6; `t_scale`):
/// the whole-image stage functions of the cross-check hooks use it.
#[cfg(any(test, feature = "internals"))]
pub const T_SCALE: f32 = crate::method::params::DEFAULT_T_SCALE as f32;
/// Cluster id (as stored, f32) of pixels that have none (r == 0 or masked out).
const NO_CLUSTER: f32 = -1.0;

/// sgn(d) |d|^p (the vectorizable power of [`crate::kernels::fastmath`]).
#[inline(always)]
pub fn signed_pow(d: f32, p: f64) -> f32 {
    fastmath::signed_pow(d, p)
}

#[cfg(any(test, feature = "internals"))]
/// The medium-compensated vector of METHOD §0 / 4.1 for one pixel.
#[inline]
pub fn compensated(px: [f32; 3], a: [f32; 3], wt: &WaterType) -> [f32; 3] {
    HazeType::new(a, wt).compensated(px)
}

/// Per-type constants of METHOD §4-5 for a given veiling light A.
#[derive(Debug, Clone, Copy)]
pub struct HazeType {
    /// veiling light A
    pub a: [f32; 3],
    /// (beta_BR, beta_BG)
    pub beta: [f64; 2],
    /// A_R^-beta_BR, A_G^-beta_BG, 1 / A_B: the lower bound's factors, in
    /// f64 (A_R^-beta_BR reaches 1e63 for A_R = 0.008 and a ratio of 30)
    lb_scale: [f64; 3],
}

impl HazeType {
    /// The constants for water type `wt` and veiling light `a` (each > 0).
    pub fn new(a: [f32; 3], wt: &WaterType) -> Self {
        let beta = [wt.beta_br, wt.beta_bg];
        Self {
            a,
            beta,
            lb_scale: [
                f64::from(a[0]).powf(-beta[0]),
                f64::from(a[1]).powf(-beta[1]),
                1.0 / f64::from(a[2]),
            ],
        }
    }

    /// The medium-compensated vector of METHOD §0 / 4.1 for one pixel.
    #[inline(always)]
    pub fn compensated(&self, px: [f32; 3]) -> [f32; 3] {
        [
            signed_pow(self.a[0] - px[0], self.beta[0]),
            signed_pow(self.a[1] - px[1], self.beta[1]),
            self.a[2] - px[2],
        ]
    }

    /// The lower bound t_LB of METHOD §5 from the compensated vector v:
    /// max(1 - I_c/A_c, 0)^beta_c = max(v_c, 0) A_c^-beta_c, floor 0.1.
    /// Each term is at most 1 in exact arithmetic; the product is formed in
    /// f64 and capped at 1, so that an extreme type (a large ratio with a
    /// small A_c, where A_c^-beta_c overflows f32) gives no inf or NaN.
    #[inline(always)]
    pub fn lower_bound(&self, v: [f32; 3]) -> f32 {
        let [r, g, b] = v.map(|x| f64::from(x.max(0.0)));
        let [sr, sg, sb] = self.lb_scale;
        ((r * sr).max(g * sg).max(b * sb).min(1.0) as f32).max(LB_FLOOR)
    }
}

/// For one row of pixels: the compensated vectors v (METHOD §4.1), their
/// radii |v| and the lower bounds t_LB (METHOD §5). Compiled for baseline
/// x86-64, AVX2 and AVX-512 (METHOD appendix, same bits on every CPU), picked at run time; the same
/// bits on each (plain IEEE operations, [`crate::kernels::fastmath`]).
/// Also each v's lookup cell in `index` ([`SphereIndex::cell`]).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
pub fn compensate_row(ht: &HazeType, index: &SphereIndex, px: &[[f32; 3]], out: &mut CompensatedRow) {
    let CompensatedRow { v, r, lb, cell } = out;
    for ((((p, v), r), lb), cell) in px.iter().zip(v.iter_mut()).zip(r.iter_mut()).zip(lb.iter_mut()).zip(cell.iter_mut()) {
        let c = ht.compensated(*p);
        *v = c;
        *r = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        *lb = ht.lower_bound(c);
        *cell = index.cell(&c);
    }
}

/// What [`compensate_row`] gives for a row of pixels, one entry per pixel
/// in each field (separate arrays, so that the lookups of
/// [`SphereIndex::nearest_row`] read only what they need).
#[derive(Debug, Clone, Default)]
pub struct CompensatedRow {
    /// the compensated vectors v (METHOD §4.1)
    pub v: Vec<[f32; 3]>,
    /// |v|
    pub r: Vec<f32>,
    /// t_LB (METHOD §5)
    pub lb: Vec<f32>,
    /// v's lookup cell
    pub cell: Vec<u32>,
}

impl CompensatedRow {
    /// Buffers for rows of `w` pixels.
    pub fn new(w: usize) -> Self {
        Self {
            v: vec![[0.0; 3]; w],
            r: vec![0.0; w],
            lb: vec![0.0; w],
            cell: vec![0; w],
        }
    }
}

/// Floor of the lower bound (METHOD §5).
pub const LB_FLOOR: f32 = 0.1;

/// The lower bound t_LB of METHOD §5 for one pixel.
#[cfg(any(test, feature = "internals"))]
#[inline]
pub fn lower_bound_px(px: [f32; 3], a: [f32; 3], wt: &WaterType) -> f32 {
    let ht = HazeType::new(a, wt);
    ht.lower_bound(ht.compensated(px))
}

/// t_LB for every pixel (METHOD §5), through the per-pixel functions of
/// the haze-lines pass.
#[cfg(any(test, feature = "internals"))]
pub fn lower_bound(img: &ImageRef, a: [f32; 3], wt: &WaterType) -> Vec<f32> {
    let ht = HazeType::new(a, wt);
    img.data
        .as_chunks::<3>()
        .0
        .par_iter()
        .map(|&p| ht.lower_bound(ht.compensated(p)))
        .collect()
}

/// Rows per work item of the per-pixel passes.
pub const CHUNK_ROWS: usize = 8;

/// First pass of METHOD §4 (and the lower bound of METHOD §5) over all pixels:
/// `r_out[i]` = |v| (0 for masked-out pixels), `aux[i]` = (t_LB, cluster
/// as f32 or -1 for none). Returns r_max per cluster (max is exact and
/// order-free: the same for any split).
pub fn haze_pass(
    img: &ImageRef,
    ht: &HazeType,
    index: &SphereIndex,
    mask: Option<&[bool]>,
    r_out: &mut [f32],
    aux: &mut [[f32; 2]],
) -> Vec<f32> {
    let w = img.width;
    let k = index.len();
    let chunk = w * CHUNK_ROWS;
    r_out
        .par_chunks_mut(chunk)
        .zip(aux.par_chunks_mut(chunk))
        .zip(img.data.par_chunks(3 * chunk))
        .enumerate()
        .map(|(ci, ((rr, aa), px))| {
            let mut m = vec![0f32; k];
            // per row: first the compensated vectors, radii and lower
            // bounds (a SIMD kernel), then the cluster lookups
            let mut cs = CompensatedRow::new(w);
            let mut ks = vec![0u32; w];
            let all = vec![true; w];
            for (y, ((rr, aa), px)) in rr.chunks_mut(w).zip(aa.chunks_mut(w)).zip(px.chunks(3 * w)).enumerate() {
                compensate_row(ht, index, px.as_chunks::<3>().0, &mut cs);
                // the direction of v: no need to normalise it (SphereIndex::nearest)
                index.nearest_row(&cs.cell, &cs.v, &mut ks);
                let row0 = ci * chunk + y * w;
                let inside = match mask {
                    None => &all[..],
                    Some(mk) => mk.get(row0..row0 + w).unwrap_or(&[]),
                };
                let pix = cs.r.iter().zip(&cs.lb).zip(&ks).zip(inside);
                for ((r, a), (((&cr, &lb), &kc), &ins)) in rr.iter_mut().zip(aa.iter_mut()).zip(pix) {
                    let ok = ins && cr > 0.0 && cr.is_finite();
                    if ok {
                        if let Some(slot) = m.get_mut(kc as usize) {
                            *slot = slot.max(cr);
                        }
                    }
                    *r = if ins { cr } else { 0.0 };
                    *a = [lb, if ok { kc as f32 } else { NO_CLUSTER }];
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
        )
}

/// t~ of one pixel (METHOD §4.4) from its radius, cluster (-1: none) and the
/// clusters' r_max: clamp(r / r_max, 0.01, 1), or 1 without a cluster.
#[inline(always)]
pub fn t_tilde(r: f32, cluster: f32, rmax: &[f32]) -> f32 {
    if cluster < 0.0 {
        return 1.0;
    }
    match rmax.get(cluster as usize) {
        Some(&m) if m > 0.0 => (r / m).clamp(T_MIN, 1.0),
        _ => 1.0,
    }
}

#[cfg(any(test, feature = "internals"))]
/// t~ for every pixel (METHOD §4.1-4.6): haze-line clusters on masked-in
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
    let mut t = vec![0f32; n];
    let mut aux = vec![[0f32; 2]; n];
    let rmax = haze_pass(img, &HazeType::new(a, wt), index, mask, &mut t, &mut aux);
    t.par_iter_mut()
        .zip(aux.par_iter())
        .for_each(|(v, x)| *v = t_tilde(*v, x[1], &rmax));
    if let Some(m) = mask {
        fill_masked(&mut t, m, img.height, img.width);
    }
    t.par_iter_mut().for_each(|v| *v *= T_SCALE);
    t
}

/// Fills masked-out pixels (mask false) by normalised convolution with a
/// growing radius 1, 2, 4, ... (METHOD §4): each still-unfilled pixel
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
            .zip(num.par_iter().zip(den.par_iter()))
            .for_each(|((v, f), (&nm, &dn))| {
                if !*f && dn > 0.0 {
                    *v = nm / dn;
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
    fn row_kernel_gives_the_per_pixel_bits() {
        // compensate_row runs its AVX2 build where the CPU has AVX2; the
        // per-pixel functions called here are the baseline build: the bits
        // must agree (METHOD appendix, same bits on every CPU). Values include D = 0, negative D,
        // tiny and large differences.
        let noise = crate::kernels::util::test_noise(3 * 4099, 7);
        let special = [0.0f32, 1e-30, 0.5, 1.0, 0.2, 0.3, 0.4, 1e-7, 0.999_999];
        let px: Vec<[f32; 3]> = noise
            .chunks_exact(3)
            .enumerate()
            .map(|(i, c)| {
                let pick = |k: usize, v: f32| if i % 5 == 0 { special[(i / 5 + k) % special.len()] } else { v };
                [pick(0, c[0]), pick(1, c[1]), pick(2, c[2])]
            })
            .collect();
        let idx = SphereIndex::new(500).unwrap();
        for name in ["I", "III", "3C", "9C"] {
            let ht = HazeType::new([0.2, 0.3, 0.4], &WaterType::by_name(name).unwrap());
            let mut out = CompensatedRow::new(px.len());
            compensate_row(&ht, &idx, &px, &mut out);
            let mut ks = vec![0u32; px.len()];
            idx.nearest_row(&out.cell, &out.v, &mut ks);
            for (i, p) in px.iter().enumerate() {
                let v = ht.compensated(*p);
                assert_eq!(out.v[i].map(f32::to_bits), v.map(f32::to_bits), "{p:?}");
                assert_eq!(out.r[i].to_bits(), (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().to_bits());
                assert_eq!(out.lb[i].to_bits(), ht.lower_bound(v).to_bits());
                if out.r[i] > 0.0 {
                    assert_eq!(idx.nearest_in_cell(out.cell[i], &out.v[i]), idx.nearest(&v));
                    assert_eq!(ks[i] as usize, idx.nearest(&v));
                }
            }
        }
    }

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
    fn lower_bound_of_an_extreme_type_is_finite() {
        // A_R^-beta_BR = 0.008^-20.15 overflows f32 (found by proptest: the
        // product gave inf, the guided filter NaN); by hand, I_R = A_R / 2:
        // (1 - 1/2)^20.15 = 8.8e-7, under the floor, and I = 0: 1 for red
        let wt = WaterType::new("x", 20.153500771027755, crate::method::water::MIN_RATIO).unwrap();
        let ht = HazeType::new([0.008, 1e-4, 1e-4], &wt);
        let lb = ht.lower_bound(ht.compensated([0.004, 1e-4, 1e-4]));
        assert_eq!(lb, LB_FLOOR);
        let lb0 = ht.lower_bound(ht.compensated([0.0, 1e-4, 1e-4]));
        // (0.008^20.15 is an f32 subnormal with few significant bits)
        assert!(lb0.is_finite() && lb0 <= 1.0 && (lb0 - 1.0).abs() < 1e-3, "{lb0}");
        // an ordinary type: (1 - 0.1/0.5)^0.8 from the green channel
        let wt = WaterType::new("y", 0.5, 0.8).unwrap();
        let ht = HazeType::new([0.2, 0.5, 0.6], &wt);
        let lb = ht.lower_bound(ht.compensated([0.19, 0.1, 0.59]));
        assert!((lb - 0.8f32.powf(0.8)).abs() < 1e-6, "{lb}");
    }

    #[test]
    fn one_haze_line_gives_relative_distances() {
        // Pixels on one haze-line: I = t J + (1 - t) A with the same J, so v is
        // parallel with |v| proportional to t (METHOD §0), up to t_B: r / r_max = t / t_max.
        let a = [0.1f32, 0.4, 0.5];
        let j = [0.8f32, 0.6, 0.2];
        let wt = WaterType::new("x", 1.0, 1.0).unwrap();
        let ts = [1.0f32, 0.5, 0.25, 0.75];
        let mut d = Vec::new();
        for t in ts {
            for _ in 0..4 {
                for c in 0..3 {
                    d.push(t * j[c] + (1.0 - t) * a[c]);
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
        let mut d = [0.2f32, 0.3, 0.4].repeat(16);
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
