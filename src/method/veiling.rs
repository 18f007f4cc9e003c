//! Veiling light A and the water region VL (METHOD §3, METHOD §3).
//!
//! The reference uses a pretrained edge forest; here the edge strength is a
//! deterministic, noise-aware map computed on a downscaled, globally
//! normalised copy: no per-channel stretch and no CLAHE (both amplify the
//! sensor noise of flat water, worst in a nearly empty red channel), a
//! sigma = 1 Gaussian, the Sobel magnitude / 8, the maximum over channels,
//! and a threshold of min(max(0.005, 0.6 * sigma_noise), 0.02) where sigma_noise is
//! Immerkaer's robust estimate of the image's own noise.

use crate::kernels::filters::{
    convolve_separable, downscale, downscale_map, gaussian_kernel, largest_component, sobel_max,
};
use crate::method::image::ImageRef;
use crate::method::params::Flag;
use crate::kernels::rank::{f32_key, f64_key, key_f32, order_stats};
use crate::kernels::util::{percentiles, Normalize};
use rayon::prelude::*;

/// Longer side of the working copy for the edge map (METHOD §3 variant).
pub const EDGE_SIDE: usize = 512;
/// Fixed part of the textureless threshold (METHOD §3).
pub const EDGE_THRESHOLD: f64 = 0.005;
/// Noise multiple of the threshold: for Gaussian noise of std sigma, 99.9%
/// of the edge map lies below 0.58 sigma (measured).
pub const K_NOISE: f64 = 0.6;
/// Ceiling of the noise-adaptive threshold: the noise estimate cannot tell
/// noise from fine texture on an image that is textured everywhere, so the
/// threshold may rise at most to 4x its fixed part (noise std up to 0.033
/// of the image range).
pub const EDGE_THRESHOLD_MAX: f64 = 0.02;
/// Fraction of the top rows where VL may lie (METHOD §3.4).
pub const TOP_FRACTION_DEN: usize = 4;
/// Below this fraction of the pixels VL counts as empty (METHOD §3).
pub const MIN_VL_FRACTION: f64 = 0.001;
/// The lower quartile of |Z| for a standard normal Z.
pub const HALF_NORMAL_Q25: f64 = 0.318_639_363_964_375_2;
/// Lower bound for every component of A, so that I / A is defined.
pub const MIN_A: f32 = 1e-4;

/// A detected region whose median-luminance color is darker than this
/// fraction of the image's median luminance is rejected (a shadow).
pub const DARK_REGION_RATIO: f64 = 0.2;

/// The edge-strength map at working size, with what produced it.
#[derive(Debug, Clone)]
pub struct EdgeMap {
    /// edge strength, `hs * ws`
    pub e: Vec<f32>,
    /// rows of the working copy
    pub hs: usize,
    /// columns of the working copy
    pub ws: usize,
    /// integer downscale factor
    pub scale: usize,
    /// the robust noise estimate (in normalised units)
    #[cfg_attr(not(any(test, feature = "internals")), allow(dead_code))]
    pub sigma: f64,
    /// the threshold used: E < tau is textureless
    pub tau: f64,
}

/// The result of [`estimate`].
#[derive(Debug, Clone)]
pub struct Veiling {
    /// veiling light A (linear input units, clamped to >= [`MIN_A`])
    pub a: [f32; 3],
    /// water region VL, one entry per pixel (all false when empty)
    pub vl: Vec<bool>,
    /// number of true entries of `vl`
    pub vl_count: usize,
    /// flags raised
    pub flags: Vec<Flag>,
}

/// Immerkaer's robust noise estimate (METHOD §3 step 5): per channel
/// the lower quartile of |M * x| over interior pixels (M the Laplacian-
/// difference kernel, whose response to white noise of std sigma has std
/// 6 sigma) divided by 6 * 0.31864 (the lower quartile of a half-normal
/// variable); the maximum over the three channels. The lower quartile, not
/// the median, keeps texture from inflating the estimate unless three
/// quarters of the image are textured.
pub fn noise_sigma(img: &[f32], h: usize, w: usize) -> f64 {
    if h < 3 || w < 3 {
        return 0.0;
    }
    let mut best = 0f64;
    for c in 0..3 {
        // (y, x) stay inside the image below; 0 only for a short buffer
        let at = |y: usize, x: usize| img.get((y * w + x) * 3 + c).copied().unwrap_or(0.0);
        let resp: Vec<f32> = (1..h - 1)
            .into_par_iter()
            .flat_map_iter(|y| {
                (1..w - 1).map(move |x| {
                    let v =
                        (at(y - 1, x - 1) + at(y - 1, x + 1) + at(y + 1, x - 1) + at(y + 1, x + 1))
                            - 2.0 * (at(y - 1, x) + at(y + 1, x) + at(y, x - 1) + at(y, x + 1))
                            + 4.0 * at(y, x);
                    v.abs()
                })
            })
            .collect();
        let q = percentiles(resp, &[0.25]).first().copied().unwrap_or(0.0);
        best = best.max(q / (6.0 * HALF_NORMAL_Q25));
    }
    best
}

