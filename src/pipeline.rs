//! Orchestration (METHOD §2-10): per-image work once (validation, veiling
//! light and water region, the Mahalanobis matting model, guide
//! statistics), then the water types one after another, each with every
//! pass parallel over rows, and the chosen type computed once more to
//! produce the outputs. Per type only three buffers exist (the refined
//! transmission / J, the guided filter's (a, b), and with an estimation
//! mask the filtered plane); no per-type full-resolution image is kept.
//!
//! Selection needs from each type only sums over pixels (METHOD §9) and the
//! display stretch's limits, which come from order statistics of J before
//! the artifact clamp: the clamp and the normalisation are non-decreasing
//! maps, so they commute with ranking ([`crate::rank`]).

use crate::error::{Error, Result};
use crate::filters::components8;
use crate::guided::GuideStats;
use crate::hazelines::{fill_masked, haze_pass, t_tilde, HazeType, CHUNK_ROWS, T_MIN, T_SCALE};
use crate::image::{check_mask, ImageRef};
use crate::matting::Matting;
use crate::options::{DEFAULT_EPS, DEFAULT_MAX_MEMORY, DEFAULT_SPHERE_POINTS};
use crate::recover::{display_limits, recover_values, ArtifactClamp, Recovery, DISPLAY_QS};
use crate::select::{choose, Choice, SelectionSums, TypeStats, FLAG_RELAXED};
use crate::sphere::SphereIndex;
use crate::util::{channel_percentiles, with_threads, ChannelStretch, Normalize};
use crate::veiling::{estimate, Veiling};
use crate::water::{jerlov_types, validate_types, WaterType};
use rayon::prelude::*;
use std::ops::Range;

/// Longer side (about) of the copy on which [`Selection::Fast`] scores the types.
pub const FAST_SIDE: usize = 1024;
/// How many of the copy's best-scoring surviving types [`Selection::Fast`]
/// scores again at full resolution before choosing.
pub const FAST_RESCORE: usize = 3;

/// How the water type is chosen (METHOD §9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Selection {
    /// Every candidate type is restored at full resolution and scored
    /// (METHOD §9 as written).
    #[default]
    Exhaustive,
    /// The types are scored on a copy whose longer side is about
    /// [`FAST_SIDE`]: one pixel (the centre) of every s x s block, s =
    /// ceil(max(H, W) / 1024), with its water region and mask, and the
    /// full-resolution veiling light. Where the copy's choice (METHOD §9 on
    /// the copy) is uncertain, up to [`FAST_RESCORE`] of its best surviving
    /// types are scored again at full resolution and METHOD §9 chooses among
    /// them (see [`FAST_SCORE_MARGIN`], [`FAST_EXCLUSION_MARGIN`]); the
    /// chosen type is restored exactly as the exhaustive mode restores it. Reported scores and exclusions are full-resolution ones for the
    /// re-scored types and the copy's for the others. Images whose longer
    /// side is at most 1024 are processed exhaustively.
    Fast,
}

impl Selection {
    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Selection::Exhaustive => "exhaustive",
            Selection::Fast => "fast",
        }
    }

    /// The selection called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "exhaustive" => Ok(Selection::Exhaustive),
            "fast" => Ok(Selection::Fast),
            other => Err(Error::Param {
                name: "selection",
                msg: format!("must be \"exhaustive\" or \"fast\"; got {other:?}"),
            }),
        }
    }
}

/// Parameters of [`restore`]; `Default` gives docs/METHOD.md's defaults.
#[derive(Debug, Clone)]
pub struct Params {
    /// candidate water types (METHOD §1); default: the ten Jerlov types
    pub water_types: Vec<WaterType>,
    /// a given veiling light A (each component in (0, 1]); default: estimated (METHOD §3)
    pub veiling_light: Option<[f32; 3]>,
    /// guided-filter radius; default round(min(H, W) / 4) (METHOD §6)
    pub guided_radius: Option<usize>,
    /// guided-filter eps, > 0; default 1e-3 (METHOD §6)
    pub guided_eps: f64,
    /// number of haze-line clusters; default 500 (METHOD §4.3)
    pub sphere_points: usize,
    /// worker threads; None = rayon's global pool (all cores)
    pub threads: Option<usize>,
    /// working-memory limit in bytes, checked before anything large is allocated
    pub max_memory: u64,
    /// how the water type is chosen; default exhaustive
    pub selection: Selection,
    /// guided-filter subsampling factor s: 1 (default) = the exact filter
    /// of METHOD §6; s >= 2 = He and Sun's fast guided filter, (a, b) computed
    /// on samples at the centres of s x s blocks and interpolated back (METHOD §6, subsampled guided filter);
    /// 0 = automatic, [`auto_subsample`] of the radius
    pub guided_subsample: usize,
}

/// Window radius, in blocks, that [`auto_subsample`] keeps at least.
pub const AUTO_SUBSAMPLE_BLOCKS: usize = 32;

/// The automatic guided-filter subsampling factor for radius r:
/// max(1, floor(r / 32)), so that the subsampled window still spans at
/// least 65 x 65 blocks (METHOD §6, subsampled guided filter).
pub fn auto_subsample(r: usize) -> usize {
    (r / AUTO_SUBSAMPLE_BLOCKS).max(1)
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
            selection: Selection::Exhaustive,
            guided_subsample: 1,
        }
    }
}

/// The image and its optional masks.
#[derive(Debug, Clone, Copy)]
pub struct Input<'a> {
    /// linear RGB in [0, 1]
    pub image: ImageRef<'a>,
    /// true = use the pixel for estimation (METHOD §2); false e.g. on color charts
    pub mask: Option<&'a [bool]>,
    /// a given water region VL, used instead of detection (METHOD §3)
    pub water_mask: Option<&'a [bool]>,
}

/// Everything [`restore`] returns (METHOD §10).
#[derive(Debug, Clone)]
pub struct Restoration {
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// the white-balanced, display-stretched result of the chosen type (METHOD §8), interleaved RGB
    pub image: Vec<f32>,
    /// J after the artifact clamp, before the stretch (METHOD §7), interleaved RGB
    pub radiance: Vec<f32>,
    /// t_B of the chosen type (METHOD §7); -ln t_B = beta_B z
    pub transmission: Vec<f32>,
    /// the chosen water type
    pub water_type: WaterType,
    /// every evaluated type with its gray-world score, in input order (METHOD §9)
    pub scores: Vec<(String, f64)>,
    /// names of the types excluded by the t_R rule (METHOD §9)
    pub excluded: Vec<String>,
    /// the veiling light A used
    pub veiling_light: [f32; 3],
    /// the water region VL (all false when there is none)
    pub veiling_mask: Vec<bool>,
    /// documented fallbacks that were used
    pub flags: Vec<String>,
    /// the guided-filter radius used
    pub guided_radius: usize,
    /// the guided-filter subsampling factor used at full resolution (1: exact)
    pub guided_subsample: usize,
    /// wall-clock seconds of each stage, in order (for profiling; not part
    /// of the result proper and different from run to run)
    pub timings: Vec<(&'static str, f64)>,
}

/// Wall-clock laps of the stages of one [`restore`] call.
struct Clock {
    last: std::time::Instant,
    laps: Vec<(&'static str, f64)>,
}

impl Clock {
    fn new() -> Self {
        Self {
            last: std::time::Instant::now(),
            laps: Vec::new(),
        }
    }

