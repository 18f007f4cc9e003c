//! Contrast-limited adaptive histogram equalisation in the manner of
//! MATLAB's `adapthisteq` defaults (8x8 tiles, clip limit 0.01, 256 bins,
//! uniform distribution), METHOD §3.2.
//!
//! The default water-region detector does NOT use it: the per-channel
//! stretch and CLAHE of METHOD §3.1-§3.2 amplify sensor noise in flat water
//! (worst in a nearly empty red channel), so a gradient of that image marks
//! water as textured. It is kept, with [`naive_edge_map`], so that this
//! failure is measured by a test rather than asserted in prose.

use crate::filters::sobel_max;
use crate::pipeline::stretch_image;
use rayon::prelude::*;

/// CLAHE parameters.
#[derive(Debug, Clone, Copy)]
pub struct Clahe {
    /// tiles along y and x
    pub tiles: (usize, usize),
    /// normalised clip limit in [0, 1] (1 = no clipping)
    pub clip_limit: f64,
    /// histogram bins
    pub bins: usize,
}

impl Default for Clahe {
    fn default() -> Self {
        Self {
            tiles: (8, 8),
            clip_limit: 0.01,
            bins: 256,
        }
    }
}

/// Tile spans: `n` tiles over `len` pixels as (start, end), as equal as integers allow.
fn spans(len: usize, n: usize) -> Vec<(usize, usize)> {
    (0..n).map(|k| (k * len / n, (k + 1) * len / n)).collect()
}

/// The centre of each span, in pixel coordinates.
fn centres(spans: &[(usize, usize)]) -> Vec<f64> {
    spans
        .iter()
        .map(|&(a, b)| (a + b) as f64 / 2.0 - 0.5)
        .collect()
}

/// The lower neighbour centre of `p`, the upper one, and the upper one's weight.
fn locate(c: &[f64], p: f64) -> (usize, usize, f64) {
    let (Some(&first), Some(&last_c)) = (c.first(), c.last()) else {
        return (0, 0, 0.0);
    };
    let last = c.len() - 1;
    if p <= first {
        return (0, 0, 0.0);
    }
    if p >= last_c {
        return (last, last, 0.0);
    }
    let i = c.iter().rposition(|&v| v <= p).unwrap_or(0).min(last.saturating_sub(1));
    match (c.get(i), c.get(i + 1)) {
        (Some(&lo), Some(&hi)) if hi > lo => (i, i + 1, (p - lo) / (hi - lo)),
        _ => (i, i, 0.0),
    }
}

impl Clahe {
    #[inline]
    fn bin(&self, v: f32) -> usize {
        ((v.clamp(0.0, 1.0) as f64 * self.bins as f64) as usize).min(self.bins.saturating_sub(1))
    }

    /// The mapping (bin -> [0, 1]) of one tile: clipped histogram with the
    /// excess spread evenly over all bins, then its normalised cumulative sum.
    fn mapping(&self, plane: &[f32], w: usize, ys: (usize, usize), xs: (usize, usize)) -> Vec<f32> {
        let nb = self.bins.max(1);
        let mut hist = vec![0f64; nb];
        for row in plane.chunks(w.max(1)).skip(ys.0).take(ys.1.saturating_sub(ys.0)) {
            for &v in row.get(xs.0..xs.1).unwrap_or(&[]) {
                if let Some(c) = hist.get_mut(self.bin(v)) {
                    *c += 1.0;
                }
            }
        }
        let n: f64 = hist.iter().sum();
        if n == 0.0 {
            return (0..nb)
                .map(|b| b as f32 / nb.saturating_sub(1).max(1) as f32)
                .collect();
        }
        // adapthisteq's actual limit: at least the uniform count per bin.
        let min_clip = (n / nb as f64).ceil();
        let clip = min_clip + (self.clip_limit * (n - min_clip)).round();
        let excess: f64 = hist.iter().map(|&c| (c - clip).max(0.0)).sum();
        let add = excess / nb as f64;
        hist.iter_mut().for_each(|c| *c = c.min(clip) + add);
        let mut acc = 0f64;
        hist.iter()
            .map(|&c| {
                acc += c;
                (acc / n).min(1.0) as f32
            })
            .collect()
    }

