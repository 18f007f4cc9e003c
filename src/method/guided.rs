//! He et al.'s guided filter with a color guide (METHOD §6). Everything that
//! depends only on the guide (window means, inverse regularised covariances)
//! is computed once per image in [`GuideStats::new`] and reused for every
//! water type. Filtering a plane takes two streaming box passes
//! ([`crate::kernels::boxsum`]): the first forms (a, b) per pixel from the window
//! means of p and I p, the second the window means of (a, b) and
//! q = mean(a) . I + mean(b), handed row by row to the caller.

use crate::kernels::boxsum::{band_ranges, box_means, split_bands, with_starts, BoxGeom};
use rayon::prelude::*;
use std::ops::Range;
use crate::kernels::filters::components8;

/// Rows a band of the box passes has at least.
const MIN_BAND_ROWS: usize = 16;

/// Guide-only terms of the color guided filter.
pub struct GuideStats {
    geom: BoxGeom,
    eps: f64,
    /// the guide, interleaved RGB
    guide: Vec<f32>,
    /// max |guide value| (bounds the products I p)
    guide_bound: f64,
    /// per pixel: window means of the three guide channels, then
    /// (Sigma + eps U)^-1 (symmetric: xx, xy, xz, yy, yz, zz); stored by
    /// row, each row as nine runs of w values (one per quantity), so that
    /// the per-type solve reads nine contiguous streams
    stats: Vec<f32>,
    /// parallel row bands of the box passes
    bands: usize,
    /// He and Sun's fast guided filter (subsampling factor > 1): the filter
    /// of the s x s blocks' centre samples, whose window means of (a, b) are
    /// interpolated back to full resolution
    low: Option<Box<Low>>,
}

/// The subsampled level of a [`GuideStats`] (factor s > 1).
struct Low {
    /// the factor s
    s: usize,
    /// the exact filter of the sampled guide at radius round(r / s)
    gs: GuideStats,
    /// per full-resolution row and column: the two low-resolution samples
    /// around it and the weight of the second (bilinear interpolation
    /// between block centres, constant beyond the first and last)
    rows: Vec<(usize, usize, f32)>,
    cols: Vec<(usize, usize, f32)>,
}

/// The sampled position of block k (of s) along an axis of length n: the
/// centre of the block clipped to the axis, rounded down. The samples and
/// the interpolation back to full resolution both use it.
fn sample_pos(k: usize, n: usize, s: usize) -> usize {
    (k * s + ((k + 1) * s).min(n) - 1) / 2
}

/// Point samples of a plane with `c` interleaved channels at the centres
/// of its s x s blocks (clipped at the border): ceil(h / s) x ceil(w / s) x c
/// values. Point samples, not block means: the window statistics of the
/// samples (the variance of the guide, its covariance with the input) are
/// those of the full-resolution pixels, which averaging would shrink.
pub fn block_samples(src: &[f32], h: usize, w: usize, c: usize, s: usize) -> Vec<f32> {
    let s = s.max(1);
    let xs: Vec<usize> = (0..w.div_ceil(s)).map(|k| sample_pos(k, w, s)).collect();
    let mut out = vec![0f32; h.div_ceil(s) * xs.len() * c];
    out.par_chunks_mut((xs.len() * c).max(1)).enumerate().for_each(|(by, orow)| {
        let y = sample_pos(by, h, s);
        let line = src.get(y * w * c..(y + 1) * w * c).unwrap_or(&[]);
        for (o, &x) in orow.chunks_exact_mut(c.max(1)).zip(&xs) {
            if let Some(px) = line.get(x * c..(x + 1) * c) {
                o.copy_from_slice(px);
            }
        }
    });
    out
}

/// The rows of a plane of (a, b), `w` per row, as the f64 source of a box pass.
fn ab_rows(ab: &[[f32; 4]], w: usize) -> impl Fn(usize, &mut [[f64; 4]]) + Sync + '_ {
    move |y, row| {
        let line = ab.get(y * w..(y + 1) * w).unwrap_or(&[]);
        for (d, v) in row.iter_mut().zip(line) {
            *d = v.map(f64::from);
        }
    }
}

