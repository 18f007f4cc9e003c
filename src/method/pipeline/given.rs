//! METHOD §13: restoring with a known distance. The water (attenuation per
//! channel and veiling light) is fitted from the photo and its distance
//! map ([`crate::method::distance`]); the transmission is e^(-beta_c z),
//! the distance filled from the nearest known pixel where it is unknown;
//! the display removes a tint of light that crossed the same water
//! (METHOD §13.4). No haze-line is needed: with the distance the method
//! has what the haze-lines guess.

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::method::distance::{fit_water, known, nearest_type, WaterFit};
use crate::method::fallback::trust;
use crate::method::params::{Flag, Input, Params, Restoration, Stage};
use crate::method::profile::Fallback;
use crate::method::veiling::estimate;
use crate::method::water::WaterType;

/// Fewer known object pixels than this share of the image leave too little
/// to fit the water with.
pub const MIN_COVERAGE: f32 = 0.05;

/// The smallest transmission a channel is divided by (METHOD §13.3).
pub const MIN_T: f32 = 0.05;

/// The depths of light path searched for the display's tint (METHOD §13.4):
/// d = 0, `PATH_STEP`, ..., `PATH_MAX` metres.
pub const PATH_MAX: f64 = 15.0;
/// Step of the searched light path, metres.
pub const PATH_STEP: f64 = 0.25;

/// What became of a given distance map (the sidecar's `distance`).
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceUse {
    /// the share of the image's pixels with a known distance
    pub coverage: f32,
    /// the fitted water, when a fit was made
    pub fit: Option<WaterFit>,
    /// the nearest Jerlov type to the fitted ratios and how far (in the log
    /// of the ratios beta_B/beta_R, beta_B/beta_G)
    pub nearest: Option<(String, f32)>,
    /// why the distance was not used (None: it was)
    pub rejected: Option<String>,
    /// the light path (metres of the same water) whose tint the display
    /// removed (METHOD §13.4)
    pub light_path: Option<f32>,
}

/// Resizes a distance map to `h` x `w` by nearest neighbour (an average
/// would blend a near edge with the far background into a distance that
/// exists nowhere). A map of another aspect ratio (more than 2% apart) is
/// refused: it is not this photo's.
pub fn resize_distance(z: &[f32], zh: usize, zw: usize, h: usize, w: usize) -> Result<Vec<f32>> {
    if zh == 0 || zw == 0 || z.len() != zh.saturating_mul(zw) {
        return Err(Error::Distance(format!("the distance map holds {} values, not {zw}x{zh}", z.len())));
    }
    if (zh, zw) == (h, w) {
        return Ok(z.to_vec());
    }
    let (ra, rb) = (zw as f64 / zh as f64, w as f64 / h as f64);
    if (ra / rb - 1.0).abs() > 0.02 {
        return Err(Error::Distance(format!(
            "the distance map is {zw}x{zh} and the image {w}x{h}: another aspect ratio (another photo's map?)"
        )));
    }
    let xs: Vec<usize> = (0..w).map(|x| (((x as f64 + 0.5) * zw as f64 / w as f64) as usize).min(zw - 1)).collect();
    let mut out = Vec::with_capacity(h.saturating_mul(w));
    for y in 0..h {
        let sy = (((y as f64 + 0.5) * zh as f64 / h as f64) as usize).min(zh - 1);
        let row = z.get(sy * zw..(sy + 1) * zw).unwrap_or(&[]);
        out.extend(xs.iter().map(|&sx| row.get(sx).copied().unwrap_or(f32::NAN)));
    }
    Ok(out)
}

/// Each unknown distance replaced by that of the nearest known pixel (in
/// steps of the 4-neighbourhood, ties to the first reached in raster
/// order): the holes of a depth map are mostly the same surface as their
/// rim (METHOD §13.3). None when no pixel is known.
pub fn fill_nearest(z: &[f32], h: usize, w: usize) -> Option<Vec<f32>> {
    let mut out = z.to_vec();
    let mut done: Vec<bool> = z.iter().map(|&v| known(v)).collect();
    let mut queue: VecDeque<usize> = (0..z.len()).filter(|&i| done.get(i).copied().unwrap_or(false)).collect();
    if queue.is_empty() {
        return None;
    }
    while let Some(i) = queue.pop_front() {
        let v = out.get(i).copied().unwrap_or(f32::NAN);
        let (y, x) = (i / w.max(1), i % w.max(1));
        let next = [
            (y > 0).then(|| i - w),
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y + 1 < h).then(|| i + w),
        ];
        for j in next.into_iter().flatten() {
            if let Some(d) = done.get_mut(j) {
                if !*d {
                    *d = true;
                    if let Some(o) = out.get_mut(j) {
                        *o = v;
                    }
                    queue.push_back(j);
                }
            }
        }
    }
    Some(out)
}