/// Integer downscale factor bringing the longer side to about [`EDGE_SIDE`].
pub fn edge_scale(h: usize, w: usize) -> usize {
    h.max(w).div_ceil(EDGE_SIDE).max(1)
}

/// The edge-strength map of METHOD §3 steps 1-5.
pub fn edge_map(img: &ImageRef) -> EdgeMap {
    let (h, w) = (img.height, img.width);
    let norm = Normalize::masked(img.data, None);
    let scale = edge_scale(h, w);
    let (small, hs, ws) = downscale_map(img.data, h, w, 3, scale, |v| norm.apply(v));
    let sigma = noise_sigma(&small, hs, ws);
    let blurred = convolve_separable(&small, hs, ws, 3, &gaussian_kernel(1.0, 3));
    let e = sobel_max(&blurred, hs, ws, 3);
    let tau = EDGE_THRESHOLD.max(K_NOISE * sigma).min(EDGE_THRESHOLD_MAX);
    EdgeMap {
        e,
        hs,
        ws,
        scale,
        sigma,
        tau,
    }
}

/// The detected water region at full size (METHOD §3 steps 6-8), before
/// the size check of step 9.
pub fn detect_region(img: &ImageRef, mask: Option<&[bool]>) -> Vec<bool> {
    let em = edge_map(img);
    let (hs, ws) = (em.hs, em.ws);
    let top = hs.div_ceil(TOP_FRACTION_DEN);
    let grid: Vec<bool> = (0..hs * ws)
        .map(|i| i / ws < top && em.e.get(i).is_some_and(|&e| (e as f64) < em.tau))
        .collect();
    let small = largest_component(&grid, hs, ws);
    let (w, s) = (img.width, em.scale);
    (0..img.len())
        .into_par_iter()
        .map(|i| {
            let (y, x) = (i / w, i % w);
            small.get((y / s) * ws + x / s).copied().unwrap_or(false)
                && mask.is_none_or(|m| m.get(i).copied().unwrap_or(false))
        })
        .collect()
}

/// Luminance of linear RGB (Rec. 709 / sRGB primaries).
#[inline]
pub fn luminance(p: [f32; 3]) -> f64 {
    0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64
}

/// Median (lower) luminance of the masked-in pixels.
pub fn median_luminance(img: &ImageRef, mask: Option<&[bool]>) -> f64 {
    let (h, w) = (img.height, img.width);
    let n = mask.map_or(img.len(), |m| m.par_iter().filter(|&&b| b).count());
    if n == 0 {
        return 0.0;
    }
    let k = (n - 1) / 2;
    let [v] = order_stats(h, [n], [&[k]], |y, b: &mut [Vec<u32>; 1]| {
        let row = img.data.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
        for (x, &p) in row.as_chunks::<3>().0.iter().enumerate() {
            if mask.is_none_or(|m| m.get(y * w + x).copied().unwrap_or(false)) {
                b[0].push(f32_key(luminance(p) as f32));
            }
        }
    });
    v.first().map_or(0.0, |&k| key_f32(k) as f64)
}

/// A as the color of the VL pixel with the (lower) median luminance; VL
/// pixels ordered by (luminance, raster index). None for an empty region.
pub fn veiling_from_region(img: &ImageRef, vl: &[bool]) -> Option<[f32; 3]> {
    let (h, w) = (img.height, img.width);
    let n = vl.par_iter().filter(|&&b| b).count();
    if n == 0 {
        return None;
    }
    let k = (n - 1) / 2;
    // key: (luminance, raster index), as one integer
    let [v] = order_stats(h, [n], [&[k]], |y, b: &mut [Vec<u128>; 1]| {
        let row = img.data.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
        for (x, &p) in row.as_chunks::<3>().0.iter().enumerate() {
            let i = y * w + x;
            if vl.get(i).copied().unwrap_or(false) {
                b[0].push(((f64_key(luminance(p)) as u128) << 64) | i as u128);
            }
        }
    });
    let i = v.first().map(|&key| key as u64 as usize)?;
    img.data.as_chunks::<3>().0.get(i).copied()
}