/// Row source of the first pass: (p, I_R p, I_G p, I_B p) in f64.
/// The kernels below are compiled for baseline x86-64 and for AVX2, picked
/// at run time, with the same bits either way (METHOD appendix, same bits on every CPU).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn products_row(row: &mut [[f64; 4]], p: &[f32], guide: &[[f32; 3]]) {
    for ((d, &pv), &[r, g, b]) in row.iter_mut().zip(p).zip(guide) {
        let pv = f64::from(pv);
        *d = [pv, f64::from(r) * pv, f64::from(g) * pv, f64::from(b) * pv];
    }
}

/// Sink of the first pass (METHOD §6): from the window means (p, I p) and the
/// guide statistics (one row: nine runs of w values),
/// a = (Sigma + eps U)^-1 (mean(I p) - mean_I mean_p),
/// b = mean_p - a . mean_I; `maxes` gathers max |.| of each of the four.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn ab_from_means(out: &mut [[f32; 4]], means: &[[f64; 4]], stats: &[f32], maxes: &mut [f64; 4]) {
    let w = out.len();
    let mut runs = stats.chunks_exact(w.max(1));
    let mut next = || runs.next().unwrap_or(&[]).iter().map(|&v| f64::from(v));
    let (u0, u1, u2) = (next(), next(), next());
    let (i0, i1, i2, i3, i4, i5) = (next(), next(), next(), next(), next(), next());
    let s = u0.zip(u1).zip(u2).zip(i0.zip(i1).zip(i2)).zip(i3.zip(i4).zip(i5));
    for ((d, m), ((((u0, u1), u2), ((i0, i1), i2)), ((i3, i4), i5))) in out.iter_mut().zip(means).zip(s) {
        let [mp, mr, mg, mb] = *m;
        let c = [mr - u0 * mp, mg - u1 * mp, mb - u2 * mp];
        let ax = i0 * c[0] + i1 * c[1] + i2 * c[2];
        let ay = i1 * c[0] + i3 * c[1] + i4 * c[2];
        let az = i2 * c[0] + i4 * c[1] + i5 * c[2];
        let b = mp - ax * u0 - ay * u1 - az * u2;
        *d = [ax as f32, ay as f32, az as f32, b as f32];
    }
    // max |.| per component in separate lanes (a max is exact in any
    // order; one running max would serialise the loop above)
    let mut mx = [[0f32; 4]; 4];
    let (chunks, rest) = out.as_chunks::<4>();
    for c in chunks {
        for (l, d) in mx.iter_mut().zip(c) {
            for (x, v) in l.iter_mut().zip(d) {
                *x = x.max(v.abs());
            }
        }
    }
    for d in rest {
        for (x, v) in mx[0].iter_mut().zip(d) {
            *x = x.max(v.abs());
        }
    }
    for l in &mx {
        for (x, v) in maxes.iter_mut().zip(l) {
            *x = x.max(f64::from(*v));
        }
    }
}

/// Sink of the second pass: q = mean(a) . I + mean(b) for one row.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn q_row(q: &mut [f32], means: &[[f64; 4]], guide: &[[f32; 3]]) {
    for ((q, m), &[r, g, b]) in q.iter_mut().zip(means).zip(guide) {
        *q = (m[0] * f64::from(r) + m[1] * f64::from(g) + m[2] * f64::from(b) + m[3]) as f32;
    }
}

/// a + t (b - a) per component.
#[inline(always)]
fn lerp4(a: &[f32; 4], b: &[f32; 4], t: f32) -> [f32; 4] {
    let [a0, a1, a2, a3] = *a;
    let [b0, b1, b2, b3] = *b;
    [a0 + t * (b0 - a0), a1 + t * (b1 - a1), a2 + t * (b2 - a2), a3 + t * (b3 - a3)]
}

