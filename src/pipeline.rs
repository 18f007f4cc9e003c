//! Orchestration (SPEC 2-10): per-image work once (validation, veiling
//! light and water region, Mahalanobis weights, guide statistics), per-type
//! work in parallel, the chosen type recomputed once to produce the outputs
//! (so no per-type full-resolution image is kept).

use crate::error::{Error, Result};
use crate::filters::components8;
use crate::guided::GuideStats;
use crate::hazelines::initial_transmission;
use crate::image::{check_mask, ImageRef};
use crate::matting::{lower_bound_px, mahalanobis_sq, matting_weights};
use crate::recover::{channel_t, display_stretch, recover};
use crate::select::{choose, type_stats, TypeStats, FLAG_RELAXED};
use crate::sphere::SphereIndex;
use crate::util::{masked_channel, normalize_masked, percentiles, stretch_channels, with_threads};
use crate::veiling::{estimate, Veiling};
use crate::water::{jerlov_types, validate_types, WaterType};
use rayon::prelude::*;

/// Default guided-filter regulariser (SPEC 6).
pub const DEFAULT_EPS: f64 = 1e-3;
/// Default number of haze-line clusters (SPEC 4.3).
pub const DEFAULT_SPHERE_POINTS: usize = 500;
/// Default working-memory limit: 16 GiB.
pub const DEFAULT_MAX_MEMORY: u64 = 16 << 30;

/// Parameters of [`restore`]; `Default` gives SPEC.md's defaults.
#[derive(Debug, Clone)]
pub struct Params {
    /// candidate water types (SPEC 1); default: the ten Jerlov types
    pub water_types: Vec<WaterType>,
    /// a given veiling light A (each component in (0, 1]); default: estimated (SPEC 3)
    pub veiling_light: Option<[f32; 3]>,
    /// guided-filter radius; default round(min(H, W) / 4) (SPEC 6)
    pub guided_radius: Option<usize>,
    /// guided-filter eps, > 0; default 1e-3 (SPEC 6)
    pub guided_eps: f64,
    /// number of haze-line clusters; default 500 (SPEC 4.3)
    pub sphere_points: usize,
    /// worker threads; None = rayon's global pool (all cores)
    pub threads: Option<usize>,
    /// working-memory limit in bytes, checked before anything large is allocated
    pub max_memory: u64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            water_types: jerlov_types(),
            veiling_light: None,
            guided_radius: None,
            guided_eps: DEFAULT_EPS,
            sphere_points: DEFAULT_SPHERE_POINTS,
            threads: None,
            max_memory: DEFAULT_MAX_MEMORY,
        }
    }
}

/// The image and its optional masks.
#[derive(Debug, Clone, Copy)]
pub struct Input<'a> {
    /// linear RGB in [0, 1]
    pub image: ImageRef<'a>,
    /// true = use the pixel for estimation (SPEC 2); false e.g. on color charts
    pub mask: Option<&'a [bool]>,
    /// a given water region VL, used instead of detection (SPEC 3)
    pub water_mask: Option<&'a [bool]>,
}

/// Everything [`restore`] returns (SPEC 10).
#[derive(Debug, Clone)]
pub struct Restoration {
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// the white-balanced, display-stretched result of the chosen type (SPEC 8), interleaved RGB
    pub image: Vec<f32>,
    /// J after the artifact clamp, before the stretch (SPEC 7), interleaved RGB
    pub radiance: Vec<f32>,
    /// t_B of the chosen type (SPEC 7); -ln t_B = beta_B z
    pub transmission: Vec<f32>,
    /// the chosen water type
    pub water_type: WaterType,
    /// every evaluated type with its gray-world score, in input order (SPEC 9)
    pub scores: Vec<(String, f64)>,
    /// names of the types excluded by the t_R rule (SPEC 9)
    pub excluded: Vec<String>,
    /// the veiling light A used
    pub veiling_light: [f32; 3],
    /// the water region VL (all false when there is none)
    pub veiling_mask: Vec<bool>,
    /// documented fallbacks that were used
    pub flags: Vec<String>,
    /// the guided-filter radius used
    pub guided_radius: usize,
}

impl Restoration {
    /// Per-channel transmission maps (t_R, t_G, t_B) of the chosen type (SPEC 7).
    pub fn channel_transmissions(&self) -> [Vec<f32>; 3] {
        channel_transmissions(&self.transmission, &self.water_type)
    }
}