/// The fallback A (METHOD §3): the brightest 0.1% of a heavily blurred,
/// downscaled copy of the input, in its top half.
pub fn veiling_fallback(img: &ImageRef) -> [f32; 3] {
    let (h, w) = (img.height, img.width);
    let (small, hs, ws) = downscale(img.data, h, w, 3, edge_scale(h, w));
    let sigma = hs.max(ws) as f64 / 20.0;
    let radius = (3.0 * sigma).ceil() as usize;
    let blurred = convolve_separable(&small, hs, ws, 3, &gaussian_kernel(sigma, radius));
    let n = hs.div_ceil(2) * ws;
    let px = blurred.as_chunks::<3>().0;
    let mut idx: Vec<(f64, usize)> = px
        .iter()
        .take(n)
        .enumerate()
        .map(|(i, &p)| (luminance(p), i))
        .collect();
    idx.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let k = ((0.001 * n as f64).ceil() as usize).max(1);
    let mut acc = [0f64; 3];
    for p in idx.iter().take(k).filter_map(|&(_, i)| px.get(i)) {
        for (a, &v) in acc.iter_mut().zip(p) {
            *a += v as f64;
        }
    }
    [
        (acc[0] / k as f64) as f32,
        (acc[1] / k as f64) as f32,
        (acc[2] / k as f64) as f32,
    ]
}

/// Veiling light and water region (METHOD §3 / METHOD §3). `water_mask`
/// replaces detection, `given_a` replaces the estimate of A.
pub fn estimate(
    img: &ImageRef,
    mask: Option<&[bool]>,
    water_mask: Option<&[bool]>,
    given_a: Option<[f32; 3]>,
) -> Veiling {
    let n = img.len();
    let detected = water_mask.is_none();
    let mut vl = match water_mask {
        Some(wm) => wm
            .iter()
            .enumerate()
            .map(|(i, &b)| b && mask.is_none_or(|m| m.get(i).copied().unwrap_or(false)))
            .collect(),
        None => detect_region(img, mask),
    };
    let mut vl_count = vl.iter().filter(|&&b| b).count();
    let min_count = ((MIN_VL_FRACTION * n as f64).ceil() as usize).max(2);
    let mut flags = Vec::new();
    let mut from_region = veiling_from_region(img, &vl);
    if detected {
        if let Some(cand) = from_region {
            // A flat region far darker than the scene is a shadow, not the
            // water at infinity: every object pixel would be brighter than
            // its own asymptote (METHOD §3 step 9).
            if luminance(cand) < DARK_REGION_RATIO * median_luminance(img, mask) {
                from_region = None;
            }
        }
    }
    if vl_count < min_count || from_region.is_none() {
        vl.iter_mut().for_each(|b| *b = false);
        vl_count = 0;
        from_region = None;
        flags.push(Flag::NoWaterRegion);
    }
    let mut a = match (given_a, from_region) {
        (Some(a), _) => a,
        (None, Some(a)) => a,
        (None, None) => {
            flags.push(Flag::VeilingFallback);
            veiling_fallback(img)
        }
    };
    if a.iter().any(|&v| v < MIN_A) {
        flags.push(Flag::VeilingLightClamped);
        a.iter_mut().for_each(|v| *v = v.max(MIN_A));
    }
    if !water_coloured(a) {
        flags.push(Flag::VeilingLightNotWater);
    }
    Veiling {
        a,
        vl,
        vl_count,
        flags,
    }
}

