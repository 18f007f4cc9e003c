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
use crate::method::params::{check_params, Flag, Input, Params, Restoration, Stage};
use crate::method::profile::Fallback;
use crate::method::veiling::estimate;
use crate::method::water::WaterType;

/// Fewer known object pixels than this share of the image leave too little
/// to fit the water with.
pub const MIN_COVERAGE: f32 = 0.05;

/// The smallest transmission a channel is divided by (METHOD §13.3).
pub const MIN_T: f32 = 0.05;

/// The longest light path (metres of the fitted water) the display's tint
/// may remove (METHOD §13.4); the shortest is 0 (white light).
pub const PATH_MAX: f64 = 15.0;

/// The longer side at which the haze-lines are run to check the map's
/// order of near and far against the photo's own haze (METHOD §13.1).
pub const ORDER_SIDE: usize = 160;

/// A map whose rank correlation with the haze-line optical depth
/// -ln t_B is below this orders near and far the other way round from the
/// photo's haze: not used (METHOD §13.1).
pub const MIN_HAZE_ORDER: f64 = -0.5;

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
    /// the rank correlation of the map with the haze-lines' -ln t_B at
    /// [`ORDER_SIDE`] (METHOD §13.1); None when not checked
    pub haze_order: Option<f32>,
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
    // §2: the photo and the parameters are refused as they are without a
    // distance (the map may be rejected and the method run on them)
    check_params(input, params)?;
    img.validate_values()?;
    if params.veiling_light.is_some() {
        return Err(Error::Param {
            name: "veiling_light",
            msg: "A is fitted from the distance map with the attenuation: give one or the other".into(),
        });
    }
    if let Some(wm) = input.water_mask {
        let inside = |i: usize| input.mask.is_none_or(|m| m.get(i).copied().unwrap_or(false));
        super::objects_left(input, wm.iter().enumerate().filter(|&(i, &w)| w && inside(i)).count())?;
    }
    let rejected = |why: String, coverage: f32, fit: Option<WaterFit>, haze_order: Option<f32>| -> Result<Restoration> {
        let mut res = super::restore(input, params)?;
        res.flags.push(Flag::DistanceRejected);
        res.distance = Some(DistanceUse { coverage, fit, nearest: None, rejected: Some(why), light_path: None, haze_order });
        Ok(res)
    };
    let z = match resize_distance(distance, zh, zw, img.height, img.width) {
        Ok(z) => z,
        Err(Error::Distance(why)) => return rejected(why, 0.0, None, None),
        Err(e) => return Err(e),
    };
    let coverage = z.iter().filter(|&&v| known(v)).count() as f32 / img.len().max(1) as f32;
    if coverage < MIN_COVERAGE {
        return rejected(format!("only {:.1}% of the pixels have a known distance", 100.0 * coverage), coverage, None, None);
    }
    let fit = match fit_water(img.data, img.height, img.width, &z, input.mask) {
        Ok(f) if f.suspect() => {
            let why = format!(
                "the photo does not follow its distance map (residual {:.3}): another photo's map, other units, or too little water between near and far",
                f.residual
            );
            return rejected(why, coverage, Some(f), None);
        }
        Ok(f) if f.at_grid_end() => {
            let why = format!(
                "the fit's blue attenuation, {:.4} 1/m, is at the end of what it searches ({} to {} 1/m): \
                 the distances are likely in other units than metres (centimetres or millimetres as metres, \
                 or a reconstruction's own scale)",
                f.beta[2],
                crate::method::distance::BETA_MIN,
                crate::method::distance::BETA_MAX
            );
            return rejected(why, coverage, Some(f), None);
        }
        Ok(f) => f,
        Err(why) => return rejected(why, coverage, None, None),
    };
    // §13.1: a map flipped or rotated against the photo, or disparity given
    // as distance, orders near and far against the photo's own haze
    let haze_order = haze_order(input, &z);
    if let Some(rho) = haze_order.filter(|&r| r < MIN_HAZE_ORDER) {
        let why = format!(
            "the map orders near and far against the photo's own haze (rank correlation {rho:.2} with the haze-lines' \
             optical depth): a map flipped or rotated against the photo, disparity given as distance, or another photo's map"
        );
        return rejected(why, coverage, Some(fit), Some(rho as f32));
    }
    let haze_order = haze_order.map(|r| r as f32);
    let Some(filled) = fill_nearest(&z, img.height, img.width) else {
        return rejected("no pixel has a known distance".into(), coverage, None, haze_order);
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
            for (((o, &p), &beta), &ac) in j.iter_mut().zip(px).zip(&fit.beta).zip(&a) {
                let t = (-beta * zv).exp().max(MIN_T);
                *o = ac + (p - ac) / t;
            }
        });
    // J below 0 (noise over a far, dark pixel) is clipped; no artifact
    // clamp of §7: its shift by min J adds gray to every pixel, and with the
    // distance known there is no haze-line artifact to hide (METHOD §13.3)
    radiance.par_iter_mut().for_each(|v| *v = v.max(0.0));
    let inside = |i: usize| input.mask.is_none_or(|m| m.get(i).copied().unwrap_or(false));
    // §13.4: the tint of light that crossed the same water, then exposure
    let objects = |i: usize| inside(i) && known(z.get(i).copied().unwrap_or(f32::NAN)) && !veil.vl.get(i).copied().unwrap_or(false);
    let d = light_path(&radiance, img.height, img.width, &objects, fit.beta);
    let gains: [f32; 3] = fit.beta.map(|b| (f64::from(b) * d).exp() as f32);
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
    flags.extend(tr.iter().flat_map(|t| t.flags()));
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
        fallback_share: None,
        distance: Some(DistanceUse {
            coverage,
            nearest: Some((name.to_string(), how_far)),
            fit: Some(fit),
            rejected: None,
            light_path: Some(d as f32),
            haze_order,
        }),
        guided_radius: 0,
        guided_subsample: 1,
        timings,
    })
}