    /// Ends the stage `name` (adds to an earlier lap of that name).
    fn lap(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        let dt = (now - self.last).as_secs_f64();
        self.last = now;
        match self.laps.iter_mut().find(|(n, _)| *n == name) {
            Some((_, t)) => *t += dt,
            None => self.laps.push((name, dt)),
        }
    }
}

impl Restoration {
    /// Per-channel transmission maps (t_R, t_G, t_B) of the chosen type (METHOD §7).
    pub fn channel_transmissions(&self) -> [Vec<f32>; 3] {
        channel_transmissions(&self.transmission, &self.water_type)
    }
}

/// Per-channel transmission maps (t_R, t_G, t_B) from a clamped t_B (METHOD §7).
pub fn channel_transmissions(t_b: &[f32], wt: &WaterType) -> [Vec<f32>; 3] {
    let rec = Recovery::new([1.0; 3], wt);
    let per: Vec<[f32; 3]> = t_b.par_iter().map(|&t| rec.channel_t(t)).collect();
    [
        per.iter().map(|v| v[0]).collect(),
        per.iter().map(|v| v[1]).collect(),
        per.iter().map(|v| v[2]).collect(),
    ]
}

/// Default guided-filter radius: round(min(H, W) / 4), halves away from zero (METHOD §6).
pub fn default_radius(h: usize, w: usize) -> usize {
    (h.min(w) as f64 / 4.0).round() as usize
}

/// Working memory of [`restore`] in bytes beyond the input image, estimated
/// up front from the image size (documented in the README):
/// `H W (88 + 17 holes)` bytes, holes = the estimation mask has false pixels.
/// Per pixel: 12 B guide + 36 B guide statistics (window means and inverse
/// covariances, f32) + 1 B water region, image-wide; 12 B (J, first the
/// refined transmission) + 16 B (t_LB and cluster in its first half, then
/// the guided filter's a, b) + 4 B (the filtered plane q) for the type being
/// evaluated; 4 B for the q kept of the best type so far (so that the
/// chosen type is not filtered again); 3 B for row buffers,
/// order-statistics brackets and allocator slack (measured: 86.7 B per
/// pixel at 12 MP). With masked-out pixels, 17 B for the fill of METHOD
/// §4.5. The outputs (29 B per pixel) are allocated after the per-type
/// buffers and the guide statistics are freed. [`Selection::Fast`] scores
/// its copy before the full-size buffers exist (the estimate adds the
/// copy's share anyway).
pub fn memory_estimate(h: usize, w: usize, holes: bool) -> u64 {
    let n = (h as u64).saturating_mul(w as u64);
    let per_px = 88 + if holes { 17 } else { 0 };
    n.saturating_mul(per_px)
}

/// Fractions of the guide stretch's percentiles (METHOD §3.1).
const GUIDE_QS: [f64; 2] = [0.01, 0.99];

/// The normalisation and per-channel limits of METHOD §3.1 (METHOD §3.1).
fn stretch_limits(data: &[f32], mask: Option<&[bool]>) -> (Normalize, ChannelStretch) {
    let norm = Normalize::masked(data, mask);
    let p = channel_percentiles(data, mask, &GUIDE_QS, |_, v| norm.apply(v));
    let limits = p.map(|p| match (p.first(), p.get(1)) {
        (Some(&lo), Some(&hi)) if hi - lo > 1e-12 => Some((lo, hi)),
        _ => None,
    });
    (norm, ChannelStretch::new(limits))
}

/// The contrast stretch of METHOD §3.1 (METHOD §3.1): global min-max, then
/// per channel between its 1% and 99% percentiles, clipped to [0, 1].
/// Statistics over masked-in pixels (all without a mask), applied to all.
pub fn stretch_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let (norm, st) = stretch_limits(data, mask);
    st.map_rgb(data, |v| norm.apply(v))
}

/// The guide of METHOD §6: the stretched input raised to 1/2.2, 0 on masked-out pixels.
pub fn guide_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    guide_image_into(data, mask, Vec::new())
}

/// [`guide_image`] written into `buf` when it has the right length (a
/// [`Buffers`] plane from an earlier frame: every value is overwritten),
/// else into a new buffer.
fn guide_image_into(data: &[f32], mask: Option<&[bool]>, buf: Vec<f32>) -> Vec<f32> {
    let (norm, st) = stretch_limits(data, mask);
    let mut g = reuse(buf, data.len());
    g.par_chunks_mut(3 * 4096)
        .zip(data.par_chunks(3 * 4096))
        .enumerate()
        .for_each(|(ci, (o, s))| {
            let m = mask.and_then(|m| m.get(ci * 4096..(ci * 4096 + s.len() / 3)));
            guide_row(&norm, &st, s.as_chunks::<3>().0, o.as_chunks_mut::<3>().0, m);
        });
    g
}