/// The whole method with a known distance (METHOD §13): `distance` is a
/// `zh` x `zw` map in metres (NaN, 0 or negative unknown) of the image's
/// aspect ratio, resized to it by [`resize_distance`]. A map of another
/// aspect ratio, one with too little known, or one the fitted model does
/// not explain is not used: the photo is restored without it and flagged
/// `distance_rejected`, and `Restoration::distance` says why.
pub fn restore_at_distance(input: &Input, distance: &[f32], zh: usize, zw: usize, params: &Params) -> Result<Restoration> {
    let t0 = std::time::Instant::now();
    let img = &input.image;
    let rejected = |why: String, coverage: f32, fit: Option<WaterFit>| -> Result<Restoration> {
        let mut res = super::restore(input, params)?;
        res.flags.push(Flag::DistanceRejected);
        res.distance = Some(DistanceUse { coverage, fit, nearest: None, rejected: Some(why), light_path: None });
        Ok(res)
    };
    let z = match resize_distance(distance, zh, zw, img.height, img.width) {
        Ok(z) => z,
        Err(Error::Distance(why)) => return rejected(why, 0.0, None),
        Err(e) => return Err(e),
    };
    let coverage = z.iter().filter(|&&v| known(v)).count() as f32 / img.len().max(1) as f32;
    if coverage < MIN_COVERAGE {
        return rejected(format!("only {:.1}% of the pixels have a known distance", 100.0 * coverage), coverage, None);
    }
    let fit = match fit_water(img.data, img.height, img.width, &z, input.mask) {
        Ok(f) if f.suspect() => {
            let why = format!(
                "the photo does not follow its distance map (residual {:.3}): another photo's map, other units, or too little water between near and far",
                f.residual
            );
            return rejected(why, coverage, Some(f));
        }
        Ok(f) => f,
        Err(why) => return rejected(why, coverage, None),
    };
    let Some(filled) = fill_nearest(&z, img.height, img.width) else {
        return rejected("no pixel has a known distance".into(), coverage, None);
    };
    let [br, bg, bb] = fit.beta;
    let (name, how_far) = nearest_type(fit.beta);
    let wt = WaterType::new(name, f64::from(bb / br), f64::from(bb / bg))?;
    let a = fit.veiling_light.map(|v| v.max(crate::method::veiling::MIN_A));
    let mut timings = vec![(Stage::Validation, t0.elapsed().as_secs_f64())];
    let t1 = std::time::Instant::now();
    // §3 for the water region only (the record), with the fitted A
    let veil = estimate(img, input.mask, input.water_mask, Some(a));
    // §13.3: t_c = max(e^(-beta_c z), MIN_T), J_c = A_c + (I_c - A_c) / t_c
    let n = img.len();
    let mut transmission = vec![0f32; n];
    let mut radiance = vec![0f32; 3 * n];
    transmission
        .par_iter_mut()
        .zip(radiance.par_chunks_mut(3))
        .zip(img.data.par_chunks(3))
        .zip(filled.par_iter())
        .for_each(|(((tb, j), px), &zv)| {
            *tb = (-bb * zv).exp().clamp(1e-6, 1.0);
            for c in 0..3 {
                let t = (-fit.beta[c] * zv).exp().max(MIN_T);
                if let (Some(o), Some(&p)) = (j.get_mut(c), px.get(c)) {
                    *o = a[c] + (p - a[c]) / t;
                }
            }
        });
    // J below 0 (noise over a far, dark pixel) is clipped; no artifact
    // clamp of §7: its shift by min J adds gray to every pixel, and with the
    // distance known there is no haze-line artifact to hide (METHOD §13.3)
    radiance.par_iter_mut().for_each(|v| *v = v.max(0.0));
    let inside = |i: usize| input.mask.is_none_or(|m| m.get(i).copied().unwrap_or(false));
    // §13.4: the tint of light that crossed the same water, then exposure
    let objects = |i: usize| inside(i) && known(z.get(i).copied().unwrap_or(f32::NAN)) && !veil.vl.get(i).copied().unwrap_or(false);
    let d = light_path(&radiance, &objects, fit.beta);
    let gains: [f32; 3] = std::array::from_fn(|c| (f64::from(fit.beta[c]) * d).exp() as f32);
    let mut image = expose(&radiance, &gains, &inside);
    // the output radiance is J in [0, 1] (METHOD §10)
    radiance.par_iter_mut().for_each(|v| *v = v.min(1.0));
    // METHOD §12.5's confidence and flag, without the blend toward the
    // input's balance: with the distance known the transmission is not a
    // guess, and the blend took the held renders' own-colour scenes under
    // white light from 7.0 to 10.9 degrees (METHOD §13.5)
    let tr = (params.fallback_used() == Fallback::InputBalance).then(|| {
        let vl = &veil.vl;
        let objects = move |i: usize| inside(i) && !vl.get(i).copied().unwrap_or(false);
        trust(img, &objects, a, &wt, &transmission, &radiance, &mut image, false)
    });
    let mut flags = veil.flags.clone();
    if tr.as_ref().is_some_and(|t| t.unreliable()) {
        flags.push(Flag::Unreliable);
    }
    if let Some(t) = &tr {
        settle_noise(&mut image, &t.confidence, img.height, img.width);
    }
    timings.push((Stage::ChosenOutputs, t1.elapsed().as_secs_f64()));
    Ok(Restoration {
        height: img.height,
        width: img.width,
        image,
        radiance,
        transmission,
        water_type: wt.clone(),
        scores: vec![(wt.name.clone(), 0.0)],
        excluded: Vec::new(),
        veiling_light: a,
        veiling_mask: veil.vl,
        flags,
        confidence: tr.as_ref().map(|t| t.confidence.clone()),
        veil_excess: tr.as_ref().map(|t| t.veil_excess),
        distance: Some(DistanceUse {
            coverage,
            nearest: Some((name.to_string(), how_far)),
            fit: Some(fit),
            rejected: None,
            light_path: Some(d as f32),
        }),
        guided_radius: 0,
        guided_subsample: 1,
        timings,
    })
}