/// METHOD §13.1: Spearman's rank correlation between the distance `z`
/// (the image's size) and the optical depth -ln t_B of the default profile
/// run on the photo shrunk by block means to at most [`ORDER_SIDE`] pixels
/// on its longer side (a block's z: the mean of its known distances when at
/// least half are known; blocks mostly in a given water region, or in the
/// water region the method finds on the copy, are left out: their t is not
/// a distance's). The haze-lines' t_B is often wrong in scale but
/// rarely in the order of near and far (rho 0.4-0.99 against the true map on
/// the renders of benches/truth.py). None when the small photo cannot be
/// restored or fewer than 64 blocks have a distance.
pub fn haze_order(input: &Input, z: &[f32]) -> Option<f64> {
    let img = &input.image;
    let (h, w) = (img.height, img.width);
    let f = h.max(w).div_ceil(ORDER_SIDE).max(1);
    let (small, cnt, hs, ws) = block_means(img.data, h, w, f);
    let (zsum, zcnt) = block_sums(h, w, f, |i| z.get(i).copied().filter(|&v| known(v)).map(f64::from));
    let holds = |m: &[bool]| block_sums(h, w, f, |i| m.get(i).copied().unwrap_or(false).then_some(0.0)).1;
    let half = |v: &[usize]| -> Vec<bool> { v.iter().zip(&cnt).map(|(&a, &c)| 2 * a >= c.max(1)).collect() };
    let mask = input.mask.map(|m| half(&holds(m)));
    let water = input.water_mask.map(holds);
    let image = crate::method::image::ImageRef::new(&small, hs, ws).ok()?;
    // the method finds the water itself: a water mask given for the photo
    // only leaves its blocks out below (a wrong one would set A, and every t)
    let res = super::restore(&Input { image, mask: mask.as_deref(), water_mask: None }, &Params::default()).ok()?;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (blk, (&c, (&s, &k))) in cnt.iter().zip(zsum.iter().zip(&zcnt)).enumerate() {
        let inm = mask.as_ref().is_none_or(|m| m.get(blk).copied().unwrap_or(false));
        let wet = water.as_ref().is_some_and(|v| 2 * v.get(blk).copied().unwrap_or(0) >= c)
            || res.veiling_mask.get(blk).copied().unwrap_or(false);
        if k > 0 && 2 * k >= c && inm && !wet {
            if let Some(&t) = res.transmission.get(blk) {
                a.push(-f64::from(t.max(1e-6)).ln());
                b.push(s / k as f64);
            }
        }
    }
    if a.len() < 64 {
        return None;
    }
    Some(spearman(&a, &b))
}