/// The guide of METHOD §6 for a run of pixels: the stretched input (METHOD §3
/// step 1) raised to 1/2.2 ([`crate::fastmath::pow_pos`]), 0 where `mask`
/// is false. Compiled for baseline x86-64, AVX2 and AVX-512, picked at
/// run time; the same bits on each (METHOD appendix, same bits on every CPU, F7).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
fn guide_row(norm: &Normalize, st: &ChannelStretch, src: &[[f32; 3]], out: &mut [[f32; 3]], mask: Option<&[bool]>) {
    let gamma = 1.0 / 2.2;
    let map = |v: f32, lo: f64, inv: f64, on: bool| -> f32 {
        let x = norm.apply(v);
        let s = ((x as f64 - lo) * inv).clamp(0.0, 1.0) as f32;
        crate::fastmath::pow_pos(if on { s } else { x }, gamma)
    };
    let tail = |c: usize, x: f32| crate::fastmath::pow_pos(st.apply(c, norm.apply(x)), gamma);
    map_lanes(st, src, out, map, tail);
    if let Some(m) = mask {
        for (o, &k) in out.iter_mut().zip(m) {
            if !k {
                *o = [0.0; 3];
            }
        }
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

/// METHOD §4.4-5 for a run of pixels: t~ = clamp(r / r_max, 0.01, 1) from the
/// radius in `p` and the cluster in `aux` (`rm`: r_max by cluster + 1,
/// entry 0 for "no cluster", t~ = 1), or t~ as given in `p` when `tilde`
/// is false; then t = max(0.9 t~, t_LB), blended with t_LB by the matting
/// weight. Compiled for baseline x86-64, AVX2 and AVX-512, picked at run
/// time; the same bits on each (METHOD appendix, same bits on every CPU, F7).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
fn blend_row(p: &mut [f32], aux: &[[f32; 2]], px: &[[f32; 3]], rm: &[f32], matting: Option<&Matting>, tilde: bool) {
    let last = rm.len().saturating_sub(1);
    let tt = |v: f32, x: &[f32; 2]| -> f32 {
        let t = if tilde {
            let k = ((x[1] + 1.0).max(0.0) as usize).min(last);
            match rm.get(k) {
                Some(&m) if m > 0.0 => (v / m).clamp(T_MIN, 1.0),
                _ => 1.0,
            }
        } else {
            v
        };
        (t * T_SCALE).max(x[0])
    };
    match matting {
        Some(mt) => {
            for ((v, x), c) in p.iter_mut().zip(aux).zip(px) {
                let t = tt(*v, x);
                let wgt = mt.weight(*c);
                *v = wgt * x[0] + (1.0 - wgt) * t;
            }
        }
        None => {
            for (v, x) in p.iter_mut().zip(aux) {
                *v = tt(*v, x);
            }
        }
    }
}

/// Values per run of [`map_lanes`] and [`sum_lanes`]: 8 pixels of 3 channels.
const LANES: usize = 24;

/// The stretch constants of a run of [`LANES`] interleaved values (lane k
/// holds channel k % 3): lo, 1 / (hi - lo), and whether the channel is
/// stretched (lo 0 and 1 when not).
#[inline(always)]
fn lane_constants(st: &ChannelStretch) -> ([f64; LANES], [f64; LANES], [bool; LANES]) {
    let lanes: [(f64, f64, bool); 3] = std::array::from_fn(|c| {
        let l = st.channel(c);
        let (lo, inv) = l.unwrap_or((0.0, 1.0));
        (lo, inv, l.is_some())
    });
    (
        std::array::from_fn(|k| lanes.get(k % 3).map_or(0.0, |l| l.0)),
        std::array::from_fn(|k| lanes.get(k % 3).map_or(1.0, |l| l.1)),
        std::array::from_fn(|k| lanes.get(k % 3).is_some_and(|l| l.2)),
    )
}

/// The loop of [`guide_row`]: runs of 8 pixels whose 24 values each get
/// their channel's stretch constants (lo, 1/(hi - lo), stretched or not)
/// in the same lane (which lets the compiler vectorize across the
/// interleaved channels), `map(value, lo, inv, on)` on each, and
/// `tail(channel, value)` on the pixels left over. Inlined into each
/// caller's builds ([`counted_sums`] has the same lane layout).
#[inline(always)]
fn map_lanes<M, T>(st: &ChannelStretch, src: &[[f32; 3]], out: &mut [[f32; 3]], map: M, tail: T)
where
    M: Fn(f32, f64, f64, bool) -> f32,
    T: Fn(usize, f32) -> f32,
{
    const L: usize = LANES;
    let (lo, inv, on) = lane_constants(st);
    let (sf, of) = (src.as_flattened(), out.as_flattened_mut());
    let (sc, sr) = sf.as_chunks::<L>();
    let (oc, or) = of.as_chunks_mut::<L>();
    for (o, v) in oc.iter_mut().zip(sc) {
        for k in 0..L {
            if let (Some(d), Some(&x), Some(&l), Some(&i), Some(&f)) = (o.get_mut(k), v.get(k), lo.get(k), inv.get(k), on.get(k)) {
                *d = map(x, l, i, f);
            }
        }
    }
    for (k, (d, &x)) in or.iter_mut().zip(sr).enumerate() {
        *d = tail(k % 3, x);
    }
}

/// Sums of the three displayed channels of a row of J (`sp` applied, the
/// METHOD §7 clamp and METHOD §8 stretch, or the values as they are without)
/// over the pixels where `counted` is true (METHOD §9's means). Without `sp`
/// on values mapped by [`Stretch::apply`], the same bits as with `sp` on
/// the values. Runs of 8 pixels are summed in 24 lanes (one
/// channel each, as in [`map_lanes`]), each lane in pixel order; a
/// channel's lanes are combined in lane order, then the pixels left over
/// are added: the same for any thread count. Compiled for baseline x86-64
/// and for AVX2, picked at run time; the same bits either way (METHOD appendix, same bits on every CPU).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn counted_sums(sp: Option<&Stretch>, px: &[[f32; 3]], counted: &[bool]) -> [f64; 3] {
    match sp {
        Some(sp) => {
            let shown = |v: f32, lo: f64, inv: f64, on: bool| -> f32 {
                let x = sp.norm.apply(sp.clamp.apply(v));
                let s = ((x as f64 - lo) * inv).clamp(0.0, 1.0) as f32;
                if on {
                    s
                } else {
                    x
                }
            };
            sum_lanes(&sp.limits, px, counted, shown, |c, x| sp.apply(c, x))
        }
        None => sum_lanes(&ChannelStretch::new([None; 3]), px, counted, |v, _, _, _| v, |_, x| x),
    }
}

/// The loop of [`counted_sums`] with `map` (and `tail` for the pixels left
/// over) giving the displayed values; inlined into each of its builds.
#[inline(always)]
fn sum_lanes<M, T>(limits: &ChannelStretch, px: &[[f32; 3]], counted: &[bool], map: M, tail: T) -> [f64; 3]
where
    M: Fn(f32, f64, f64, bool) -> f32,
    T: Fn(usize, f32) -> f32,
{
    const P: usize = LANES / 3;
    const L: usize = LANES;
    let (lo, inv, on) = lane_constants(limits);
    let mut acc = [0f64; L];
    let (pc, prest) = px.as_chunks::<P>();
    let (cc, crest) = counted.as_chunks::<P>();
    for (p, c) in pc.iter().zip(cc) {
        let v = p.as_flattened();
        let mut shown = [0f32; L];
        for k in 0..L {
            if let (Some(d), Some(&x), Some(&l), Some(&i), Some(&f)) = (shown.get_mut(k), v.get(k), lo.get(k), inv.get(k), on.get(k)) {
                *d = map(x, l, i, f);
            }
        }
        let flag: [bool; L] = std::array::from_fn(|k| c.get(k / 3).copied().unwrap_or(false));
        for ((a, &x), &n) in acc.iter_mut().zip(&shown).zip(&flag) {
            *a += if n { f64::from(x) } else { 0.0 };
        }
    }
    let mut out = [0f64; 3];
    for (k, a) in acc.iter().enumerate() {
        if let Some(o) = out.get_mut(k % 3) {
            *o += *a;
        }
    }
    for (p, &n) in prest.iter().zip(crest) {
        for (c, (o, &x)) in out.iter_mut().zip(p).enumerate() {
            *o += if n { f64::from(tail(c, x)) } else { 0.0 };
        }
    }
    out
}

/// Adds to `st` one row's statistics: min and max of J over the pixels
/// inside the mask, sums of t_R and counts over its VL and other pixels.
/// Accumulates in 8 lanes combined in lane order (the same for any thread
/// count); compiled for baseline x86-64 and for AVX2, picked at run time,
/// the same bits either way (METHOD appendix, same bits on every CPU).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn row_stats(j: &[[f32; 3]], tr: &[f32], inside: &[bool], vl: &[bool], st: &mut RowStats) {
    const L: usize = 8;
    // one array per statistic, one entry per lane: each lane's values are
    // accumulated in pixel order, and lanes in lane order, as before
    let mut lo = [f32::INFINITY; L];
    let mut hi = [f32::NEG_INFINITY; L];
    let [mut s0, mut s1, mut s2, mut s3] = [[0f64; L]; 4];
    let (jc, jrest) = j.as_chunks::<L>();
    let (tc, trest) = tr.as_chunks::<L>();
    let (ic, irest) = inside.as_chunks::<L>();
    let (vc, vrest) = vl.as_chunks::<L>();
    for (((jj, tt), ii), vv) in jc.iter().zip(tc).zip(ic).zip(vc) {
        let lanes = lo.iter_mut().zip(hi.iter_mut()).zip(s0.iter_mut().zip(s1.iter_mut()).zip(s2.iter_mut().zip(s3.iter_mut())));
        for (((l, h), ((a0, a1), (a2, a3))), (((jv, &t), &ins), &v)) in lanes.zip(jj.iter().zip(tt).zip(ii).zip(vv)) {
            let (mn, mx) = (jv[0].min(jv[1]).min(jv[2]), jv[0].max(jv[1]).max(jv[2]));
            *l = l.min(if ins { mn } else { f32::INFINITY });
            *h = h.max(if ins { mx } else { f32::NEG_INFINITY });
            let t = f64::from(t);
            let (iv, ic) = (ins && v, ins && !v);
            *a0 += if iv { t } else { 0.0 };
            *a1 += if iv { 1.0 } else { 0.0 };
            *a2 += if ic { t } else { 0.0 };
            *a3 += if ic { 1.0 } else { 0.0 };
        }
    }
    // the pixels left over go to lane 0, after its chunk values
    for (((jv, &t), &ins), &v) in jrest.iter().zip(trest).zip(irest).zip(vrest) {
        let (mn, mx) = (jv[0].min(jv[1]).min(jv[2]), jv[0].max(jv[1]).max(jv[2]));
        let t = f64::from(t);
        let (iv, ic) = (ins && v, ins && !v);
        let lane0 = (lo.first_mut(), hi.first_mut(), s0.first_mut(), s1.first_mut(), s2.first_mut(), s3.first_mut());
        if let (Some(l), Some(h), Some(a0), Some(a1), Some(a2), Some(a3)) = lane0 {
            *l = l.min(if ins { mn } else { f32::INFINITY });
            *h = h.max(if ins { mx } else { f32::NEG_INFINITY });
            *a0 += if iv { t } else { 0.0 };
            *a1 += if iv { 1.0 } else { 0.0 };
            *a2 += if ic { t } else { 0.0 };
            *a3 += if ic { 1.0 } else { 0.0 };
        }
    }
    for k in 0..L {
        let get = |a: &[f64; L]| a.get(k).copied().unwrap_or(0.0);
        st.lo = st.lo.min(lo.get(k).copied().unwrap_or(f32::INFINITY));
        st.hi = st.hi.max(hi.get(k).copied().unwrap_or(f32::NEG_INFINITY));
        st.sums.tr_vl += get(&s0);
        st.sums.vl += get(&s1);
        st.sums.tr_counted += get(&s2);
        st.sums.counted += get(&s3);
    }
}