/// METHOD §13.4: where the confidence is low (the noise, magnified by
/// 1/t far away, is of the size of the colour) the displayed chromaticity
/// is blended toward that of its local mean, so that far pixels show the
/// surface's colour rather than coloured speckle, while the brightness
/// keeps every detail: m = c image + (1 - c) box(image), box of radius
/// max(2, min(H, W) / 80), c the confidence; then m is scaled so that its
/// channel sum is the image's.
fn settle_noise(image: &mut [f32], confidence: &[f32], h: usize, w: usize) {
    if confidence.iter().all(|&c| c >= 1.0) {
        return;
    }
    let r = (h.min(w) / 80).max(2);
    let means: Vec<Vec<f32>> = (0..3)
        .map(|c| {
            let plane: Vec<f32> = image.iter().skip(c).step_by(3).copied().collect();
            crate::kernels::filters::box_mean(&plane, h, w, r)
        })
        .collect();
    image.par_chunks_exact_mut(3).zip(confidence.par_iter()).enumerate().for_each(|(i, (px, &k))| {
        let mixed: [f32; 3] = std::array::from_fn(|c| {
            let m = means.get(c).and_then(|p| p.get(i)).copied().unwrap_or(0.0);
            k * px.get(c).copied().unwrap_or(0.0) + (1.0 - k) * m
        });
        let (sv, sm) = (px.iter().sum::<f32>(), mixed.iter().sum::<f32>());
        let scale = if sm > 0.0 { sv / sm } else { 0.0 };
        for (v, m) in px.iter_mut().zip(mixed) {
            *v = (m * scale).clamp(0.0, 1.0);
        }
    });
}

/// Every 7th pixel in raster order is enough for the casts of the search.
const SAMPLE: usize = 7;

/// METHOD §13.4: the light path d (metres of the fitted water) whose gains
/// g_c = e^(beta_c d) leave the least cast: the sum, over p = 1 (gray world)
/// and p = 4 (shades of gray), of the spread (sample std / mean) of the
/// three channels' power means of g J over the object pixels with a known
/// distance (every 7th). A power mean scales with its gain, so the means
/// are taken once and the search is over three numbers per d.
pub fn light_path(radiance: &[f32], objects: &dyn Fn(usize) -> bool, beta: [f32; 3]) -> f64 {
    let mut s1 = [0f64; 3];
    let mut s4 = [0f64; 3];
    let mut n = 0f64;
    for (i, px) in radiance.chunks_exact(3).enumerate().step_by(SAMPLE) {
        if !objects(i) {
            continue;
        }
        n += 1.0;
        for c in 0..3 {
            let v = f64::from(px.get(c).copied().unwrap_or(0.0));
            if let (Some(a), Some(b)) = (s1.get_mut(c), s4.get_mut(c)) {
                *a += v;
                *b += v.powi(4);
            }
        }
    }
    if n == 0.0 {
        return 0.0;
    }
    let e1 = s1.map(|v| v / n);
    let e4 = s4.map(|v| (v / n).powf(0.25));
    let spread = |e: [f64; 3]| {
        let m = (e[0] + e[1] + e[2]) / 3.0;
        if m <= 0.0 {
            return f64::INFINITY;
        }
        let var = e.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 2.0;
        var.sqrt() / m
    };
    let steps = (PATH_MAX / PATH_STEP).round() as usize;
    let mut best = (f64::INFINITY, 0.0);
    for k in 0..=steps {
        let d = k as f64 * PATH_STEP;
        let g: [f64; 3] = std::array::from_fn(|c| (f64::from(beta[c]) * d).exp());
        let cost = spread(std::array::from_fn(|c| g[c] * e1[c])) + spread(std::array::from_fn(|c| g[c] * e4[c]));
        if cost < best.0 {
            best = (cost, d);
        }
    }
    best.1
}