/// Whether a veiling light can be the colour of water (METHOD §3): its red
/// below its green or its blue. Water attenuates red the most in every
/// type of the table, so its veil, lit by daylight that crossed it, is
/// never reddest; a veil as red as it is green and blue is the haze of air,
/// a warm wall taken for water, or water no type describes (tannin).
pub fn water_coloured(a: [f32; 3]) -> bool {
    a[0] < a[1].max(a[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Water (constant A) in the upper rows above a textured checkerboard.
    fn water_over_texture(h: usize, w: usize, horizon: usize) -> Vec<f32> {
        let mut d = vec![0f32; h * w * 3];
        for y in 0..h {
            for x in 0..w {
                let p = if y < horizon {
                    [0.05, 0.3, 0.45]
                } else if (x / 2 + y / 2) % 2 == 0 {
                    [0.6, 0.5, 0.3]
                } else {
                    [0.1, 0.2, 0.1]
                };
                d[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&p);
            }
        }
        d
    }

    #[test]
    fn finds_flat_water_and_its_color() {
        let (h, w) = (40, 60);
        let d = water_over_texture(h, w, 14);
        let img = ImageRef::new(&d, h, w).unwrap();
        let v = estimate(&img, None, None, None);
        assert!(v.flags.is_empty(), "{:?}", v.flags);
        assert_eq!(v.a, [0.05, 0.3, 0.45]);
        // only the top quarter (10 rows) may be water, and all of it is, bar
        // the row whose blurred edge touches the horizon
        let rows_in: Vec<usize> = (0..h).filter(|&y| v.vl[y * w + 30]).collect();
        assert_eq!(rows_in, (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn textured_image_falls_back() {
        let (h, w) = (40, 60);
        let d = water_over_texture(h, w, 0);
        let img = ImageRef::new(&d, h, w).unwrap();
        let v = estimate(&img, None, None, None);
        assert_eq!(v.vl_count, 0);
        // the fallback takes A from the warm squares: no water's colour, and said so
        assert_eq!(v.flags, vec![Flag::NoWaterRegion, Flag::VeilingFallback, Flag::VeilingLightNotWater]);
        assert!(v.a.iter().all(|&x| x > 0.0 && x <= 1.0));
    }

    #[test]
    fn given_water_mask_and_a_are_used() {
        let (h, w) = (20, 20);
        let d = water_over_texture(h, w, 5);
        let img = ImageRef::new(&d, h, w).unwrap();
        let mut wm = vec![false; h * w];
        wm[..3 * w].iter_mut().for_each(|b| *b = true);
        let v = estimate(&img, None, Some(&wm), Some([0.2, 0.3, 0.0]));
        assert_eq!(v.vl, wm);
        assert_eq!(v.a, [0.2, 0.3, MIN_A]);
        assert_eq!(v.flags, vec![Flag::VeilingLightClamped]);
    }

    #[test]
    fn a_veil_as_red_as_green_or_blue_is_not_water() {
        // by hand: red below the larger of green and blue is water's colour
        assert!(water_coloured([0.02, 0.20, 0.40]) && water_coloured([0.04, 0.30, 0.18]));
        assert!(water_coloured([0.45, 0.55, 0.78]) && water_coloured([0.29, 0.30, 0.10]));
        assert!(!water_coloured([0.50, 0.44, 0.41]) && !water_coloured([0.4, 0.4, 0.4]) && !water_coloured([0.3, 0.3, 0.1]));
        let (h, w) = (20, 20);
        let d = water_over_texture(h, w, 5);
        let img = ImageRef::new(&d, h, w).unwrap();
        let wm: Vec<bool> = (0..h * w).map(|i| i < 3 * w).collect();
        let v = estimate(&img, None, Some(&wm), Some([0.5, 0.44, 0.41]));
        assert_eq!(v.flags, vec![Flag::VeilingLightNotWater]);
        // the order the flags are taken in: clamped first
        let v = estimate(&img, None, Some(&wm), Some([0.3, 0.0, 0.2]));
        assert_eq!(v.flags, vec![Flag::VeilingLightClamped, Flag::VeilingLightNotWater]);
    }

    #[test]
    fn dark_flat_region_is_a_shadow_not_water() {
        // flat near-black top (a shadow) over bright texture: rejected
        let (h, w) = (40, 60);
        let mut d = water_over_texture(h, w, 14);
        for px in d[..14 * w * 3].chunks_mut(3) {
            px.copy_from_slice(&[0.004, 0.006, 0.007]);
        }
        let img = ImageRef::new(&d, h, w).unwrap();
        let v = estimate(&img, None, None, None);
        assert_eq!(v.vl_count, 0);
        assert_eq!(v.flags, vec![Flag::NoWaterRegion, Flag::VeilingFallback, Flag::VeilingLightNotWater]);
        // the same region given as a water mask is the user's word: kept
        let mut wm = vec![false; h * w];
        wm[..10 * w].iter_mut().for_each(|b| *b = true);
        let v = estimate(&img, None, Some(&wm), None);
        assert_eq!(v.vl_count, 10 * w);
    }

    #[test]
    fn noise_estimate_of_pure_noise() {
        // uniform noise in [-0.5, 0.5) * 0.02 has std 0.02 / sqrt(12)
        let (h, w) = (200, 200);
        let mut s: u64 = 7;
        let d: Vec<f32> = (0..h * w * 3)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                0.5 + 0.02 * (((s >> 40) as f32 / (1u64 << 24) as f32) - 0.5)
            })
            .collect();
        let sig = noise_sigma(&d, h, w);
        let truth = 0.02 / 12f64.sqrt();
        assert!((sig / truth - 1.0).abs() < 0.15, "{sig} vs {truth}");
    }
}