/// Block means (factor `f`) of the RGB image `rgb` of `h` x `w` pixels,
/// over every pixel of each block (f64 sums in raster order), and each
/// block's pixel count. Returns (means, counts, height, width).
fn block_means(rgb: &[f32], h: usize, w: usize, f: usize) -> (Vec<f32>, Vec<usize>, usize, usize) {
    let (hs, ws) = (h.div_ceil(f), w.div_ceil(f));
    let mut acc = vec![0f64; hs * ws * 3];
    let mut all = vec![0usize; hs * ws];
    for (i, px) in rgb.chunks_exact(3).enumerate().take(h * w) {
        let k = (i / w / f) * ws + (i % w) / f;
        if let (Some(a), Some(n)) = (acc.get_mut(3 * k..3 * k + 3), all.get_mut(k)) {
            for (d, &v) in a.iter_mut().zip(px.iter()) {
                *d += f64::from(v);
            }
            *n += 1;
        }
    }
    let means = acc
        .chunks_exact(3)
        .zip(all.iter())
        .flat_map(|(a, &n)| a.iter().map(move |&v| if n > 0 { (v / n as f64) as f32 } else { 0.0 }))
        .collect();
    (means, all, hs, ws)
}

/// Per block (factor `f`) of an `h` x `w` image: the sum of `value(i)`
/// over its pixels where it is `Some`, and how many those are.
fn block_sums(h: usize, w: usize, f: usize, value: impl Fn(usize) -> Option<f64>) -> (Vec<f64>, Vec<usize>) {
    let ws = w.div_ceil(f);
    let n = h.div_ceil(f) * ws;
    let (mut sums, mut counts) = (vec![0f64; n], vec![0usize; n]);
    for i in 0..h * w {
        let k = (i / w / f) * ws + (i % w) / f;
        if let (Some(v), Some(s), Some(c)) = (value(i), sums.get_mut(k), counts.get_mut(k)) {
            *s += v;
            *c += 1;
        }
    }
    (sums, counts)
}

/// Ranks of `v` from 1, ties given their mean rank.
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<(f64, usize)> = v.iter().copied().zip(0..).collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut r = vec![0f64; v.len()];
    let mut start = 0usize;
    for run in order.chunk_by(|a, b| a.0 == b.0) {
        // ranks start + 1 ..= start + len share their mean
        let mean = start as f64 + (run.len() as f64 + 1.0) / 2.0;
        for &(_, i) in run {
            if let Some(o) = r.get_mut(i) {
                *o = mean;
            }
        }
        start += run.len();
    }
    r
}

/// Spearman's rank correlation of two equally long samples (Pearson's on
/// their ranks, ties averaged); 0 when either is constant.
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let (ra, rb) = (ranks(a), ranks(b));
    let n = ra.len().min(rb.len()) as f64;
    if n < 2.0 {
        return 0.0;
    }
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
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

/// Every 3rd object pixel (in raster order) is enough for the colour
/// estimates of [`light_path`].
const SAMPLE: usize = 3;
/// The percentile of each channel taken as the white patch (METHOD §13.4).
const WHITE_PATCH: f64 = 0.99;
/// Radius of the box that smooths the radiance before its gradients (noise,
/// magnified by 1/t, would otherwise be the edges).
const EDGE_BOX: usize = 2;
/// Gray edge or white patch replaces gray world only when its residual is
/// below this share of gray world's: the mean has the most pixels behind it
/// and the least noise (METHOD §13.4: on tune, gray scenes under white
/// light 7.7 degrees with a plain minimum, 6.9 with 0.5 to 0.7, the other
/// conditions unchanged).
const GRAY_WORLD_MARGIN: f64 = 0.5;