/// Interpolation table along one axis of length n for blocks of s: for each
/// position, the samples ([`sample_pos`]) that bracket it and the second
/// one's weight.
fn interp_axis(n: usize, s: usize) -> Vec<(usize, usize, f32)> {
    let nb = n.div_ceil(s);
    let centre = |k: usize| sample_pos(k, n, s) as f64;
    let mut k = 0usize;
    (0..n)
        .map(|i| {
            let x = i as f64;
            while k + 1 < nb && centre(k + 1) <= x {
                k += 1;
            }
            if k + 1 >= nb || x <= centre(k) {
                (k, k, 0.0)
            } else {
                let (c0, c1) = (centre(k), centre(k + 1));
                (k, k + 1, ((x - c0) / (c1 - c0)) as f32)
            }
        })
        .collect()
}

#[cfg(any(test, feature = "internals"))]
/// Inverse of a symmetric 3x3 matrix given as (a, b, c, d, e, f) =
/// [[a b c] [b d e] [c e f]]; None if singular.
pub fn inv_sym3(m: [f64; 6]) -> Option<[f64; 6]> {
    let (v, ok) = inv_sym3_select(m);
    ok.then_some(v)
}

/// The arithmetic of [`inv_sym3`] without its branch: the cofactors over
/// the determinant, and whether the determinant is usable (when not, the
/// values are to be ignored). Inlined into vectorized loops.
#[inline(always)]
fn inv_sym3_select(m: [f64; 6]) -> ([f64; 6], bool) {
    let [a, b, c, d, e, f] = m;
    let c00 = d * f - e * e;
    let c01 = c * e - b * f;
    let c02 = b * e - c * d;
    let det = a * c00 + b * c01 + c * c02;
    let ok = det.abs() >= 1e-300 && det.is_finite();
    let c11 = a * f - c * c;
    let c12 = b * c - a * e;
    let c22 = a * d - b * b;
    ([c00 / det, c01 / det, c02 / det, c11 / det, c12 / det, c22 / det], ok)
}

/// Sink of the statistics pass (METHOD §6): from the window means of (I,
/// I I^T) of one row, the means and the inverse of Sigma + eps U
/// ([`inv_sym3`]; where that has no inverse, which eps > 0 rules out,
/// 1/eps U), written as nine runs of w values. Branch-free, so that the
/// loop vectorizes: compiled for baseline x86-64 and for AVX2, picked at
/// run time, the same bits either way (METHOD appendix, same bits on every CPU).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn stats_row(out: &mut [f32], means: &[[f64; 9]], eps: f64) {
    let w = means.len();
    let mut runs = out.chunks_exact_mut(w.max(1));
    let mut next = || runs.next().unwrap_or(&mut []).iter_mut();
    let (u0, u1, u2) = (next(), next(), next());
    let (i0, i1, i2, i3, i4, i5) = (next(), next(), next(), next(), next(), next());
    let outs = u0.zip(u1).zip(u2).zip(i0.zip(i1).zip(i2)).zip(i3.zip(i4).zip(i5));
    let fb = [1.0 / eps, 0.0, 0.0, 1.0 / eps, 0.0, 1.0 / eps];
    for (m, ((((u0, u1), u2), ((i0, i1), i2)), ((i3, i4), i5))) in means.iter().zip(outs) {
        let [m0, m1, m2, rr, rg, rb, gg, gb, bb] = *m;
        let cov = [
            rr - m0 * m0 + eps,
            rg - m0 * m1,
            rb - m0 * m2,
            gg - m1 * m1 + eps,
            gb - m1 * m2,
            bb - m2 * m2 + eps,
        ];
        let (v, ok) = inv_sym3_select(cov);
        let [v0, v1, v2, v3, v4, v5] = std::array::from_fn(|k| {
            let (x, y) = (v.get(k).copied().unwrap_or(0.0), fb.get(k).copied().unwrap_or(0.0));
            (if ok { x } else { y }) as f32
        });
        (*u0, *u1, *u2) = (m0 as f32, m1 as f32, m2 as f32);
        (*i0, *i1, *i2, *i3, *i4, *i5) = (v0, v1, v2, v3, v4, v5);
    }
}

