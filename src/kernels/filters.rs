//! Image filters shared by the stages: clipped box means (METHOD §6), separable
//! Gaussian blur, Sobel magnitude, block downscaling and 8-connected
//! components (METHOD §3). Planes are row-major `h * w` slices; RGB images are
//! interleaved `h * w * 3` slices.

use crate::kernels::boxsum::{box_mean_plane, BoxGeom};
use rayon::prelude::*;

/// Clipped-window box mean of a plane (METHOD §6): each output is the mean of
/// the input over `[y-r, y+r] x [x-r, x+r]` intersected with the image,
/// divided by the number of pixels actually in that window. Exact sums of
/// quantised values ([`crate::kernels::boxsum`]): bit-identical for any thread count.
pub fn box_mean(src: &[f32], h: usize, w: usize, r: usize) -> Vec<f32> {
    box_mean_plane(src, BoxGeom { h, w, r }, rayon::current_num_threads())
}

/// Normalised 1-D Gaussian kernel exp(-x^2 / (2 sigma^2)) on [-radius, radius].
pub fn gaussian_kernel(sigma: f64, radius: usize) -> Vec<f64> {
    let k: Vec<f64> = (-(radius as isize)..=radius as isize)
        .map(|x| (-(x * x) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    k.into_iter().map(|v| v / s).collect()
}

/// Separable convolution of a `c`-channel interleaved image with a symmetric
/// kernel, rows then columns, replicate border. Values missing from a short
/// `src` read as 0 (never a panic).
pub fn convolve_separable(src: &[f32], h: usize, w: usize, c: usize, k: &[f64]) -> Vec<f32> {
    if h == 0 || w == 0 || c == 0 {
        // nothing to convolve (and no rows to walk: chunk sizes must be non-zero)
        return vec![0f32; src.len()];
    }
    let rad = (k.len() / 2) as isize;
    let row_len = w * c;
    let mut tmp = vec![0f32; src.len()];
    tmp.par_chunks_mut(row_len)
        .zip(src.par_chunks(row_len))
        .for_each(|(dst, row)| {
            for (x, px) in dst.chunks_exact_mut(c).enumerate() {
                for (ch, d) in px.iter_mut().enumerate() {
                    let mut s = 0f64;
                    for (j, kv) in k.iter().enumerate() {
                        let xx = (x as isize + j as isize - rad).clamp(0, w as isize - 1) as usize;
                        s += kv * row.get(xx * c + ch).map_or(0.0, |&v| v as f64);
                    }
                    *d = s as f32;
                }
            }
        });
    let mut out = vec![0f32; src.len()];
    let tmp = &tmp;
    out.par_chunks_mut(row_len).enumerate().for_each(|(y, dst)| {
        for (i, d) in dst.iter_mut().enumerate() {
            let mut s = 0f64;
            for (j, kv) in k.iter().enumerate() {
                let yy = (y as isize + j as isize - rad).clamp(0, h as isize - 1) as usize;
                s += kv * tmp.get(yy * w * c + i).map_or(0.0, |&v| v as f64);
            }
            *d = s as f32;
        }
    });
    out
}

/// Sobel gradient magnitude divided by 8 (replicate border) of each channel
/// of an interleaved `c`-channel image, maximum over channels (METHOD §3).
pub fn sobel_max(src: &[f32], h: usize, w: usize, c: usize) -> Vec<f32> {
    if h == 0 || w == 0 {
        return Vec::new();
    }
    let at = |y: isize, x: isize, ch: usize| -> f64 {
        let yy = y.clamp(0, h as isize - 1) as usize;
        let xx = x.clamp(0, w as isize - 1) as usize;
        src.get((yy * w + xx) * c + ch).map_or(0.0, |&v| v as f64)
    };
    let mut out = vec![0f32; h * w];
    out.par_chunks_mut(w).enumerate().for_each(|(y, dst)| {
        let y = y as isize;
        for (x, d) in dst.iter_mut().enumerate() {
            let x = x as isize;
            let mut best = 0f64;
            for ch in 0..c {
                let gx = (at(y - 1, x + 1, ch) - at(y - 1, x - 1, ch))
                    + 2.0 * (at(y, x + 1, ch) - at(y, x - 1, ch))
                    + (at(y + 1, x + 1, ch) - at(y + 1, x - 1, ch));
                let gy = (at(y + 1, x - 1, ch) - at(y - 1, x - 1, ch))
                    + 2.0 * (at(y + 1, x, ch) - at(y - 1, x, ch))
                    + (at(y + 1, x + 1, ch) - at(y - 1, x + 1, ch));
                best = best.max((gx * gx + gy * gy).sqrt() / 8.0);
            }
            *d = best as f32;
        }
    });
    out
}

/// Block-average downscale of an interleaved `c`-channel image by an integer
/// factor `s` (METHOD §3 step 2); partial border blocks average the pixels
/// they hold. Returns the image and its size.
pub fn downscale(src: &[f32], h: usize, w: usize, c: usize, s: usize) -> (Vec<f32>, usize, usize) {
    downscale_map(src, h, w, c, s, |v| v)
}

/// [`downscale`] of `f(value)` (e.g. a normalisation), without a full-size copy.
pub fn downscale_map<F: Fn(f32) -> f32 + Sync>(
    src: &[f32],
    h: usize,
    w: usize,
    c: usize,
    s: usize,
    f: F,
) -> (Vec<f32>, usize, usize) {
    let s = s.max(1);
    if s == 1 {
        return (src.par_iter().map(|&v| f(v)).collect(), h, w);
    }
    let (hs, ws) = (h.div_ceil(s), w.div_ceil(s));
    let mut out = vec![0f32; hs * ws * c];
    out.par_chunks_mut(ws * c)
        .enumerate()
        .for_each(|(by, dst)| {
            let y0 = by * s;
            let y1 = (y0 + s).min(h);
            let mut sums = vec![0f64; ws * c];
            for row in src.get(y0 * w * c..y1 * w * c).unwrap_or(&[]).chunks_exact(w * c) {
                for (blk, px) in sums.chunks_exact_mut(c).zip(row.chunks(s * c)) {
                    for p in px.chunks_exact(c) {
                        for (acc, v) in blk.iter_mut().zip(p) {
                            *acc += f(*v) as f64;
                        }
                    }
                }
            }
            for (bx, (d, sm)) in dst.chunks_exact_mut(c).zip(sums.chunks_exact(c)).enumerate() {
                let nx = ((bx + 1) * s).min(w) - bx * s;
                let n = ((y1 - y0) * nx) as f64;
                for (o, v) in d.iter_mut().zip(sm) {
                    *o = (v / n) as f32;
                }
            }
        });
    (out, hs, ws)
}

/// 8-connected components of the true pixels of a `h x w` grid. Labels are
/// 1.. in raster order of each component's first pixel (0 = background).
/// Returns (labels, sizes) with `sizes[l - 1]` the size of label `l`.
pub fn components8(grid: &[bool], h: usize, w: usize) -> (Vec<u32>, Vec<usize>) {
    let mut labels = vec![0u32; h * w];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for (start, &g) in grid.iter().enumerate().take(h * w) {
        let Some(first) = labels.get_mut(start) else {
            continue;
        };
        if !g || *first != 0 {
            continue;
        }
        let label = sizes.len() as u32 + 1;
        *first = label;
        stack.push(start);
        let mut size = 0usize;
        while let Some(i) = stack.pop() {
            size += 1;
            let (y, x) = (i / w, i % w);
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (ny, nx) = (y as isize + dy, x as isize + dx);
                    if ny < 0 || nx < 0 || ny >= h as isize || nx >= w as isize {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if let (Some(&true), Some(l)) = (grid.get(j), labels.get_mut(j)) {
                        if *l == 0 {
                            *l = label;
                            stack.push(j);
                        }
                    }
                }
            }
        }
        sizes.push(size);
    }
    (labels, sizes)
}

/// The largest 8-connected component of `grid` (ties: the component whose
/// first pixel in raster order comes first); all false if `grid` is.
pub fn largest_component(grid: &[bool], h: usize, w: usize) -> Vec<bool> {
    let (labels, sizes) = components8(grid, h, w);
    let mut best: Option<(usize, usize)> = None;
    for (i, &s) in sizes.iter().enumerate() {
        if best.is_none_or(|(_, bs)| s > bs) {
            best = Some((i, s));
        }
    }
    match best {
        Some((i, _)) => labels.iter().map(|&l| l as usize == i + 1).collect(),
        None => vec![false; h * w],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::kernels::util::test_noise as lcg;

    #[test]
    fn box_mean_is_the_exact_streaming_box_mean() {
        // the brute-force comparison lives with the implementation (boxsum)
        let (h, w) = (7, 9);
        let x = lcg(h * w, 3);
        for r in [0usize, 1, 3, 10] {
            assert_eq!(box_mean(&x, h, w, r), box_mean_plane(&x, BoxGeom { h, w, r }, 1));
        }
    }

    #[test]
    fn gaussian_blur_keeps_constants_and_mass() {
        let k = gaussian_kernel(1.0, 3);
        assert_eq!(k.len(), 7);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let img = vec![0.3f32; 5 * 6 * 3];
        let b = convolve_separable(&img, 5, 6, 3, &k);
        assert!(b.iter().all(|&v| (v - 0.3).abs() < 1e-6));
    }

    #[test]
    fn sobel_on_a_ramp() {
        // f(x) = 0.01 x: gx = (1 + 2 + 1) * 0.02 = 0.08 -> /8 = 0.01 inside.
        let (h, w) = (5, 6);
        let img: Vec<f32> = (0..h * w).map(|i| 0.01 * (i % w) as f32).collect();
        let e = sobel_max(&img, h, w, 1);
        assert!((e[2 * w + 2] - 0.01).abs() < 1e-6);
        // at the left border (replicate) the central difference spans one step
        assert!((e[2 * w] - 0.005).abs() < 1e-6);
    }

    #[test]
    fn downscale_averages_blocks_with_partial_borders() {
        // 3x3 single channel, s=2 -> 2x2: blocks {0,1,3,4}, {2,5}, {6,7}, {8}
        let img: Vec<f32> = (0..9).map(|v| v as f32).collect();
        let (d, hs, ws) = downscale(&img, 3, 3, 1, 2);
        assert_eq!((hs, ws), (2, 2));
        assert_eq!(d, vec![2.0, 3.5, 6.5, 8.0]);
    }

    #[test]
    fn components_on_drawn_shapes() {
        // Two shapes: a diagonal chain (8-connected, 4 px) and a 2x3 block (6 px).
        let pic = [
            "#.....", //
            ".#..##", //
            "..#.##", //
            "...###", //
            "#.....", //
        ];
        let (h, w) = (pic.len(), pic[0].len());
        let grid: Vec<bool> = pic
            .iter()
            .flat_map(|r| r.chars().map(|c| c == '#'))
            .collect();
        let (labels, sizes) = components8(&grid, h, w);
        // diagonal #,#,# then the block (whose corner touches the diagonal at (3,3)? no:
        // (2,2) and (3,3) are diagonal neighbours, so they join) and a lone pixel.
        assert_eq!(sizes, vec![10, 1]);
        assert_eq!(labels[0], 1);
        assert_eq!(labels[4 * w], 2);
        let big = largest_component(&grid, h, w);
        assert_eq!(big.iter().filter(|&&b| b).count(), 10);
        // tie: two single pixels -> the first in raster order wins
        let mut g = vec![false; 9];
        g[2] = true;
        g[6] = true;
        let l = largest_component(&g, 3, 3);
        assert!(l[2] && !l[6]);
        assert!(largest_component(&[false; 4], 2, 2).iter().all(|&b| !b));
    }
}