/// METHOD §13.4: the light path d (metres of the fitted water) whose gains
/// g_c = e^(beta_c d) remove the tint of the light on the scene.
///
/// Three colour estimates of the light, each from an assumption about the
/// scene: gray world (mean of J), gray edge (mean gradient magnitude of J
/// smoothed by a 5 x 5 box) and white patch (99th percentile of each
/// channel), over every 3rd object pixel of J block-averaged to at most
/// `FIT_SIDE` px. Each is projected onto the family a light through this
/// water can give: in log chromaticity l_c = ln e_c - mean, the d that
/// makes l + d beta~ (beta~ = beta - mean beta) smallest in the least-squares
/// sense, d = -<l, beta~> / <beta~, beta~>, and the residual r = |l + d beta~|.
/// The estimate with the smallest residual is used (its d clamped to
/// [0, `PATH_MAX`]), gray world's residual first multiplied by
/// `GRAY_WORLD_MARGIN`: an estimate that a light of this water can make
/// neutral is credible, one that no such light can has been coloured by
/// the scene. Ties go to the earlier of gray world, gray edge, white patch.
pub fn light_path(radiance: &[f32], h: usize, w: usize, objects: &dyn Fn(usize) -> bool, beta: [f32; 3]) -> f64 {
    let b: [f64; 3] = beta.map(f64::from);
    let bm = (b[0] + b[1] + b[2]) / 3.0;
    let bt = b.map(|v| v - bm);
    let bb: f64 = bt.iter().map(|v| v * v).sum();
    if bb <= 1e-18 || h == 0 || w == 0 {
        return 0.0;
    }
    // block means (the fit's working size) and which blocks are objects
    let f = h.max(w).div_ceil(crate::method::distance::FIT_SIDE).max(1);
    let (small, all, hs, ws) = block_means(radiance, h, w, f);
    let obj = block_sums(h, w, f, |i| objects(i).then_some(0.0)).1;
    let k = vec![1.0 / (2 * EDGE_BOX + 1) as f64; 2 * EDGE_BOX + 1];
    let smooth = crate::kernels::filters::convolve_separable(&small, hs, ws, 3, &k);
    let at = |y: usize, x: usize, c: usize| f64::from(smooth.get((y * ws + x) * 3 + c).copied().unwrap_or(0.0));
    let mut sum = [0f64; 3];
    let mut edge = [0f64; 3];
    let mut vals: [Vec<f64>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    let mut seen = 0usize;
    for y in 0..hs {
        for x in 0..ws {
            let i = y * ws + x;
            let (n, o) = (all.get(i).copied().unwrap_or(0), obj.get(i).copied().unwrap_or(0));
            if o == 0 || 2 * o < n {
                continue;
            }
            seen += 1;
            if !(seen - 1).is_multiple_of(SAMPLE) {
                continue;
            }
            for c in 0..3 {
                let v = f64::from(small.get(3 * i + c).copied().unwrap_or(0.0));
                // central differences inside, 0 on the border rows and columns
                let gy = if y > 0 && y + 1 < hs { (at(y + 1, x, c) - at(y - 1, x, c)) / 2.0 } else { 0.0 };
                let gx = if x > 0 && x + 1 < ws { (at(y, x + 1, c) - at(y, x - 1, c)) / 2.0 } else { 0.0 };
                if let (Some(s), Some(e), Some(l)) = (sum.get_mut(c), edge.get_mut(c), vals.get_mut(c)) {
                    *s += v;
                    *e += gy.hypot(gx);
                    l.push(v);
                }
            }
        }
    }
    let n = vals[0].len();
    if n == 0 {
        return 0.0;
    }
    let white: [f64; 3] = std::array::from_fn(|c| {
        let l = vals.get_mut(c).map(std::mem::take).unwrap_or_default();
        percentile(l, WHITE_PATCH)
    });
    let estimates = [sum.map(|v| v / n as f64), edge.map(|v| v / n as f64), white];
    let mut best = (f64::INFINITY, 0.0);
    for (k, e) in estimates.into_iter().enumerate() {
        let l = e.map(|v| v.max(1e-12).ln());
        let lm = (l[0] + l[1] + l[2]) / 3.0;
        let l = l.map(|v| v - lm);
        let d = -(l[0] * bt[0] + l[1] * bt[1] + l[2] * bt[2]) / bb;
        let r = l.iter().zip(bt.iter()).map(|(lc, bc)| (lc + d * bc).powi(2)).sum::<f64>().sqrt();
        let r = if k == 0 { r * GRAY_WORLD_MARGIN } else { r };
        if r < best.0 {
            best = (r, d);
        }
    }
    best.1.clamp(0.0, PATH_MAX)
}

/// The q-quantile of `v` with linear interpolation between order statistics
/// (as NumPy's default); 0 for an empty list.
fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let pos = q * (v.len() - 1) as f64;
    let i = pos.floor() as usize;
    let f = pos - i as f64;
    match (v.get(i), v.get(i + 1)) {
        (Some(a), Some(b)) => a + (b - a) * f,
        (Some(a), None) => *a,
        _ => 0.0,
    }
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
    fn spearman_of_hand_computed_cases() {
        let up = [1.0, 2.0, 3.0, 4.0];
        assert!((spearman(&up, &[10.0, 20.0, 30.0, 45.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&up, &[9.0, 7.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        // ties share their mean rank: ranks (1, 2.5, 2.5, 4) against (1, 2, 3, 4),
        // deviations (-1.5, 0, 0, 1.5) and (-1.5, -0.5, 0.5, 1.5): 4.5 / sqrt(4.5 x 5)
        let r = spearman(&[1.0, 2.0, 2.0, 3.0], &up);
        assert!((r - 4.5 / (4.5f64 * 5.0).sqrt()).abs() < 1e-12, "{r}");
        // a monotone but non-linear map keeps rank correlation 1
        assert!((spearman(&up, &up.map(|v: f64| v.exp())) - 1.0).abs() < 1e-12);
        assert_eq!(spearman(&up, &[2.0; 4]), 0.0);
        assert_eq!(spearman(&[1.0], &[1.0]), 0.0);
    }

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

    /// A 60 x 90 scene of 6 x 6 patches, patch k coloured `colour(k)`, lit
    /// through `d` m of water `beta` (E_c = e^(-beta_c d)).
    fn lit_patches(beta: [f32; 3], d: f32, colour: &dyn Fn(usize) -> [f32; 3]) -> Vec<f32> {
        let (h, w) = (60, 90);
        let mut rad = Vec::with_capacity(h * w * 3);
        for y in 0..h {
            for x in 0..w {
                let j = colour((y / 6) * 15 + x / 6);
                rad.extend((0..3).map(|c| j[c] * (-beta[c] * d).exp()));
            }
        }
        rad
    }

    #[test]
    fn the_light_path_undoes_a_known_tint() {
        // a gray scene lit through d = 4 m of water: every estimate (mean,
        // edges, brightest) is the light's colour, on the water's family, and
        // gains e^(beta_c 4) make it gray again
        let beta = [0.4f32, 0.1, 0.05];
        let gray = |k: usize| [0.1 + 0.08 * (k % 10) as f32; 3];
        let d = light_path(&lit_patches(beta, 4.0, &gray), 60, 90, &|_| true, beta);
        assert!((d - 4.0).abs() < 1e-3, "{d}");
        // white light on a gray scene: no path
        let d = light_path(&lit_patches(beta, 0.0, &gray), 60, 90, &|_| true, beta);
        assert!(d.abs() < 1e-3, "{d}");
    }

    #[test]
    fn an_orange_scene_with_white_patches_keeps_its_colour() {
        // mostly orange (0.8, 0.4, 0.1) x level, one patch in ten white: the
        // mean is orange, which no light of this water makes neutral (by hand:
        // its log chromaticity projects to d = -4.7 with residual 0.82), while
        // the brightest pixels, the white patches, are the light itself. So
        // under a light through 4 m the path is 4 m (gray world alone: 0), and
        // under white light 0 m.
        let beta = [0.4f32, 0.1, 0.05];
        let scene = |k: usize| {
            if k % 10 == 3 {
                [0.9; 3]
            } else {
                let v = 0.3 + 0.05 * (k % 7) as f32;
                [0.8 * v, 0.4 * v, 0.1 * v]
            }
        };
        let d = light_path(&lit_patches(beta, 4.0, &scene), 60, 90, &|_| true, beta);
        assert!((d - 4.0).abs() < 1e-3, "{d}");
        let d = light_path(&lit_patches(beta, 0.0, &scene), 60, 90, &|_| true, beta);
        assert!(d.abs() < 1e-3, "{d}");
        // without the white patches nothing in the photo tells an orange scene
        // under that light from a redder-than-orange one under white light:
        // every estimate projects to 4 - 4.7 m, clamped to white light (the
        // limit of METHOD §13.4)
        let orange = |k: usize| scene(10 * k + 1);
        let d = light_path(&lit_patches(beta, 4.0, &orange), 60, 90, &|_| true, beta);
        assert_eq!(d, 0.0);
    }
}