impl GuideStats {
    /// Precomputes the guide statistics for radius `r` and regulariser `eps`
    /// (eps > 0 keeps every per-pixel matrix positive definite). The box
    /// passes run in as many row bands as the current pool has threads.
    pub fn new(guide: Vec<f32>, h: usize, w: usize, r: usize, eps: f64) -> Self {
        Self::subsampled(guide, h, w, r, eps, 1)
    }

    /// As [`GuideStats::new`], for He and Sun's fast guided filter with
    /// subsampling factor `s` (1: the exact filter): the guide and the
    /// input sampled at the centres of s x s blocks are filtered exactly at radius
    /// max(1, round(r / s)), and the window means of (a, b) are interpolated
    /// bilinearly back to full resolution, where q = mean(a) . I + mean(b)
    /// uses the full-resolution guide (METHOD §6, subsampled guided filter).
    pub fn subsampled(guide: Vec<f32>, h: usize, w: usize, r: usize, eps: f64, s: usize) -> Self {
        let geom = BoxGeom { h, w, r };
        let guide_bound = guide.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
        let s = s.clamp(1, h.max(w).max(1));
        let low = (s > 1).then(|| {
            let (hs, ws) = (h.div_ceil(s), w.div_ceil(s));
            let rl = ((r as f64 / s as f64).round() as usize).max(1);
            Box::new(Low {
                s,
                gs: Self::new(block_samples(&guide, h, w, 3, s), hs, ws, rl, eps),
                rows: interp_axis(h, s),
                cols: interp_axis(w, s),
            })
        });
        let mut gs = Self {
            geom,
            eps,
            guide,
            guide_bound,
            stats: Vec::new(),
            bands: rayon::current_num_threads(),
            low,
        };
        if gs.low.is_none() {
            gs.stats = gs.compute_stats();
        }
        gs
    }

    #[cfg(any(test, feature = "internals"))]
    /// The subsampling factor (1: the exact filter).
    pub fn subsample(&self) -> usize {
        self.low.as_ref().map_or(1, |l| l.s)
    }

    fn compute_stats(&self) -> Vec<f32> {
        let BoxGeom { h, w, .. } = self.geom;
        let mut stats = vec![0f32; 9 * h * w];
        let g = &self.guide;
        let eps = self.eps;
        let source = |y: usize, row: &mut [[f64; 9]]| {
            let line = g.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
            for (d, px) in row.iter_mut().zip(line.chunks_exact(3)) {
                if let [r, gg, b] = *px {
                    let (r, gg, b) = (r as f64, gg as f64, b as f64);
                    *d = [r, gg, b, r * r, r * gg, r * b, gg * gg, gg * b, b * b];
                }
            }
        };
        let sink = |o: &mut (usize, &mut [f32]), y: usize, means: &[[f64; 9]]| {
            let off = 9 * (y - o.0) * w;
            if let Some(line) = o.1.get_mut(off..off + 9 * w) {
                stats_row(line, means, eps);
            }
        };
        let gb = self.guide_bound;
        let bounds = [gb, gb, gb, gb * gb, gb * gb, gb * gb, gb * gb, gb * gb, gb * gb];
        let ranges = self.ranges();
        let work = with_starts(&ranges, split_bands(&mut stats, 9 * w, &ranges));
        box_means(self.geom, bounds, work, &source, &sink);
        stats
    }

    #[cfg(any(test, feature = "internals"))]
    /// Sets the number of parallel row bands of the box passes (results do
    /// not depend on it); 1 when the caller already runs several filters in
    /// parallel.
    pub fn set_bands(&mut self, bands: usize) {
        self.bands = bands.max(1);
    }

    /// The row bands of the box passes (and of [`GuideStats::apply_rows`]'s sink).
    pub fn ranges(&self) -> Vec<Range<usize>> {
        band_ranges(self.geom.h, self.bands, MIN_BAND_ROWS)
    }