/// Row buffers of [`Shared::recover_row`], reused from row to row.
struct RowScratch {
    tr: Vec<f32>,
    tb: Vec<f32>,
    /// all true
    yes: Vec<bool>,
    /// all false
    no: Vec<bool>,
}

impl RowScratch {
    fn new(w: usize) -> Self {
        Self {
            tr: vec![0.0; w],
            tb: vec![0.0; w],
            yes: vec![true; w],
            no: vec![false; w],
        }
    }
}

/// What one pass over a row of recovered pixels gathers (METHOD §7-9).
#[derive(Debug, Clone, Copy)]
struct RowStats {
    /// min and max of J over the masked-in pixels' channels
    lo: f32,
    hi: f32,
    /// t_R sums over counted and VL pixels (the channel sums come later)
    sums: SelectionSums,
}

impl Default for RowStats {
    fn default() -> Self {
        Self {
            lo: f32::INFINITY,
            hi: f32::NEG_INFINITY,
            sums: SelectionSums::default(),
        }
    }
}

impl RowStats {
    fn add(&mut self, o: &Self) {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
        self.sums.add(&o.sums);
    }
}

/// The buffers of the type being evaluated (reused from type to type).
struct Work {
    /// the refined transmission p in the first n entries, then J (3 per pixel)
    j: Vec<f32>,
    /// t_LB and cluster per pixel (METHOD §4-5), then the guided filter's (a, b)
    aux: Vec<[f32; 4]>,
    /// the filtered plane q after the chart fill (METHOD §6): what the
    /// recovery reads, kept so that the chosen type need not be filtered
    /// again ([`Shared::score`])
    q: Vec<f32>,
}

impl Work {
    fn new(n: usize) -> Self {
        Self::from_pool(n, &mut Buffers::default())
    }

    /// The buffers for n pixels, (a, b) and q taken from `pool` when they
    /// have the right length. No pass reads a value of these buffers that
    /// it has not written (the types already share them), so old contents
    /// do not matter.
    fn from_pool(n: usize, pool: &mut Buffers) -> Self {
        Self {
            j: vec![0.0; 3 * n],
            aux: reuse(std::mem::take(&mut pool.aux), n),
            q: reuse(std::mem::take(&mut pool.q), n),
        }
    }
}

/// `buf` if it holds exactly `n` values, else n default values.
fn reuse<T: Copy + Default>(buf: Vec<T>, n: usize) -> Vec<T> {
    if buf.len() == n {
        buf
    } else {
        drop(buf);
        vec![T::default(); n]
    }
}

/// Full-resolution work buffers that a [`crate::sequence::Sequence`] keeps
/// from one frame to the next (the guide image, the guided filter's (a, b)
/// and the filtered plane: 32 B per pixel), so that a frame of the same
/// size reuses their pages instead of having the kernel map and zero new
/// ones (METHOD §10, sequence mode). A plain [`restore`] starts from empty buffers and
/// frees its planes as early as before (`keep` false).
#[derive(Debug, Default)]
pub struct Buffers {
    guide: Vec<f32>,
    aux: Vec<[f32; 4]>,
    q: Vec<f32>,
    /// keep the planes at the end of a call (else they are freed as soon as
    /// they are no longer needed)
    keep: bool,
}

impl Buffers {
    /// Buffers that keep their planes between calls.
    pub fn kept() -> Self {
        Self { keep: true, ..Self::default() }
    }

    /// Bytes currently held.
    pub fn bytes(&self) -> usize {
        4 * (self.guide.len() + 4 * self.aux.len() + self.q.len())
    }

    /// Takes back the work planes at the end of a call (drops them unless kept).
    fn put(&mut self, aux: Vec<[f32; 4]>, q: Vec<f32>) {
        if self.keep {
            self.aux = aux;
            self.q = q;
        }
    }
}

/// A type's restored image before its final form: J before the artifact
/// clamp, and the maps that make the outputs from it.
struct Stretch {
    clamp: ArtifactClamp,
    norm: Normalize,
    limits: ChannelStretch,
}

impl Stretch {
    /// The displayed value of channel c of J (METHOD §7 clamp, METHOD §8 stretch).
    #[inline(always)]
    fn apply(&self, c: usize, j: f32) -> f32 {
        self.limits.apply(c, self.norm.apply(self.clamp.apply(j)))
    }
}

/// Per-image state shared by every water type.
struct Shared<'a> {
    img: ImageRef<'a>,
    mask: Option<&'a [bool]>,
    vl: &'a [bool],
    a: [f32; 3],
    matting: Option<Matting>,
    guide: GuideStats,
    index: &'a SphereIndex,
    holes: bool,
}