    /// CLAHE of one plane with values in [0, 1]: per-tile mappings,
    /// bilinearly interpolated between the four nearest tile centres.
    pub fn apply(&self, plane: &[f32], h: usize, w: usize) -> Vec<f32> {
        let (ty, tx) = (
            self.tiles.0.clamp(1, h.max(1)),
            self.tiles.1.clamp(1, w.max(1)),
        );
        let (sy, sx) = (spans(h, ty), spans(w, tx));
        let maps: Vec<Vec<f32>> = sy
            .iter()
            .flat_map(|&ys| sx.iter().map(move |&xs| (ys, xs)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(ys, xs)| self.mapping(plane, w, ys, xs))
            .collect();
        let (cy, cx) = (centres(&sy), centres(&sx));
        let map = |yy: usize, xx: usize, b: usize| -> f64 {
            maps.get(yy * tx + xx)
                .and_then(|m| m.get(b))
                .copied()
                .unwrap_or(0.0) as f64
        };
        let mut out = vec![0f32; h * w];
        out.par_chunks_mut(w.max(1))
            .zip(plane.par_chunks(w.max(1)))
            .enumerate()
            .for_each(|(y, (row, src))| {
                let (y0, y1, fy) = locate(&cy, y as f64);
                for (x, (o, &v)) in row.iter_mut().zip(src).enumerate() {
                    let (x0, x1, fx) = locate(&cx, x as f64);
                    let b = self.bin(v);
                    let top = map(y0, x0, b) * (1.0 - fx) + map(y0, x1, b) * fx;
                    let bot = map(y1, x0, b) * (1.0 - fx) + map(y1, x1, b) * fx;
                    *o = (top * (1.0 - fy) + bot * fy) as f32;
                }
            });
        out
    }
}

/// The edge map of METHOD §3.1-§3.3 without the forest: contrast stretch
/// (S3.1), CLAHE per channel, Sobel magnitude / 8, maximum over channels.
/// Kept to measure why it is not used (see the module docs).
pub fn naive_edge_map(data: &[f32], h: usize, w: usize) -> Vec<f32> {
    let s = stretch_image(data, None);
    let c = Clahe::default();
    let [r, g, b] = [0, 1, 2].map(|k| {
        let p: Vec<f32> = s.iter().skip(k).step_by(3).copied().collect();
        c.apply(&p, h, w)
    });
    let inter: Vec<f32> = r
        .iter()
        .zip(&g)
        .zip(&b)
        .flat_map(|((&r, &g), &b)| [r, g, b])
        .collect();
    sobel_max(&inter, h, w, 3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_image_stays_constant() {
        let (h, w) = (32, 40);
        let out = Clahe::default().apply(&vec![0.3f32; h * w], h, w);
        assert!(out.iter().all(|&v| (v - out[0]).abs() < 1e-6));
        assert!((0.0..=1.0).contains(&out[0]));
    }

    #[test]
    fn ramp_with_one_unclipped_tile_is_plain_equalisation() {
        // A ramp has a flat histogram: equalising it is (almost) the identity,
        // v -> cdf(v) = (bin(v) + 1) / 256 for a ramp hitting every bin once.
        let (h, w) = (4, 256);
        let ramp: Vec<f32> = (0..h * w).map(|i| ((i % w) as f32 + 0.5) / 256.0).collect();
        let c = Clahe {
            tiles: (1, 1),
            clip_limit: 1.0,
            bins: 256,
        };
        let out = c.apply(&ramp, h, w);
        for (x, v) in out.iter().take(w).enumerate() {
            assert!((v - (x as f32 + 1.0) / 256.0).abs() < 1e-6, "x={x}");
        }
        // a low-contrast ramp in [0.4, 0.6) is stretched to the full range
        let low: Vec<f32> = (0..h * w)
            .map(|i| 0.4 + 0.2 * (i % w) as f32 / 256.0)
            .collect();
        let out = c.apply(&low, h, w);
        assert!(out[0] < 0.05 && out[w - 1] > 0.99);
    }

    #[test]
    fn ramp_with_default_tiles_by_hand() {
        // 64x256 horizontal ramp x/255: tiles of 8 rows x 32 columns, 256
        // pixels each; tile 0 holds bins 0..31 with 8 pixels each. Actual
        // clip = ceil(256/256) + round(0.01 * 255) = 4, so each bin keeps 4
        // and the excess 32 * 4 = 128 adds 0.5 to each of the 256 bins.
        // Left of the first tile centre only tile 0's mapping applies:
        // out(x) = (4 (x + 1) + 0.5 (x + 1)) / 256.
        let (h, w) = (64, 256);
        let ramp: Vec<f32> = (0..h * w).map(|i| (i % w) as f32 / 255.0).collect();
        let out = Clahe::default().apply(&ramp, h, w);
        assert!(out.iter().all(|&v| (0.0..=1.0).contains(&v)));
        for y in [0, 30, 63] {
            for x in 0..16 {
                let e = 4.5 * (x as f32 + 1.0) / 256.0;
                assert!(
                    (out[y * w + x] - e).abs() < 1e-6,
                    "y={y} x={x}: {} vs {e}",
                    out[y * w + x]
                );
            }
        }
    }

    #[test]
    fn naive_map_marks_noisy_water_as_textured() {
        // Flat water with a little sensor noise over a textured bottom: the
        // stretch + CLAHE map calls the water textured (>= 0.005) almost
        // everywhere, while the robust map of veiling.rs calls it flat.
        let (h, w) = (96, 128);
        let mut s: u64 = 11;
        let mut noise = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.01
        };
        let mut d = vec![0f32; h * w * 3];
        for y in 0..h {
            for x in 0..w {
                let base = if y < 40 {
                    [0.01, 0.25, 0.4]
                } else if (x / 3 + y / 3) % 2 == 0 {
                    [0.5, 0.5, 0.4]
                } else {
                    [0.1, 0.2, 0.2]
                };
                for c in 0..3 {
                    d[(y * w + x) * 3 + c] = (base[c] + noise()).clamp(0.0, 1.0);
                }
            }
        }
        let e = naive_edge_map(&d, h, w);
        let water_textured =
            (0..24 * w).filter(|&i| e[i] >= 0.005).count() as f64 / (24 * w) as f64;
        assert!(water_textured > 0.5, "naive map: {water_textured}");
        let img = crate::ImageRef::new(&d, h, w).unwrap();
        let em = crate::veiling::edge_map(&img);
        let flat =
            (0..24 * w).filter(|&i| (em.e[i] as f64) < em.tau).count() as f64 / (24 * w) as f64;
        assert!(flat > 0.95, "robust map: {flat}");
    }
}