    #[cfg(any(test, feature = "internals"))]
    /// The radius the statistics were computed for.
    pub fn radius(&self) -> usize {
        self.geom.r
    }

    #[cfg(any(test, feature = "internals"))]
    /// The guide image (interleaved RGB).
    pub fn guide(&self) -> &[f32] {
        &self.guide
    }

    /// The guide image, giving up the statistics (for reuse of its buffer).
    pub fn into_guide(self) -> Vec<f32> {
        self.guide
    }

    /// Frees the per-pixel statistics once no further plane needs
    /// [`GuideStats::coefficients`] ([`GuideStats::apply_rows`] needs only the guide).
    pub fn release_stats(&mut self) {
        self.stats = Vec::new();
        if let Some(l) = self.low.as_mut() {
            l.gs.release_stats();
        }
    }

    /// First pass (METHOD §6): a = (Sigma + eps U)^-1 (mean(I p) - mean_I mean_p),
    /// b = mean_p - a . mean_I for every pixel, written to `ab` as
    /// (a_R, a_G, a_B, b). Returns max |.| of each of the four, which
    /// bounds the second pass.
    /// With subsampling, (a, b) are those of the samples and fill the
    /// first ceil(H/s) ceil(W/s) entries of `ab`.
    pub fn coefficients(&self, p: &[f32], ab: &mut [[f32; 4]]) -> [f64; 4] {
        let BoxGeom { h, w, .. } = self.geom;
        let n = h * w;
        if let Some(l) = &self.low {
            let pl = block_samples(p, h, w, 1, l.s);
            let m = pl.len();
            return match ab.get_mut(..m) {
                Some(abl) if p.len() == n => l.gs.coefficients(&pl, abl),
                _ => [0.0; 4],
            };
        }
        if p.len() != n || ab.len() != n || self.stats.len() != 9 * n {
            return [0.0; 4];
        }
        let (g, st) = (&self.guide, &self.stats);
        let pb = p.par_chunks(w.max(1)).map(|c| c.iter().fold(0f32, |m, v| m.max(v.abs()))).reduce(|| 0.0, f32::max) as f64;
        let source = |y: usize, row: &mut [[f64; 4]]| {
            let pl = p.get(y * w..(y + 1) * w).unwrap_or(&[]);
            let gl = g.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
            products_row(row, pl, gl.as_chunks::<3>().0);
        };
        let sink = |o: &mut (usize, &mut [[f32; 4]], [f64; 4]), y: usize, means: &[[f64; 4]]| {
            let off = (y - o.0) * w;
            let (Some(line), Some(sl)) = (o.1.get_mut(off..off + w), st.get(9 * y * w..9 * (y + 1) * w))
            else {
                return;
            };
            ab_from_means(line, means, sl, &mut o.2);
        };
        let gb = self.guide_bound;
        let ranges = self.ranges();
        let work: Vec<_> = with_starts(&ranges, split_bands(ab, w, &ranges))
            .into_iter()
            .map(|(r, (y0, sl))| (r, (y0, sl, [0f64; 4])))
            .collect();
        let done = box_means(self.geom, [pb, pb * gb, pb * gb, pb * gb], work, &source, &sink);
        done.iter().fold([0f64; 4], |acc, o| {
            [acc[0].max(o.2[0]), acc[1].max(o.2[1]), acc[2].max(o.2[2]), acc[3].max(o.2[3])]
        })
    }