impl Shared<'_> {
    /// METHOD §4-6 up to the guided filter's first pass: the refined
    /// transmission p = blend(max(t~, t_LB)) into `work.j[..n]`, then (a, b)
    /// into `work.aux`. Returns the bounds of (a, b) for the second pass.
    fn refine(&self, wt: &WaterType, work: &mut Work) -> [f64; 4] {
        let img = &self.img;
        let (n, w) = (img.len(), img.width);
        let Work { j, aux, .. } = work;
        let (p, _) = j.split_at_mut(n);
        let ht = HazeType::new(self.a, wt);
        // (t_LB, cluster) in the first half of the (a, b) buffer
        let pairs = aux.as_flattened_mut().get_mut(..2 * n).unwrap_or(&mut []).as_chunks_mut::<2>().0;
        let rmax = haze_pass(img, &ht, self.index, self.mask, p, pairs);
        // r_max by cluster + 1 (0: no cluster, t~ = 1)
        let rm: Vec<f32> = std::iter::once(0.0).chain(rmax.iter().copied()).collect();
        let matting = self.matting.as_ref();
        let chunk = w * CHUNK_ROWS;
        if self.holes {
            p.par_iter_mut()
                .zip(pairs.par_iter())
                .for_each(|(v, x)| *v = t_tilde(*v, x[1], &rmax));
            if let Some(m) = self.mask {
                fill_masked(p, m, img.height, w);
            }
        }
        p.par_chunks_mut(chunk)
            .zip(pairs.par_chunks(chunk))
            .zip(img.data.par_chunks(3 * chunk))
            .for_each(|((pp, aa), px)| blend_row(pp, aa, px.as_chunks::<3>().0, &rm, matting, !self.holes));
        self.guide.coefficients(p, aux)
    }

    /// METHOD §7 for one row: t_B (written to `tb` if given), t_R, t_G and J
    /// before the artifact clamp (to `j`), with the row's statistics.
    fn recover_row(&self, rec: &Recovery, y: usize, q: &[f32], j: &mut [f32], tb: Option<&mut [f32]>, sc: &mut RowScratch) -> RowStats {
        let w = self.img.width;
        let mut st = RowStats::default();
        let px = self.img.data.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
        let jr = j.as_chunks_mut::<3>().0;
        let RowScratch { tr, tb: tb_own, yes, no } = sc;
        let tbr = match tb {
            Some(b) => b,
            None => &mut tb_own[..],
        };
        recover_values(rec, q, px.as_chunks::<3>().0, jr, tbr, tr);
        let (inside, vl) = self.row_masks(y, yes, no);
        row_stats(jr, tr, inside, vl, &mut st);
        st
    }

    /// Row y of the estimation mask (all true without one) and of the
    /// water region VL, with `yes` / `no` (w entries, all true / all false)
    /// standing in for what is absent.
    fn row_masks<'s>(&'s self, y: usize, yes: &'s [bool], no: &'s [bool]) -> (&'s [bool], &'s [bool]) {
        let w = self.img.width;
        let row = y * w..(y + 1) * w;
        let inside = match self.mask {
            Some(m) => m.get(row.clone()).unwrap_or(no),
            None => yes,
        };
        (inside, self.vl.get(row).unwrap_or(no))
    }

    /// The guided filter's second pass, the chart fill (METHOD §6) and the
    /// recovery (METHOD §7) into `work.j` (and t_B into `tb` if given);
    /// returns the statistics of all rows combined in row order.
    fn recover(&self, wt: &WaterType, bounds: [f64; 4], work: &mut Work, tb: Option<&mut [f32]>) -> RowStats {
        let (h, w) = (self.img.height, self.img.width);
        let mut tb_buf = tb;
        if !self.holes {
            let rec = Recovery::new(self.a, wt);
            let mut rows = vec![RowStats::default(); h];
            let Work { j, aux, q } = &mut *work;
            let ranges = self.guide.ranges();
            let tbs: Vec<Option<&mut [f32]>> = match tb_buf.as_deref_mut() {
                Some(b) => split_rows(b, w, &ranges).into_iter().map(Some).collect(),
                None => ranges.iter().map(|_| None).collect(),
            };
            let work: Vec<_> = ranges
                .iter()
                .cloned()
                .zip(split_rows(j, 3 * w, &ranges).into_iter().zip(tbs).zip(split_rows(&mut rows, 1, &ranges)))
                .zip(split_rows(q, w, &ranges))
                .map(|((r, ((jj, tt), rr)), qq)| (r.clone(), (r.start, jj, tt, rr, qq, RowScratch::new(w))))
                .collect();
            type State<'s> = (usize, &'s mut [f32], Option<&'s mut [f32]>, &'s mut [RowStats], &'s mut [f32], RowScratch);
            let sink = |o: &mut State<'_>, y: usize, qrow: &[f32]| {
                let k = y - o.0;
                let (Some(jr), Some(slot)) = (o.1.get_mut(3 * k * w..3 * (k + 1) * w), o.3.get_mut(k)) else {
                    return;
                };
                if let Some(d) = o.4.get_mut(k * w..(k + 1) * w) {
                    d.copy_from_slice(qrow);
                }
                let tr = o.2.as_deref_mut().and_then(|b| b.get_mut(k * w..(k + 1) * w));
                *slot = self.recover_row(&rec, y, qrow, jr, tr, &mut o.5);
            };
            self.guide.apply_rows(aux, bounds, work, &sink);
            combine(&rows)
        } else {
            let Work { aux, q, .. } = &mut *work;
            let ranges = self.guide.ranges();
            let bands: Vec<_> = ranges
                .iter()
                .cloned()
                .zip(split_rows(q, w, &ranges))
                .map(|(r, s)| (r.clone(), (r.start, s)))
                .collect();
            let sink = |o: &mut (usize, &mut [f32]), y: usize, qrow: &[f32]| {
                let k = y - o.0;
                if let Some(d) = o.1.get_mut(k * w..(k + 1) * w) {
                    d.copy_from_slice(qrow);
                }
            };
            self.guide.apply_rows(aux, bounds, bands, &sink);
            if let Some(m) = self.mask {
                chart_fill(q, m, h, w);
            }
            self.recover_from_q(wt, work, tb_buf)
        }
    }

    /// The recovery (METHOD §7) from the filtered plane in `work.q` into
    /// `work.j` (and t_B into `tb` if given), with the statistics of all
    /// rows combined in row order: what [`Shared::recover`] gives for the
    /// q it stored.
    fn recover_from_q(&self, wt: &WaterType, work: &mut Work, tb: Option<&mut [f32]>) -> RowStats {
        let (h, w) = (self.img.height, self.img.width);
        let rec = Recovery::new(self.a, wt);
        let Work { j, q, .. } = work;
        let mut rows = vec![RowStats::default(); h];
        let tbs: Vec<Option<&mut [f32]>> = match tb {
            Some(b) => b.chunks_mut(w).map(Some).collect(),
            None => (0..h).map(|_| None).collect(),
        };
        rows.par_iter_mut()
            .zip(j.par_chunks_mut(3 * w))
            .zip(q.par_chunks(w))
            .zip(tbs)
            .enumerate()
            .for_each_init(
                || RowScratch::new(w),
                |sc, (y, (((slot, jr), qr), tr))| *slot = self.recover_row(&rec, y, qr, jr, tr, sc),
            );
        combine(&rows)
    }

    /// The artifact clamp and display stretch of a recovered J (METHOD §7-8),
    /// from J's min and max and the order statistics of its channels.
    fn stretch(&self, j: &[f32], st: &RowStats) -> Stretch {
        let clamp = ArtifactClamp::new(st.lo, st.hi);
        let norm = Normalize::new(clamp.apply(st.lo), clamp.apply(st.hi));
        let pcts = channel_percentiles(j, self.mask, &DISPLAY_QS, |_, v| norm.apply(clamp.apply(v)));
        Stretch {
            clamp,
            norm,
            limits: display_limits(&pcts),
        }
    }

    /// Sums of the three displayed channels over counted pixels (METHOD §9),
    /// per row, combined in row order, of J mapped by `sp` (the values as
    /// they are without).
    fn channel_sums(&self, rgb: &[f32], sp: Option<&Stretch>) -> [f64; 3] {
        let w = self.img.width;
        let rows: Vec<[f64; 3]> = rgb
            .par_chunks(3 * w)
            .enumerate()
            .map_init(
                || (vec![false; w], RowScratch::new(w)),
                |(counted, sc), (y, row)| {
                    // counted: inside the mask and not in VL
                    let (inside, vl) = self.row_masks(y, &sc.yes, &sc.no);
                    counted.iter_mut().zip(inside).zip(vl).for_each(|((c, &i), &b)| *c = i & !b);
                    counted_sums(sp, row.as_chunks::<3>().0, counted)
                },
            )
            .collect();
        rows.iter().fold([0f64; 3], |a, r| [a[0] + r[0], a[1] + r[1], a[2] + r[2]])
    }

    /// Selection statistics of one type (METHOD §4-9) without keeping any of
    /// its images.
    fn evaluate(&self, wt: &WaterType, work: &mut Work) -> TypeStats {
        let bounds = self.refine(wt, work);
        let st = self.recover(wt, bounds, work, None);
        let sp = self.stretch(&work.j, &st);
        let mut sums = st.sums;
        sums.channels = self.channel_sums(&work.j, Some(&sp));
        sums.stats()
    }

    /// The selection statistics of each type in `types` (in order), and the
    /// filtered plane q of the one that [`choose`] picks among them, when
    /// it is known: after each type, only the winner of the types scored
    /// so far can still win (a later type can only make the exclusion
    /// threshold stricter, or win itself; whether t_R differences exist
    /// does not depend on the type), so only its plane is kept.
    fn score(&self, types: &[&WaterType], work: &mut Work) -> (Vec<TypeStats>, Option<Kept>) {
        let mut stats = Vec::with_capacity(types.len());
        let mut kept: Option<Kept> = None;
        for (i, wt) in types.iter().enumerate() {
            stats.push(self.evaluate(wt, work));
            if choose(&stats).winner == i {
                let spare = kept.take().map_or_else(|| vec![0.0; work.q.len()], |k| k.q);
                kept = Some(Kept {
                    index: i,
                    q: std::mem::replace(&mut work.q, spare),
                });
            }
        }
        (stats, kept)
    }
}