/// Per-channel transmission maps (t_R, t_G, t_B) from a clamped t_B (SPEC 7).
pub fn channel_transmissions(t_b: &[f32], wt: &WaterType) -> [Vec<f32>; 3] {
    let per: Vec<[f32; 3]> = t_b.par_iter().map(|&t| channel_t(t, wt)).collect();
    [0, 1, 2].map(|c| per.iter().map(|v| v[c]).collect())
}

/// Default guided-filter radius: round(min(H, W) / 4), halves away from zero (SPEC 6).
pub fn default_radius(h: usize, w: usize) -> usize {
    (h.min(w) as f64 / 4.0).round() as usize
}

/// Working memory of [`restore`] in bytes, estimated from the image size and
/// the number of types evaluated at once (documented in the README):
/// per pixel 4 B x (3 guide + 9 guide statistics + 1 matting weight + 3 + 3
/// + 1 + 1 outputs) for the image-wide buffers, plus for each type in flight
/// 4 B x 16 planes and one 8 B box-filter accumulator.
pub fn memory_estimate(h: usize, w: usize, in_flight: usize) -> u64 {
    let n = (h as u64).saturating_mul(w as u64);
    let per_image = 4 * (3 + 9 + 1 + 3 + 3 + 1 + 1) + 1;
    let per_type = 4 * 16 + 8;
    n.saturating_mul(per_image + per_type * in_flight.max(1) as u64)
}

/// The contrast stretch of SPEC 3.1 (DECISIONS S3.1): global min-max, then
/// per channel between its 1% and 99% percentiles, clipped to [0, 1].
/// Statistics over masked-in pixels (all without a mask), applied to all.
pub fn stretch_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let x = normalize_masked(data, mask);
    let limits = [0, 1, 2].map(|c| {
        let p = percentiles(masked_channel(&x, c, mask), &[0.01, 0.99]);
        (p[1] - p[0] > 1e-12).then_some((p[0], p[1]))
    });
    stretch_channels(&x, limits)
}

/// The guide of SPEC 6: the stretched input raised to 1/2.2, 0 on masked-out pixels.
pub fn guide_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let mut g = stretch_image(data, mask);
    g.par_chunks_mut(3).enumerate().for_each(|(i, px)| {
        if mask.is_some_and(|m| !m[i]) {
            px.iter_mut().for_each(|v| *v = 0.0);
        } else {
            px.iter_mut().for_each(|v| *v = v.powf(1.0 / 2.2));
        }
    });
    g
}

/// Gives each masked-out region (8-connected) one value: the mean of `q`
/// over the masked-in pixels directly below it; if none, directly above; if
/// none, its masked-in 8-neighbours (SPEC 6, DECISIONS S6).
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
                if mask[j] {
                    pairs.push((l, j));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut sum = vec![0f64; nl];
        let mut cnt = vec![0f64; nl];
        for (l, j) in pairs {
            sum[l as usize - 1] += q[j] as f64;
            cnt[l as usize - 1] += 1.0;
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
                .find(|(_, c)| c[k] > 0.0)
                .map(|(s, c)| (s[k] / c[k]) as f32)
        })
        .collect();
    q.par_iter_mut().zip(labels.par_iter()).for_each(|(v, &l)| {
        if l > 0 {
            if let Some(x) = value[l as usize - 1] {
                *v = x;
            }
        }
    });
}

/// Per-image state shared by every water type.
struct Shared<'a> {
    input: Input<'a>,
    veil: Veiling,
    weights: Option<Vec<f32>>,
    guide: GuideStats,
    index: SphereIndex,
    has_holes: bool,
}

impl Shared<'_> {
    /// The refined transmission of one type (SPEC 4-6).
    fn refined(&self, wt: &WaterType) -> Vec<f32> {
        let img = &self.input.image;
        let a = self.veil.a;
        let mut t = initial_transmission(img, a, wt, &self.index, self.input.mask);
        let weights = self.weights.as_deref();
        t.par_iter_mut().enumerate().for_each(|(i, v)| {
            let lb = lower_bound_px(img.px(i), a, wt);
            let tt = v.max(lb);
            *v = match weights {
                Some(w) => w[i] * lb + (1.0 - w[i]) * tt,
                None => tt,
            };
        });
        let mut q = self.guide.filter(&t);
        if self.has_holes {
            if let Some(m) = self.input.mask {
                chart_fill(&mut q, m, img.height, img.width);
            }
        }
        q
    }

    /// Selection statistics of one type (SPEC 7-9).
    fn stats(&self, wt: &WaterType) -> TypeStats {
        let q = self.refined(wt);
        let (j, tb) = recover(&self.input.image, self.veil.a, &q, wt, self.input.mask);
        let s = display_stretch(&j, self.input.mask);
        let tr: Vec<f32> = tb.par_iter().map(|&t| channel_t(t, wt)[0]).collect();
        type_stats(
            &s,
            &tr,
            &self.veil.vl,
            self.input.mask,
            self.input.image.width,
        )
    }
}