    /// Second pass (METHOD §6): q = mean(a) . I + mean(b) row by row. `work`
    /// pairs each of [`GuideStats::ranges`] with a state; `sink(state, y, q)`
    /// gets row y of q. `bounds` is what [`GuideStats::coefficients`] returned.
    pub fn apply_rows<O, K>(
        &self,
        ab: &[[f32; 4]],
        bounds: [f64; 4],
        work: Vec<(Range<usize>, O)>,
        sink: &K,
    ) -> Vec<O>
    where
        O: Send,
        K: Fn(&mut O, usize, &[f32]) + Sync,
    {
        if let Some(l) = &self.low {
            return self.apply_rows_low(l, ab, bounds, work, sink);
        }
        let BoxGeom { w, .. } = self.geom;
        let g = &self.guide;
        let source = ab_rows(ab, w);
        let inner = |o: &mut (O, Vec<f32>), y: usize, means: &[[f64; 4]]| {
            let gl = g.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
            q_row(&mut o.1, means, gl.as_chunks::<3>().0);
            sink(&mut o.0, y, &o.1);
        };
        let work: Vec<_> = work.into_iter().map(|(r, o)| (r, (o, vec![0f32; w]))).collect();
        box_means(self.geom, bounds, work, &source, &inner)
            .into_iter()
            .map(|(o, _)| o)
            .collect()
    }

    /// Window means of a plane of (a, b) (exact filter level).
    fn mean_coefficients(&self, ab: &[[f32; 4]], bounds: [f64; 4]) -> Vec<[f32; 4]> {
        let BoxGeom { h, w, .. } = self.geom;
        let mut out = vec![[0f32; 4]; h * w];
        let source = ab_rows(ab, w);
        let sink = |o: &mut (usize, &mut [[f32; 4]]), y: usize, means: &[[f64; 4]]| {
            let off = (y - o.0) * w;
            if let Some(line) = o.1.get_mut(off..off + w) {
                for (d, m) in line.iter_mut().zip(means) {
                    *d = m.map(|v| v as f32);
                }
            }
        };
        let ranges = self.ranges();
        let work = with_starts(&ranges, split_bands(&mut out, w, &ranges));
        box_means(self.geom, bounds, work, &source, &sink);
        out
    }

    /// Second pass with subsampling: the low level's window means of (a, b),
    /// interpolated bilinearly to each full-resolution pixel, then
    /// q = mean(a) . I + mean(b).
    fn apply_rows_low<O, K>(
        &self,
        l: &Low,
        ab: &[[f32; 4]],
        bounds: [f64; 4],
        work: Vec<(Range<usize>, O)>,
        sink: &K,
    ) -> Vec<O>
    where
        O: Send,
        K: Fn(&mut O, usize, &[f32]) + Sync,
    {
        let BoxGeom { w, .. } = self.geom;
        let wl = l.gs.geom.w;
        let nl = l.gs.geom.h * wl;
        let means = l.gs.mean_coefficients(ab.get(..nl).unwrap_or(&[]), bounds);
        let g = &self.guide;
        work.into_par_iter()
            .map(|(range, mut o)| {
                let mut q = vec![0f32; w];
                // the row interpolated vertically, then horizontally per pixel
                let mut line = vec![[0f32; 4]; wl];
                for y in range {
                    let &(k0, k1, wy) = l.rows.get(y).unwrap_or(&(0, 0, 0.0));
                    let r0 = means.get(k0 * wl..(k0 + 1) * wl).unwrap_or(&[]);
                    let r1 = means.get(k1 * wl..(k1 + 1) * wl).unwrap_or(&[]);
                    for ((d, a), b) in line.iter_mut().zip(r0).zip(r1) {
                        *d = lerp4(a, b, wy);
                    }
                    let gl = g.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
                    for ((qv, px), &(c0, c1, wx)) in q.iter_mut().zip(gl.as_chunks::<3>().0).zip(&l.cols) {
                        let (Some(a), Some(b), &[r, gg, bb]) = (line.get(c0), line.get(c1), px) else {
                            continue;
                        };
                        let m = lerp4(a, b, wx);
                        *qv = m[0] * r + m[1] * gg + m[2] * bb + m[3];
                    }
                    sink(&mut o, y, &q);
                }
                o
            })
            .collect()
    }