/// The statistics of all rows combined in row order (the same for any
/// thread count).
fn combine(rows: &[RowStats]) -> RowStats {
    rows.iter().fold(RowStats::default(), |mut acc, r| {
        acc.add(r);
        acc
    })
}

/// The filtered plane q of a scored type (its index among the scored ones).
struct Kept {
    index: usize,
    q: Vec<f32>,
}

/// Splits a buffer of `row_len` items per row at the row ranges.
fn split_rows<'a, T>(buf: &'a mut [T], row_len: usize, ranges: &[Range<usize>]) -> Vec<&'a mut [T]> {
    crate::boxsum::split_bands(buf, row_len, ranges)
}

/// The outputs of the chosen type.
struct Final {
    radiance: Vec<f32>,
    transmission: Vec<f32>,
    image: Vec<f32>,
    stats: TypeStats,
}

/// Restores the image with one water type (METHOD §4-8): the outputs and the
/// type's selection statistics, identical to what the evaluation gave.
/// With `q`, the type's filtered plane kept from its scoring, only the
/// recovery is run again.
fn finish(
    mut shared: Shared<'_>,
    wt: &WaterType,
    mut work: Work,
    q: Option<Vec<f32>>,
    pool: &mut Buffers,
    clock: &mut Clock,
) -> Final {
    let n = shared.img.len();
    let (st, transmission) = match q {
        Some(q) if q.len() == n => {
            shared.guide.release_stats();
            if !pool.keep {
                // not read from here on: freed early unless kept
                work.aux = Vec::new();
            }
            work.q = q;
            let mut transmission = vec![0f32; n];
            let st = shared.recover_from_q(wt, &mut work, Some(&mut transmission));
            clock.lap("chosen: recovery from the kept filtered plane");
            (st, transmission)
        }
        _ => {
            let bounds = shared.refine(wt, &mut work);
            clock.lap("chosen: haze-lines, bounds, guided filter pass 1");
            // the guide statistics serve only the first pass
            shared.guide.release_stats();
            let mut transmission = vec![0f32; n];
            let st = shared.recover(wt, bounds, &mut work, Some(&mut transmission));
            clock.lap("chosen: guided filter pass 2, recovery");
            (st, transmission)
        }
    };
    let sp = shared.stretch(&work.j, &st);
    clock.lap("chosen: display stretch limits");
    pool.put(std::mem::take(&mut work.aux), std::mem::take(&mut work.q));
    let mut radiance = std::mem::take(&mut work.j);
    radiance.par_iter_mut().for_each(|v| *v = sp.clamp.apply(*v));
    let image = sp.limits.map_rgb(&radiance, |v| sp.norm.apply(v));
    let mut sums = st.sums;
    sums.channels = shared.channel_sums(&image, None);
    if pool.keep {
        pool.guide = shared.guide.into_guide();
    }
    clock.lap("chosen: outputs");
    Final {
        radiance,
        transmission,
        image,
        stats: sums.stats(),
    }
}

/// The whole method (METHOD §2-10) on one image.
pub fn restore(input: &Input, params: &Params) -> Result<Restoration> {
    restore_with(input, params, &mut Buffers::default())
}