/// The whole method (SPEC 2-10) on one image.
pub fn restore(input: &Input, params: &Params) -> Result<Restoration> {
    with_threads(params.threads, || restore_inner(input, params))?
}

fn check_params(input: &Input, params: &Params) -> Result<()> {
    let img = &input.image;
    validate_types(&params.water_types)?;
    if !(params.guided_eps.is_finite() && params.guided_eps > 0.0) {
        return Err(Error::Param {
            name: "guided_eps",
            msg: format!("{} is not a finite number > 0", params.guided_eps),
        });
    }
    if let Some(a) = params.veiling_light {
        if a.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 1.0)) {
            return Err(Error::Param {
                name: "veiling_light",
                msg: format!("{a:?}: every component must be a finite number in (0, 1]"),
            });
        }
    }
    if let Some(r) = params.guided_radius {
        if r > img.height.max(img.width) {
            return Err(Error::Param {
                name: "guided_radius",
                msg: format!(
                    "{r} is larger than the image ({}x{})",
                    img.height, img.width
                ),
            });
        }
    }
    check_mask("mask", input.mask, img.len(), 1)?;
    check_mask("water_mask", input.water_mask, img.len(), 0)?;
    let in_flight = params
        .threads
        .unwrap_or_else(rayon::current_num_threads)
        .min(params.water_types.len());
    let needed = memory_estimate(img.height, img.width, in_flight);
    if needed > params.max_memory {
        return Err(Error::Memory {
            height: img.height,
            width: img.width,
            needed,
            limit: params.max_memory,
        });
    }
    Ok(())
}

fn restore_inner(input: &Input, params: &Params) -> Result<Restoration> {
    check_params(input, params)?;
    let img = &input.image;
    img.validate_values()?;
    let (h, w) = (img.height, img.width);
    let index = SphereIndex::new(params.sphere_points)?;
    let veil = estimate(img, input.mask, input.water_mask, params.veiling_light);
    let usable = input
        .mask
        .map_or(img.len(), |m| m.iter().filter(|&&b| b).count());
    if veil.vl_count >= usable {
        return Err(Error::Mask {
            name: "water_mask",
            msg: "covers every pixel used for estimation: no object pixels are left to choose the water type".into(),
        });
    }
    let weights = if veil.vl_count > 0 {
        mahalanobis_sq(img, &veil.vl).map(|d| matting_weights(&d, &veil.vl, w))
    } else {
        None
    };
    let radius = params.guided_radius.unwrap_or_else(|| default_radius(h, w));
    let guide = GuideStats::new(
        guide_image(img.data, input.mask),
        h,
        w,
        radius,
        params.guided_eps,
    );
    let has_holes = input.mask.is_some_and(|m| m.iter().any(|&b| !b));
    let shared = Shared {
        input: *input,
        veil,
        weights,
        guide,
        index,
        has_holes,
    };

    let stats: Vec<TypeStats> = params
        .water_types
        .par_iter()
        .map(|wt| shared.stats(wt))
        .collect();
    let choice = choose(&stats);
    let wt = params
        .water_types
        .get(choice.winner)
        .ok_or_else(|| Error::Internal("winner out of range".into()))?
        .clone();
    let q = shared.refined(&wt);
    let (radiance, transmission) = recover(img, shared.veil.a, &q, &wt, input.mask);
    let image = display_stretch(&radiance, input.mask);

    let mut flags: Vec<String> = shared.veil.flags.iter().map(|s| s.to_string()).collect();
    if choice.relaxed {
        flags.push(FLAG_RELAXED.to_string());
    }
    if shared.veil.vl_count > 0 && shared.weights.is_none() {
        flags.push("matting_skipped".to_string());
    }
    Ok(Restoration {
        height: h,
        width: w,
        image,
        radiance,
        transmission,
        scores: params
            .water_types
            .iter()
            .zip(&stats)
            .map(|(t, s)| (t.name.clone(), s.score))
            .collect(),
        excluded: params
            .water_types
            .iter()
            .zip(&choice.excluded)
            .filter(|(_, &e)| e)
            .map(|(t, _)| t.name.clone())
            .collect(),
        water_type: wt,
        veiling_light: shared.veil.a,
        veiling_mask: shared.veil.vl,
        flags,
        guided_radius: radius,
    })
}