    #[cfg(any(test, feature = "internals"))]
    /// Filters the plane `p` (METHOD §6): both passes, q as a plane.
    pub fn filter(&self, p: &[f32]) -> Vec<f32> {
        let BoxGeom { h, w, .. } = self.geom;
        let mut ab = vec![[0f32; 4]; h * w];
        let bounds = self.coefficients(p, &mut ab);
        let mut q = vec![0f32; h * w];
        let ranges = self.ranges();
        let work = with_starts(&ranges, split_bands(&mut q, w, &ranges));
        self.apply_rows(&ab, bounds, work, &|o: &mut (usize, &mut [f32]), y, row: &[f32]| {
            let off = (y - o.0) * w;
            if let Some(d) = o.1.get_mut(off..off + w) {
                d.copy_from_slice(row);
            }
        });
        q
    }
}

/// Gives each masked-out region (8-connected) one value: the mean of `q`
/// over the masked-in pixels directly below it; if none, directly above; if
/// none, its masked-in 8-neighbours (METHOD §6, METHOD §6).
pub fn chart_fill(q: &mut [f32], mask: &[bool], h: usize, w: usize) {
    let out: Vec<bool> = mask.iter().map(|&b| !b).collect();
    let (labels, sizes) = components8(&out, h, w);
    if sizes.is_empty() {
        return;
    }
    let nl = sizes.len();
    // Per region, the SET of its neighbour pixels at the given offsets: (label,
    // pixel) pairs, sorted and deduplicated, then summed in that order.
    let collect = |offsets: &[(isize, isize)]| -> (Vec<f64>, Vec<f64>) {
        let mut pairs: Vec<(u32, usize)> = Vec::new();
        for (i, &l) in labels.iter().enumerate() {
            if l == 0 {
                continue;
            }
            let (y, x) = ((i / w) as isize, (i % w) as isize);
            for &(dy, dx) in offsets {
                let (ny, nx) = (y + dy, x + dx);
                if ny < 0 || nx < 0 || ny >= h as isize || nx >= w as isize {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if mask.get(j).copied().unwrap_or(false) {
                    pairs.push((l, j));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut sum = vec![0f64; nl];
        let mut cnt = vec![0f64; nl];
        for (l, j) in pairs {
            // labels are 1..=nl (0 was skipped above)
            let k = l as usize - 1;
            if let (Some(s), Some(c), Some(&qj)) = (sum.get_mut(k), cnt.get_mut(k), q.get(j)) {
                *s += qj as f64;
                *c += 1.0;
            }
        }
        (sum, cnt)
    };
    let below = collect(&[(1, 0)]);
    let above = collect(&[(-1, 0)]);
    let around = collect(&[
        (-1, -1),
        (-1, 0),
        (-1, 1),
        (0, -1),
        (0, 1),
        (1, -1),
        (1, 0),
        (1, 1),
    ]);
    let value: Vec<Option<f32>> = (0..nl)
        .map(|k| {
            [&below, &above, &around]
                .iter()
                .find_map(|(s, c)| match (s.get(k), c.get(k)) {
                    (Some(&s), Some(&c)) if c > 0.0 => Some((s / c) as f32),
                    _ => None,
                })
        })
        .collect();
    q.par_iter_mut().zip(labels.par_iter()).for_each(|(v, &l)| {
        if l > 0 {
            if let Some(&Some(x)) = value.get(l as usize - 1) {
                *v = x;
            }
        }
    });
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
        for (i, row) in a.iter().enumerate() {
            for j in 0..3 {
                let p: f64 = row.iter().zip(&b).map(|(x, bk)| x * bk[j]).sum();
                assert!((p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(inv_sym3([0.0; 6]).is_none());
    }

    #[test]
    fn stats_row_matches_the_per_pixel_inverse() {
        // window means of (I, I I^T): noise, a flat window (covariance 0,
        // so Sigma + eps U = eps U), and, with a tiny eps, a singular one
        let noise = crate::kernels::util::test_noise(9 * 37, 11);
        for eps in [1e-3, 1e-120] {
            let means: Vec<[f64; 9]> = noise
                .chunks_exact(9)
                .enumerate()
                .map(|(i, c)| {
                    let m = [c[0] as f64, c[1] as f64, c[2] as f64];
                    let spread = if i % 3 == 0 { 0.0 } else { c[3] as f64 * 0.1 };
                    [m[0], m[1], m[2], m[0] * m[0] + spread, m[0] * m[1], m[0] * m[2], m[1] * m[1] + spread, m[1] * m[2], m[2] * m[2] + spread]
                })
                .collect();
            let w = means.len();
            let mut flat = vec![0f32; 9 * w];
            stats_row(&mut flat, &means, eps);
            // back to one entry per pixel from the nine runs of w values
            let out: Vec<[f32; 9]> = (0..w).map(|x| std::array::from_fn(|c| flat[c * w + x])).collect();
            let mut fallbacks = 0;
            for (o, m) in out.iter().zip(&means) {
                let cov = [m[3] - m[0] * m[0] + eps, m[4] - m[0] * m[1], m[5] - m[0] * m[2], m[6] - m[1] * m[1] + eps, m[7] - m[1] * m[2], m[8] - m[2] * m[2] + eps];
                let v = inv_sym3(cov).unwrap_or_else(|| {
                    fallbacks += 1;
                    [1.0 / eps, 0.0, 0.0, 1.0 / eps, 0.0, 1.0 / eps]
                });
                let want = [m[0], m[1], m[2], v[0], v[1], v[2], v[3], v[4], v[5]].map(|x| (x as f32).to_bits());
                assert_eq!(o.map(f32::to_bits), want);
            }
            assert_eq!(fallbacks > 0, eps < 1e-100, "eps {eps}: {fallbacks} fallbacks");
        }
    }

    #[test]
    fn constant_input_is_returned() {
        let (h, w) = (12, 15);
        let gs = GuideStats::new(noise_guide(h, w), h, w, 3, 1e-3);
        let q = gs.filter(&vec![0.42f32; h * w]);
        assert!(q.iter().all(|&v| (v - 0.42).abs() < 1e-5), "{:?}", &q[..5]);
    }

    #[test]
    fn subsampled_returns_constants_and_linear_functions_of_the_guide() {
        // samples of p = c . I + d are c . (samples of I) + d, so the
        // low level's (a, b) is (c, d) everywhere and q = p up to eps effects
        for &(h, w, s) in &[(40usize, 37usize, 4usize), (33, 50, 3), (9, 9, 2), (70, 64, 8)] {
            let g = noise_guide(h, w);
            let gs = GuideStats::subsampled(g.clone(), h, w, 4 * s, 1e-6, s);
            assert_eq!(gs.subsample(), s);
            let q = gs.filter(&vec![0.42f32; h * w]);
            assert!(q.iter().all(|&v| (v - 0.42).abs() < 1e-4), "{h}x{w}/{s}: {:?}", &q[..5]);
            let p: Vec<f32> = (0..h * w)
                .map(|k| 0.3 * g[3 * k] - 0.2 * g[3 * k + 1] + 0.5 * g[3 * k + 2] + 0.1)
                .collect();
            let q = gs.filter(&p);
            let err = p.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
            assert!(err < 2e-3, "{h}x{w}/{s}: max error {err}");
        }
    }

    #[test]
    fn block_samples_by_hand() {
        // 3 x 5, s = 2: blocks of 2x2, 2x2, 2x1, 1x2, 1x2, 1x1; centres
        // (rounded down) at rows 0, 2 and columns 0, 2, 4
        let src: Vec<f32> = (0..15).map(|v| v as f32).collect();
        let m = block_samples(&src, 3, 5, 1, 2);
        assert_eq!(m, vec![0.0, 2.0, 4.0, 10.0, 12.0, 14.0]);
        // the interpolation weights bracket each position by block centres
        let t = interp_axis(5, 2);
        assert_eq!(t[0], (0, 0, 0.0));
        // samples at 0, 2, 4 (the blocks' centres 0.5, 2.5, 4 rounded down):
        // a sampled position takes its sample alone
        assert_eq!(t[1], (0, 1, 0.5));
        assert_eq!(t[2], (1, 1, 0.0));
        assert_eq!(t[3], (1, 2, 0.5));
        assert_eq!(t[4], (2, 2, 0.0));
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