/// [`restore`] with work buffers taken from, and (when they are kept)
/// returned to, `pool`; the results are the same bits.
pub fn restore_with(input: &Input, params: &Params, pool: &mut Buffers) -> Result<Restoration> {
    with_threads(params.threads, || restore_inner(input, params, pool))?
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
    if params.guided_subsample > img.height.max(img.width) {
        return Err(Error::Param {
            name: "guided_subsample",
            msg: format!(
                "{} is larger than the image ({}x{})",
                params.guided_subsample, img.height, img.width
            ),
        });
    }
    check_mask("mask", input.mask, img.len(), 1)?;
    check_mask("water_mask", input.water_mask, img.len(), 0)?;
    let holes = input.mask.is_some_and(|m| m.iter().any(|&b| !b));
    let mut needed = memory_estimate(img.height, img.width, holes);
    if params.selection == Selection::Fast {
        let s = fast_factor(img.height, img.width);
        needed += memory_estimate(img.height.div_ceil(s), img.width.div_ceil(s), holes);
    }
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

/// Relative margin of [`Selection::Fast`]: a survivor scoring within this
/// factor of the copy's best is re-scored at full resolution.
pub const FAST_SCORE_MARGIN: f64 = 1.5;
/// A survivor whose t_R difference on the copy is within this of the
/// copy's exclusion threshold may be excluded at full resolution: the next
/// survivor is re-scored too.
pub const FAST_EXCLUSION_MARGIN: f64 = 0.03;

/// The types [`Selection::Fast`] scores again at full resolution: from the
/// copy's survivors in order of score (`order`, best first), the best one,
/// then every next one while it scores within [`FAST_SCORE_MARGIN`] of the
/// best or all taken so far might be excluded at full resolution (t_R
/// difference within [`FAST_EXCLUSION_MARGIN`] of the threshold); at most
/// [`FAST_RESCORE`]. Measured on the shared photos and renders: the copy's
/// t_R differences are within 0.02 of the full-resolution ones, and its
/// choice differs only between types within 30% of each other's score or
/// across the exclusion threshold.
fn rescore_candidates(order: &[usize], copy: &[TypeStats], threshold: Option<f64>) -> Vec<usize> {
    let stat = |i: usize| copy.get(i).copied();
    let uncertain = |i: usize| match (threshold, stat(i).and_then(|s| s.tr_diff)) {
        (Some(thr), Some(d)) => d < thr + FAST_EXCLUSION_MARGIN,
        _ => false,
    };
    let best = order.first().and_then(|&i| stat(i)).map_or(f64::NAN, |s| s.score);
    let mut out: Vec<usize> = Vec::new();
    for &i in order {
        let close = stat(i).is_some_and(|s| s.score <= FAST_SCORE_MARGIN * best);
        if out.len() >= FAST_RESCORE || !(out.is_empty() || close || out.iter().all(|&j| uncertain(j))) {
            break;
        }
        out.push(i);
    }
    out
}

/// Block factor of the copy [`Selection::Fast`] scores on (1: no copy).
pub fn fast_factor(h: usize, w: usize) -> usize {
    h.max(w).div_ceil(FAST_SIDE).max(1)
}

/// The copy of the image with its masks that [`Selection::Fast`] scores
/// the types on: every s-th pixel of every s-th row (the centre of each
/// s x s block). Point samples, not block averages: the statistics that
/// selection depends on (the largest radius of each haze-line cluster, the
/// 0.1% / 99.9% percentiles of the display stretch) are those of the
/// pixels' own distribution, which averaging would narrow by removing
/// noise.
struct Small {
    data: Vec<f32>,
    h: usize,
    w: usize,
    mask: Option<Vec<bool>>,
    vl: Vec<bool>,
}

impl Small {
    fn new(img: &ImageRef, mask: Option<&[bool]>, vl: &[bool], s: usize) -> Self {
        let (h, w) = (img.height, img.width);
        let (hs, ws) = (h.div_ceil(s), w.div_ceil(s));
        // the sampled pixel of block (by, bx): its centre, inside the image
        let ys: Vec<usize> = (0..hs).map(|b| (b * s + s / 2).min(h - 1)).collect();
        let xs: Vec<usize> = (0..ws).map(|b| (b * s + s / 2).min(w - 1)).collect();
        let pick = |m: &[bool]| -> Vec<bool> {
            ys.iter()
                .flat_map(|&y| xs.iter().map(move |&x| y * w + x))
                .map(|i| m.get(i).copied().unwrap_or(false))
                .collect()
        };
        let data = ys
            .iter()
            .flat_map(|&y| xs.iter().map(move |&x| y * w + x))
            .flat_map(|i| img.data.get(3 * i..3 * i + 3).unwrap_or(&[0.0; 3]).iter().copied())
            .collect();
        Self {
            mask: mask.map(pick),
            vl: pick(vl),
            data,
            h: hs,
            w: ws,
        }
    }
}

fn restore_inner(input: &Input, params: &Params, pool: &mut Buffers) -> Result<Restoration> {
    let mut clock = Clock::new();
    check_params(input, params)?;
    let img = &input.image;
    img.validate_values()?;
    let (h, w) = (img.height, img.width);
    let index = SphereIndex::shared(params.sphere_points)?;
    clock.lap("validation");
    let veil = estimate(img, input.mask, input.water_mask, params.veiling_light);
    clock.lap("veiling light");
    let usable = input
        .mask
        .map_or(img.len(), |m| m.iter().filter(|&&b| b).count());
    if veil.vl_count >= usable {
        return Err(Error::Mask {
            name: "water_mask",
            msg: "covers every pixel used for estimation: no object pixels are left to choose the water type".into(),
        });
    }
    let radius = params.guided_radius.unwrap_or_else(|| default_radius(h, w));
    let holes = input.mask.is_some_and(|m| m.iter().any(|&b| !b));
    let sub = |r: usize| match params.guided_subsample {
        0 => auto_subsample(r),
        s => s,
    };
    let make = |img: ImageRef<'_>, mask: Option<&'_ [bool]>, vl: &'_ [bool], r: usize, buf: Vec<f32>| {
        (
            Matting::fit(&img, vl),
            GuideStats::subsampled(guide_image_into(img.data, mask, buf), img.height, img.width, r, params.guided_eps, sub(r)),
        )
    };
    let types = &params.water_types;
    let s = fast_factor(h, w);
    // Selection::Fast: scores of every type on the copy (METHOD §9 there)
    let copy: Option<Vec<TypeStats>> = if types.len() >= 2 && params.selection == Selection::Fast && s > 1 {
        let small = Small::new(img, input.mask, &veil.vl, s);
        let simg = ImageRef::new(&small.data, small.h, small.w)?;
        let sr = params
            .guided_radius
            .map_or_else(|| default_radius(small.h, small.w), |r| (r as f64 / s as f64).round() as usize);
        let (matting, guide) = make(simg, small.mask.as_deref(), &small.vl, sr, Vec::new());
        let sh = Shared {
            img: simg,
            mask: small.mask.as_deref(),
            vl: &small.vl,
            a: veil.a,
            matting,
            guide,
            index: &index,
            holes: small.mask.as_ref().is_some_and(|m| m.iter().any(|&b| !b)),
        };
        let mut work = Work::new(simg.len());
        let stats = types.iter().map(|wt| sh.evaluate(wt, &mut work)).collect();
        clock.lap("fast: scoring on the copy");
        Some(stats)
    } else {
        None
    };
    let (matting, guide) = make(*img, input.mask, &veil.vl, radius, std::mem::take(&mut pool.guide));
    clock.lap("matting model, guide and its statistics");
    let matting_skipped = veil.vl_count > 0 && matting.is_none();
    let shared = Shared {
        img: *img,
        mask: input.mask,
        vl: &veil.vl,
        a: veil.a,
        matting,
        guide,
        index: &index,
        holes,
    };
    let mut work = Work::from_pool(img.len(), pool);
    clock.lap("work buffers");
    // METHOD §9: which types are scored at full resolution, and the choice
    let mut kept: Option<Kept> = None;
    let mut sel = match copy {
        Some(copy) => {
            let c = choose(&copy);
            // the copy's best survivors, re-scored at full resolution where
            // its choice is uncertain
            let mut order: Vec<usize> = (0..copy.len()).filter(|&i| !c.excluded.get(i).copied().unwrap_or(true)).collect();
            let score = |i: usize| copy.get(i).map_or(f64::NAN, |s| s.score);
            order.sort_by(|&i, &j| score(i).total_cmp(&score(j)).then(i.cmp(&j)));
            let order = rescore_candidates(&order, &copy, c.threshold);
            let mut stats = copy;
            let mut excluded = c.excluded;
            let (winner, relaxed) = if order.len() > 1 {
                let picked: Vec<&WaterType> = order.iter().filter_map(|&i| types.get(i)).collect();
                let (full, k) = shared.score(&picked, &mut work);
                let sub = choose(&full);
                // the kept plane, by its index among all the types
                kept = k.and_then(|k| order.get(k.index).map(|&i| Kept { index: i, q: k.q }));
                for ((&i, st), ex) in order.iter().zip(&full).zip(&sub.excluded) {
                    if let (Some(d), Some(e)) = (stats.get_mut(i), excluded.get_mut(i)) {
                        *d = *st;
                        *e = *ex;
                    }
                }
                (order.get(sub.winner).copied().unwrap_or(c.winner), sub.relaxed)
            } else {
                (c.winner, c.relaxed)
            };
            Some((stats, Choice { winner, excluded, relaxed, threshold: None }))
        }
        None if types.len() >= 2 => {
            let all: Vec<&WaterType> = types.iter().collect();
            let (stats, k) = shared.score(&all, &mut work);
            kept = k;
            let ch = choose(&stats);
            Some((stats, ch))
        }
        None => None,
    };
    clock.lap("scoring the types");
    let winner = sel.as_ref().map_or(0, |(_, c)| c.winner);
    let wt = types
        .get(winner)
        .ok_or_else(|| Error::Internal("winner out of range".into()))?
        .clone();
    // the winner's filtered plane, when its scoring kept it
    let q = kept.filter(|k| k.index == winner).map(|k| k.q);
    let out = finish(shared, &wt, work, q, pool, &mut clock);
    let (stats, choice) = match sel.take() {
        Some((mut stats, choice)) => {
            // the chosen type's full-resolution statistics (what the copy
            // reported for it otherwise; identical in the exhaustive mode)
            if let Some(d) = stats.get_mut(winner) {
                *d = out.stats;
            }
            (stats, choice)
        }
        None => {
            let stats = vec![out.stats];
            let choice = choose(&stats);
            (stats, choice)
        }
    };
    let Veiling { a, vl, flags: vflags, .. } = veil;
    let mut flags: Vec<String> = vflags.iter().map(|s| s.to_string()).collect();
    if choice.relaxed {
        flags.push(FLAG_RELAXED.to_string());
    }
    if matting_skipped {
        flags.push("matting_skipped".to_string());
    }
    Ok(Restoration {
        height: h,
        width: w,
        image: out.image,
        radiance: out.radiance,
        transmission: out.transmission,
        scores: types
            .iter()
            .zip(&stats)
            .map(|(t, s)| (t.name.clone(), s.score))
            .collect(),
        excluded: types
            .iter()
            .zip(&choice.excluded)
            .filter(|(_, &e)| e)
            .map(|(t, _)| t.name.clone())
            .collect(),
        water_type: wt,
        veiling_light: a,
        veiling_mask: vl,
        flags,
        guided_radius: radius,
        guided_subsample: sub(radius),
        timings: clock.laps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row kernels (AVX2 builds where the CPU has AVX2) against the
    /// per-pixel functions (baseline builds here): the same bits
    /// (METHOD appendix, same bits on every CPU), and row_stats against a plain loop.
    #[test]
    fn row_kernels_match_per_pixel_values() {
        let n = 1037;
        let noise = crate::util::test_noise(8 * n, 3);
        let j: Vec<[f32; 3]> = noise.chunks_exact(3).take(n).map(|c| [c[0] * 1.4 - 0.2, c[1], c[2] * 2.0]).collect();
        let clamp = ArtifactClamp::new(-0.2, 2.0);
        let norm = Normalize::new(clamp.apply(-0.2), clamp.apply(2.0));
        for limits in [
            [Some((0.1, 0.9)), None, Some((0.0, 0.5))],
            [None, None, None],
            [Some((0.2, 0.3)), Some((0.0, 1.0)), Some((0.4, 0.8))],
        ] {
            let sp = Stretch { clamp, norm, limits: ChannelStretch::new(limits) };
            let shown: Vec<[f32; 3]> = j.iter().map(|v| std::array::from_fn(|c| sp.apply(c, v[c]))).collect();
            let counted: Vec<bool> = (0..n).map(|i| i % 5 != 2 && i % 11 != 0).collect();
            for len in [0, 5, 8, 13, n] {
                let (jr, sr, cr) = (&j[..len], &shown[..len], &counted[..len]);
                // summed from J with the stretch, or from the shown values:
                // the same bits (scoring and final output agree)
                let from_j = counted_sums(Some(&sp), jr, cr);
                let from_shown = counted_sums(None, sr, cr);
                assert_eq!(from_j.map(f64::to_bits), from_shown.map(f64::to_bits), "len {len}");
                // and the plain sums, up to the order of the additions
                for c in 0..3 {
                    let plain: f64 = sr.iter().zip(cr).filter(|(_, &k)| k).map(|(v, _)| f64::from(v[c])).sum();
                    assert!((from_j[c] - plain).abs() <= 1e-12 * plain.abs().max(1.0), "len {len} c {c}");
                }
            }
        }
        // the guide (METHOD §6): stretched input to the power 1/2.2, 0 where masked out
        let st = ChannelStretch::new([Some((0.1, 0.9)), None, Some((0.05, 0.7))]);
        let gn = Normalize::new(0.0, 1.4);
        let src: Vec<[f32; 3]> = j.iter().map(|v| v.map(|x| x.max(0.0))).collect();
        let gmask: Vec<bool> = (0..n).map(|i| i % 7 != 3).collect();
        for m in [None, Some(&gmask[..])] {
            let mut g = vec![[9f32; 3]; n];
            guide_row(&gn, &st, &src, &mut g, m);
            for i in 0..n {
                for c in 0..3 {
                    let want = if m.is_some_and(|m| !m[i]) {
                        0.0
                    } else {
                        crate::fastmath::pow_pos(st.apply(c, gn.apply(src[i][c])), 1.0 / 2.2)
                    };
                    assert_eq!(g[i][c].to_bits(), want.to_bits(), "{i} {c}");
                }
            }
        }
        // row statistics
        let tr: Vec<f32> = noise.iter().skip(3 * n).take(n).copied().collect();
        let inside: Vec<bool> = noise.iter().skip(4 * n).take(n).map(|v| *v > 0.2).collect();
        let vl: Vec<bool> = noise.iter().skip(5 * n).take(n).map(|v| *v > 0.6).collect();
        let mut st = RowStats::default();
        row_stats(&j, &tr, &inside, &vl, &mut st);
        let (mut lo, mut hi, mut s) = (f32::INFINITY, f32::NEG_INFINITY, [0f64; 4]);
        for i in 0..n {
            if inside[i] {
                lo = lo.min(j[i][0]).min(j[i][1]).min(j[i][2]);
                hi = hi.max(j[i][0]).max(j[i][1]).max(j[i][2]);
                let k = if vl[i] { 0 } else { 2 };
                s[k] += tr[i] as f64;
                s[k + 1] += 1.0;
            }
        }
        assert_eq!((st.lo, st.hi), (lo, hi));
        assert_eq!((st.sums.vl, st.sums.counted), (s[1], s[3]));
        assert!((st.sums.tr_vl - s[0]).abs() < 1e-9 && (st.sums.tr_counted - s[2]).abs() < 1e-9);
        // blend: t~ from r / r_max, the bound and the matting weight
        let rm = [0.0f32, 0.5, 0.0, 2.0];
        let aux: Vec<[f32; 2]> = (0..n).map(|i| [noise[6 * n + i] * 0.5, (i % 4) as f32 - 1.0]).collect();
        let r: Vec<f32> = noise.iter().skip(7 * n).take(n).map(|v| v * 2.0).collect();
        let mut p = r.clone();
        blend_row(&mut p, &aux, &j, &rm, None, true);
        for i in 0..n {
            let t = t_tilde(r[i], aux[i][1], &rm[1..]);
            assert_eq!(p[i].to_bits(), (t * T_SCALE).max(aux[i][0]).to_bits(), "{i}");
        }
    }

    fn st(score: f64, d: Option<f64>) -> TypeStats {
        TypeStats { score, tr_diff: d }
    }

    #[test]
    fn fast_rescores_only_uncertain_choices() {
        // clear winner, safely above the threshold: only it
        let copy = [st(0.01, Some(0.3)), st(0.05, Some(0.3)), st(0.06, Some(0.3))];
        assert_eq!(rescore_candidates(&[0, 1, 2], &copy, Some(0.1)), vec![0]);
        // a near-tie in score: both
        let copy = [st(0.010, Some(0.3)), st(0.012, Some(0.3)), st(0.06, Some(0.3))];
        assert_eq!(rescore_candidates(&[0, 1, 2], &copy, Some(0.1)), vec![0, 1]);
        // the best two might be excluded at full resolution: down to the first safe one
        let copy = [st(0.01, Some(0.11)), st(0.05, Some(0.12)), st(0.09, Some(0.3)), st(0.1, Some(0.3))];
        assert_eq!(rescore_candidates(&[0, 1, 2, 3], &copy, Some(0.1)), vec![0, 1, 2]);
        // never more than FAST_RESCORE
        let copy = [st(0.01, None), st(0.011, None), st(0.012, None), st(0.013, None)];
        assert_eq!(rescore_candidates(&[0, 1, 2, 3], &copy, None).len(), FAST_RESCORE);
        assert!(rescore_candidates(&[], &copy, None).is_empty());
    }

    #[test]
    fn fast_copy_samples_block_centres() {
        // 5 x 7 image, s = 2: rows 1, 3, 4 (last block clipped), columns 1, 3, 5, 6
        let (h, w) = (5usize, 7usize);
        let data: Vec<f32> = (0..h * w).flat_map(|i| [i as f32 / 100.0, 0.5, 0.5]).collect();
        let img = ImageRef::new(&data, h, w).unwrap();
        let mut mask = vec![true; h * w];
        mask[3 * w + 3] = false;
        let vl: Vec<bool> = (0..h * w).map(|i| i / w == 1).collect();
        let small = Small::new(&img, Some(&mask), &vl, 2);
        assert_eq!((small.h, small.w), (3, 4));
        let picked: Vec<usize> = small.data.chunks(3).map(|p| (p[0] * 100.0).round() as usize).collect();
        assert_eq!(picked, vec![8, 10, 12, 13, 22, 24, 26, 27, 29, 31, 33, 34]);
        assert_eq!(small.vl, vec![true, true, true, true, false, false, false, false, false, false, false, false]);
        assert_eq!(small.mask.unwrap().iter().filter(|&&b| !b).count(), 1);
    }
}