/// Exposure after the gains: one factor s = 1 / pct(max_c g_c J_c, 0.99)
/// over the masked-in pixels, then clipping to [0, 1] (METHOD §13.4).
fn expose(radiance: &[f32], gains: &[f32; 3], inside: &dyn Fn(usize) -> bool) -> Vec<f32> {
    let g = |px: &[f32], c: usize| px.get(c).copied().unwrap_or(0.0) * gains.get(c).copied().unwrap_or(1.0);
    let mut tops: Vec<f32> = radiance
        .chunks_exact(3)
        .enumerate()
        .filter(|(i, _)| inside(*i))
        .map(|(_, px)| g(px, 0).max(g(px, 1)).max(g(px, 2)))
        .collect();
    let top = if tops.is_empty() {
        0.0
    } else {
        let k = ((tops.len() - 1) as f64 * 0.99).round() as usize;
        *tops.select_nth_unstable_by(k, f32::total_cmp).1
    };
    let s = if top > 0.0 { 1.0 / top } else { 1.0 };
    radiance.chunks_exact(3).flat_map(|px| (0..3).map(move |c| (g(px, c) * s).clamp(0.0, 1.0))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_neighbour_resize_keeps_values_and_refuses_another_aspect() {
        // 2x2 -> 4x4: each value becomes a 2x2 block
        let z = [1.0, 2.0, 3.0, f32::NAN];
        let r = resize_distance(&z, 2, 2, 4, 4).unwrap();
        assert_eq!(&r[..4], &[1.0, 1.0, 2.0, 2.0]);
        assert_eq!(&r[8..10], &[3.0, 3.0]);
        assert!(r[10].is_nan());
        assert!(r[15].is_nan());
        assert!(resize_distance(&z, 2, 2, 4, 6).is_err());
        assert!(resize_distance(&z, 2, 3, 4, 6).is_err());
    }

    #[test]
    fn holes_take_the_nearest_known_distance() {
        // 1 x 5: [2, nan, nan, nan, 8] -> [2, 2, 2?, 8, 8]: the middle one is
        // reached first from the left (raster order of the queue)
        let z = [2.0, f32::NAN, f32::NAN, f32::NAN, 8.0];
        assert_eq!(fill_nearest(&z, 1, 5).unwrap(), vec![2.0, 2.0, 2.0, 8.0, 8.0]);
        // 3 x 3 with only the centre known: everything becomes it
        let mut z = [f32::NAN; 9];
        z[4] = 5.0;
        assert!(fill_nearest(&z, 3, 3).unwrap().iter().all(|&v| v == 5.0));
        assert!(fill_nearest(&[f32::NAN, 0.0, -1.0], 1, 3).is_none());
    }

    #[test]
    fn the_light_path_undoes_a_known_tint() {
        // a gray scene lit through d = 4 m of water: E_c = e^(-beta_c 4);
        // the search finds d = 4 (gains e^(beta_c d) make it gray again)
        let beta = [0.4f32, 0.1, 0.05];
        let mut rad = Vec::new();
        for i in 0..700 {
            let v = 0.2 + 0.6 * (i % 10) as f32 / 10.0;
            rad.extend((0..3).map(|c| v * (-beta[c] * 4.0).exp()));
        }
        let d = light_path(&rad, &|_| true, beta);
        assert!((d - 4.0).abs() < 1e-9, "{d}");
        // white light on a gray scene: no path
        let gray: Vec<f32> = (0..2100).map(|i| 0.1 + (i / 3 % 9) as f32 * 0.1).collect();
        assert_eq!(light_path(&gray, &|_| true, beta), 0.0);
    }
}
