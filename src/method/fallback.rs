//! Do no harm (METHOD §12.5): how far each restored colour can be trusted,
//! a per-photo `unreliable` flag, and a blend of the displayed colours
//! toward a balance of the input where trust is low.
//!
//! Two signals, both measured on the ground-truth renders of
//! `benches/truth.py` (METHOD §12.5 has the numbers):
//!
//! - **veil excess**, per photo: the share of object pixels where the
//!   estimated veil (1 - t_c) A_c exceeds the observed light I_c by more than
//!   the noise. The model cannot produce such a pixel with a non-negative
//!   radiance, so the estimated transmission or type is wrong for it; a
//!   large share means the whole photo's colours are suspect (a type too
//!   clear, red amplified into magenta).
//! - **noise angle**, per pixel: the angle the image noise, amplified by
//!   1/t_c and the white-balance gains, makes with the displayed colour.
//!   Where it is large, a channel is below the noise floor and its colour
//!   is a guess.

use crate::kernels::util::zip3;
use crate::method::image::ImageRef;
use crate::method::profile::{gains_from, PowerSums, SOG_P};
use crate::method::recover::Recovery;
use crate::method::veiling::water_coloured;
use crate::method::water::WaterType;
use rayon::prelude::*;

/// Veil excess below which a photo is trusted fully (METHOD §12.5).
pub const EXCESS_LO: f64 = 0.02;
/// Veil excess at which the photo's colours fall back fully.
pub const EXCESS_HI: f64 = 0.2;
/// Veil excess above which the photo is flagged `unreliable`.
pub const EXCESS_FLAG: f64 = 0.3;
/// A `fallback_share` from which a photo's colours are the input's balance
/// throughout (the progress line and the report say so).
pub const BALANCED: f64 = 0.995;
/// Noise angle (radians) at which a pixel's local confidence is 1/2.
pub const THETA0: f64 = 0.15;
/// Largest share of a pixel's colour that low local confidence alone moves
/// toward the fallback.
pub const LOCAL_WEIGHT: f64 = 0.3;
/// A channel value (linear) a pixel holds light in: 0.003, about 10 of
/// 255 in 8-bit sRGB, a few quantisation steps.
pub const LIT: f32 = 0.003;
/// The share of the object pixels that must hold light ([`LIT`]) in each
/// channel; below it the channel is empty and its restored colour a guess,
/// when another channel has that share at [`BRIGHT`].
pub const LIT_SHARE: f64 = 0.1;
/// Ten times [`LIT`]: a channel this bright on a tenth of the objects says
/// the photo is exposed, so a channel without light was taken by the water.
pub const BRIGHT: f32 = 0.03;
/// At most this many interior pixels are sampled for the noise estimate.
const NOISE_SAMPLES: usize = 1 << 20;

/// What the trust step found: the confidence map and the veil excess.
#[derive(Debug, Clone)]
pub struct Trust {
    /// per pixel, in [0, 1]: local confidence times (1 - the photo's fallback weight)
    pub confidence: Vec<f32>,
    /// share of object pixels whose estimated veil exceeds the observed light
    pub veil_excess: f64,
    /// with the blend: the mean over every pixel of its weight w (step 4),
    /// the share of the shown colour that is the input's balance rather than
    /// the restoration's; None without the blend
    pub fallback_share: Option<f64>,
    /// a channel of the input holds almost no light on the objects (fewer
    /// than [`LIT_SHARE`] of them have [`LIT`] of it) while another is
    /// exposed (that share has [`BRIGHT`] of it): flag `channel_empty`
    pub channel_empty: bool,
}

impl Trust {
    /// Whether the photo is to be flagged `unreliable`.
    pub fn unreliable(&self) -> bool {
        self.veil_excess > EXCESS_FLAG
    }

    /// The flags the trust step raises, in their order: `unreliable`,
    /// `channel_empty`.
    pub fn flags(&self) -> impl Iterator<Item = crate::method::params::Flag> {
        use crate::method::params::Flag;
        [(self.unreliable(), Flag::Unreliable), (self.channel_empty, Flag::ChannelEmpty)]
            .into_iter()
            .filter_map(|(raised, f)| raised.then_some(f))
    }
}

/// The standard deviation of 8-bit sRGB quantisation at the linear value
/// `v` (METHOD §12.5 step 3): a code step of 1/255, uniform (1/sqrt 12),
/// taken through the slope of the sRGB curve there, dI/dV = 1/12.92 in
/// its linear part, else (2.4 / 1.055) v^(1.4 / 2.4). The coarsest steps a
/// photo's values come in: a smooth JPEG whose measured noise is 0 still
/// has them.
pub fn quantisation_sigma(v: f32) -> f64 {
    // a table of 8192 intervals over [0, 1], interpolated linearly (within
    // 2e-5 of the formula from 0.001 up): the trust step asks three times a
    // pixel, where a power each would cost as much as the rest of the step
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    const N: usize = 8192;
    let table = TABLE.get_or_init(|| {
        const STEP: f64 = 1.0 / (255.0 * 3.464_101_615_137_754_5);
        (0..=N)
            .map(|k| {
                let v = k as f64 / N as f64;
                STEP * if v <= 0.003_130_8 { 1.0 / 12.92 } else { 2.4 / 1.055 * v.powf(1.4 / 2.4) }
            })
            .collect()
    });
    let x = f64::from(v).clamp(0.0, 1.0) * N as f64;
    let k = (x as usize).min(N - 1);
    match (table.get(k), table.get(k + 1)) {
        (Some(a), Some(b)) => a + (x - k as f64) * (b - a),
        _ => 0.0,
    }
}

/// Per-channel noise standard deviation of `img` (METHOD §12.5): the median
/// absolute response of the 3x3 kernel [[1,-2,1],[-2,4,-2],[1,-2,1]] (which
/// cancels planes and has gain 6 on white noise), over the interior pixels
/// (on a regular grid of at most 2^20 of them), divided by 6 x 0.6745
/// (Immerkaer's estimator made robust to edges by the median).
pub fn noise_sigma(img: &ImageRef) -> [f64; 3] {
    let (h, w) = (img.height, img.width);
    if h < 3 || w < 3 {
        return [0.0; 3];
    }
    let interior = (h - 2) * (w - 2);
    let step = ((interior as f64 / NOISE_SAMPLES as f64).sqrt().ceil() as usize).max(1);
    let d = img.data;
    let at = |y: usize, x: usize, c: usize| d.get((y * w + x) * 3 + c).map_or(0.0, |&v| f64::from(v));
    let ys: Vec<usize> = (1..h - 1).step_by(step).collect();
    let cols = (w - 2).div_ceil(step);
    // one buffer of the grid's exact size for the three channels, filled
    // by rows in parallel at fixed places: the same values, and the same
    // median, whatever the thread count
    let mut r = vec![0f64; ys.len() * cols];
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        r.par_chunks_mut(cols).zip(ys.par_iter()).for_each(|(row, &y)| {
            for (v, x) in row.iter_mut().zip((1..w - 1).step_by(step)) {
                let corners = at(y - 1, x - 1, c) + at(y - 1, x + 1, c) + at(y + 1, x - 1, c) + at(y + 1, x + 1, c);
                let edges = at(y - 1, x, c) + at(y + 1, x, c) + at(y, x - 1, c) + at(y, x + 1, c);
                *v = (corners - 2.0 * edges + 4.0 * at(y, x, c)).abs();
            }
        });
        *o = median(&mut r) / (6.0 * 0.6745);
    }
    out
}

/// The median of `v` (the mean of the two middle values for an even count; 0 when empty).
pub(crate) fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let (_, &mut hi, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        return hi;
    }
    let lo = v.get(..n / 2).unwrap_or_default().iter().copied().fold(f64::NEG_INFINITY, f64::max);
    0.5 * (lo + hi)
}

/// t_c of METHOD §7 (`Recovery::channel_t` of the clamped t_B) for a row
/// of t_B into `out`: a loop the compiler vectorizes (AVX2 where the CPU
/// has it, picked at run time; the same bits either way,
/// [`crate::kernels::fastmath`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn row_t(rec: &Recovery, t_b: &[f32], out: &mut [[f32; 3]]) {
    for (o, &t) in out.iter_mut().zip(t_b) {
        *o = rec.channel_t(rec.clamp_tb(t));
    }
}

/// Per-row sums of the first pass, combined in row order.
#[derive(Default, Clone, Copy)]
struct RowSums {
    objects: f64,
    excess: f64,
    /// object pixels with at least [`LIT`] of each channel
    lit: [f64; 3],
    /// object pixels with at least [`BRIGHT`] of each channel
    bright: [f64; 3],
    input: PowerSums,
    radiance: PowerSums,
}

/// The per-photo terms of the trust step (METHOD §12.5) for one type and
/// veiling light: the recovery, A and the image noise.
struct Terms {
    rec: Recovery,
    af: [f64; 3],
    sigma: [f64; 3],
}

impl Terms {
    fn new(a: [f32; 3], wt: &WaterType, sigma: [f64; 3]) -> Self {
        Self {
            rec: Recovery::new(a, wt),
            af: a.map(f64::from),
            sigma,
        }
    }

    /// t_c of METHOD §7 (already clamped) and the raw radiance
    /// J_c = A_c + (I_c - A_c) / t_c of input pixel `p`, before the
    /// artifact clamp.
    fn pixel(&self, p: &[f32], t: [f32; 3]) -> ([f64; 3], [f64; 3]) {
        let t = t.map(f64::from);
        let i = [0, 1, 2].map(|c| f64::from(p.get(c).copied().unwrap_or(0.0)));
        let j = zip3(zip3(self.af, i, |a, i| (a, i)), t, |(a, i), t| a + (i - a) / t);
        (t, j)
    }

    /// Whether the estimated veil exceeds the observed light beyond the
    /// noise: t_c J_c = I_c - (1 - t_c) A_c, the light left after the veil.
    fn exceeds(&self, t: &[f64; 3], j: &[f64; 3]) -> bool {
        t.iter().zip(j).zip(&self.sigma).any(|((&t, &j), &s)| t * j < -s)
    }
}

/// The photo's terms of the blend (METHOD §12.5 steps 3-4): the display's
/// gains g, the input's own balance k, the photo's fallback weight and
/// which channels' noise the quantisation floor can exceed.
struct Shade {
    g: [f64; 3],
    k: [f64; 3],
    w_photo: f64,
    floored: [bool; 3],
    /// whether A has water's colour (METHOD §3); when not, nothing of the restoration is trusted
    water: bool,
}

impl Shade {
    fn new(terms: &Terms, radiance: &PowerSums, input: &PowerSums, veil_excess: f64) -> Self {
        let water = water_coloured(terms.af.map(|v| v as f32));
        Self {
            g: gains_from(radiance.color(SOG_P)),
            k: gains_from(input.color(SOG_P)),
            // a veil of no water's colour (METHOD §3): the model does not hold, nothing of it is trusted
            w_photo: if water { ((veil_excess - EXCESS_LO) / (EXCESS_HI - EXCESS_LO)).clamp(0.0, 1.0) } else { 1.0 },
            floored: terms.sigma.map(|s| s < quantisation_sigma(1.0)),
            water,
        }
    }

    /// The local confidence of input pixel `p` with t_c `t` and raw
    /// radiance `j`, and, when `blend`, its displayed colour `d` moved
    /// toward the input's balance: returns (confidence, blend weight).
    fn apply(&self, terms: &Terms, p: &[f32], t: &[f64; 3], j: &[f64; 3], d: &mut [f32], blend: bool) -> (f32, f64) {
        let g = &self.g;
        let shown = g.iter().zip(j).map(|(&g, &j)| (g * j.max(0.0)).powi(2)).sum::<f64>().sqrt().max(1e-6);
        // the floor is looked up only for a channel whose noise it can exceed
        let noise: f64 = p
            .iter()
            .zip(terms.sigma.iter().zip(&self.floored))
            .zip(g.iter().zip(t))
            .map(|((&v, (&s, &low)), (&gc, &tc))| {
                let s = if low { s.max(quantisation_sigma(v)) } else { s };
                (gc * s / tc).powi(2)
            })
            .sum();
        let theta = (2.0 / 3.0 * noise).sqrt() / shown;
        let local = 1.0 / (1.0 + (theta / THETA0).powi(2));
        let confidence = (local * (1.0 - self.w_photo)) as f32;
        if !blend {
            return (confidence, 0.0);
        }
        let wgt = 1.0 - (1.0 - self.w_photo) * (1.0 - LOCAL_WEIGHT * (1.0 - local));
        let i = [0, 1, 2].map(|c| f64::from(p.get(c).copied().unwrap_or(0.0)));
        let base = zip3(i, self.k, |i, k| (i * k).max(0.0));
        let sum_d: f64 = d.iter().map(|&v| f64::from(v)).sum();
        let [b0, b1, b2] = base;
        let scale = sum_d / (b0 + b1 + b2).max(1e-9);
        for (v, &b) in d.iter_mut().zip(&base) {
            let x = (1.0 - wgt) * f64::from(*v) + wgt * b * scale;
            *v = x.clamp(0.0, 1.0) as f32;
        }
        (confidence, wgt)
    }
}

/// The first pass of the trust step (METHOD §12.5) over the object pixels
/// (`objects(i)`): their number, how many the veil exceeds, the input's
/// power sums and, given `radiance`, the clamped radiance's. `tb_row(y,
/// row)` writes row y's t_B. Per row, combined in row order.
fn first_pass(
    img: &ImageRef,
    objects: &(dyn Fn(usize) -> bool + Sync),
    terms: &Terms,
    tb_row: &(dyn Fn(usize, &mut [f32]) + Sync),
    radiance: Option<&[f32]>,
) -> RowSums {
    let w = img.width;
    let rows: Vec<RowSums> = (0..img.height)
        .into_par_iter()
        .map_init(
            || (vec![0f32; w], vec![[0f32; 3]; w]),
            |(tb, tc), y| {
                let mut s = RowSums::default();
                tb_row(y, tb);
                row_t(&terms.rec, tb, tc);
                for (i, &t) in (y * w..(y + 1) * w).zip(tc.iter()) {
                    if !objects(i) {
                        continue;
                    }
                    let Some(p @ &[p0, p1, p2]) = img.data.get(3 * i..3 * i + 3) else {
                        continue;
                    };
                    let (t, j) = terms.pixel(p, t);
                    s.objects += 1.0;
                    for ((l, b), &v) in s.lit.iter_mut().zip(s.bright.iter_mut()).zip(p) {
                        *l += f64::from(u8::from(v >= LIT));
                        *b += f64::from(u8::from(v >= BRIGHT));
                    }
                    if terms.exceeds(&t, &j) {
                        s.excess += 1.0;
                    }
                    s.input.push([p0, p1, p2]);
                    if let Some(&[r0, r1, r2]) = radiance.and_then(|r| r.get(3 * i..3 * i + 3)) {
                        s.radiance.push([r0, r1, r2]);
                    }
                }
                s
            },
        )
        .collect();
    rows.iter().fold(RowSums::default(), |mut acc, r| {
        acc.objects += r.objects;
        acc.excess += r.excess;
        for (a, l) in acc.lit.iter_mut().chain(acc.bright.iter_mut()).zip(r.lit.iter().chain(&r.bright)) {
            *a += l;
        }
        acc.input.add(&r.input);
        acc.radiance.add(&r.radiance);
        acc
    })
}

/// The trust step of METHOD §12.5 for the chosen type `wt` with veiling
/// light `a`: the returned t_B `t_b`, the clamped radiance `radiance` and
/// the displayed image `image` (blended in place when `blend`).
/// `objects(i)` says whether pixel i is an object pixel (masked-in, not
/// VL). Sums are per row in f64, combined in row order, so the result does
/// not depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub fn trust(
    img: &ImageRef,
    objects: &(dyn Fn(usize) -> bool + Sync),
    a: [f32; 3],
    wt: &WaterType,
    t_b: &[f32],
    radiance: &[f32],
    image: &mut [f32],
    blend: bool,
) -> Trust {
    let w = img.width;
    let terms = Terms::new(a, wt, noise_sigma(img));
    let scratch = || vec![[0f32; 3]; w];
    let tb_row = |y: usize| t_b.get(y * w..(y + 1) * w).unwrap_or_default();
    let total = first_pass(img, objects, &terms, &|y, row| row.iter_mut().zip(tb_row(y)).for_each(|(o, &v)| *o = v), Some(radiance));
    let veil_excess = if total.objects > 0.0 { total.excess / total.objects } else { 0.0 };
    // one channel without light where another has plenty: the water took
    // it (a photo dark in every channel is underexposed, not this)
    let share = LIT_SHARE * total.objects;
    let channel_empty =
        total.objects > 0.0 && total.lit.iter().any(|&l| l < share) && total.bright.iter().any(|&b| b >= share);
    // the display's gains (METHOD §12.1) and the input's own shades-of-gray balance
    let shade = Shade::new(&terms, &total.radiance, &total.input, veil_excess);
    let mut confidence = vec![0f32; t_b.len()];
    // per row, the sum of the blend weights, added in row order below
    let weights: Vec<f64> = confidence
        .par_chunks_mut(w)
        .zip(image.par_chunks_mut(3 * w))
        .enumerate()
        .map_init(scratch, |tc, (y, (conf_row, img_row))| {
            let mut row_weight = 0.0;
            row_t(&terms.rec, tb_row(y), tc);
            let in_row = img.data.get(3 * y * w..3 * (y + 1) * w).unwrap_or_default();
            for (((cf, d), &t), p) in conf_row.iter_mut().zip(img_row.chunks_exact_mut(3)).zip(tc.iter()).zip(in_row.chunks_exact(3)) {
                let (t, j) = terms.pixel(p, t);
                let (c, wgt) = shade.apply(&terms, p, &t, &j, d, blend);
                *cf = c;
                row_weight += wgt;
            }
            row_weight
        })
        .collect();
    if blend && !shade.water {
        // no water between camera and scene (or an A that is not the water's,
        // METHOD §3): nothing was dehazed, so the brightness falls back too;
        // the input's balance at the display's overall brightness
        input_balance(img, objects, &shade.k, image);
    }
    let fallback_share = blend.then(|| weights.iter().sum::<f64>() / t_b.len().max(1) as f64);
    Trust { confidence, veil_excess, fallback_share, channel_empty }
}

/// `image` replaced by the input balanced by its gains `k`, scaled so that
/// its object pixels (`objects(i)`) sum to what the displayed ones did
/// (METHOD §12.5, a veil of no water's colour). Per-row sums combined in
/// row order: the same at any thread count.
fn input_balance(img: &ImageRef, objects: &(dyn Fn(usize) -> bool + Sync), k: &[f64; 3], image: &mut [f32]) {
    let w = img.width.max(1);
    let rows: Vec<(f64, f64)> = image
        .par_chunks(3 * w)
        .enumerate()
        .map(|(y, row)| {
            let mut sums = (0.0, 0.0);
            for (x, d) in row.chunks_exact(3).enumerate() {
                let i = y * w + x;
                if !objects(i) {
                    continue;
                }
                let p = img.data.get(3 * i..3 * i + 3).unwrap_or(&[0.0; 3]);
                sums.0 += d.iter().map(|&v| f64::from(v)).sum::<f64>();
                sums.1 += p.iter().zip(k).map(|(&v, &kc)| (f64::from(v) * kc).max(0.0)).sum::<f64>();
            }
            sums
        })
        .collect();
    let (shown, balanced) = rows.iter().fold((0.0, 0.0), |acc, r| (acc.0 + r.0, acc.1 + r.1));
    let scale = if balanced > 0.0 { shown / balanced } else { 1.0 };
    image.par_chunks_mut(3).zip(img.data.par_chunks(3)).for_each(|(d, p)| {
        for ((dc, &pc), &kc) in d.iter_mut().zip(p).zip(k) {
            *dc = ((f64::from(pc) * kc).max(0.0) * scale).clamp(0.0, 1.0) as f32;
        }
    });
}

/// The trust step (METHOD §12.5) at a sample of the object pixels
/// (`objects(i)`): `samples` are their indices, `shown` their displayed
/// colours, blended in place as [`trust`] blends them. `tb_row(y, row)`
/// writes row y's t_B and `radiance` are the power sums of the clamped
/// radiance over every object pixel: the veil excess and the input's
/// balance are the whole image's, so the colours are the same as the
/// whole image's trust step gives there (up to the order of additions).
/// `sigma` is the photo's noise ([`noise_sigma`] of the photo itself:
/// the image here may be a sampled copy, whose neighbours are further
/// apart). Serves the central type choice (METHOD §12.2), which compares
/// types by their displays.
#[allow(clippy::too_many_arguments)]
pub fn blend_samples(
    img: &ImageRef,
    objects: &(dyn Fn(usize) -> bool + Sync),
    (a, wt): ([f32; 3], &WaterType),
    sigma: [f64; 3],
    tb_row: &(dyn Fn(usize, &mut [f32]) + Sync),
    radiance: &PowerSums,
    samples: &[usize],
    shown: &mut [[f32; 3]],
) {
    let terms = Terms::new(a, wt, sigma);
    let total = first_pass(img, objects, &terms, tb_row, None);
    let veil_excess = if total.objects > 0.0 { total.excess / total.objects } else { 0.0 };
    let shade = Shade::new(&terms, radiance, &total.input, veil_excess);
    let w = img.width.max(1);
    let mut row = vec![0f32; w];
    let mut row_y = usize::MAX;
    for (&i, d) in samples.iter().zip(shown.iter_mut()) {
        // samples come in raster order: each row's t_B is written once
        if i / w != row_y {
            row_y = i / w;
            tb_row(row_y, &mut row);
        }
        let t = terms.rec.channel_t(terms.rec.clamp_tb(row.get(i % w).copied().unwrap_or(1.0)));
        let p = img.data.get(3 * i..3 * i + 3).unwrap_or(&[0.0; 3]);
        let (t, j) = terms.pixel(p, t);
        shade.apply(&terms, p, &t, &j, d, true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_sigma_finds_the_noise_of_a_smooth_image() {
        // a linear ramp (cancelled by the kernel) plus a +-s checkerboard in
        // red only: the kernel's response to (-1)^(x+y) is 16 s everywhere,
        // so sigma_R = 16 s / (6 x 0.6745) and G, B (ramps) are 0
        let (h, w, s) = (20, 30, 0.01f32);
        let mut d = vec![0f32; h * w * 3];
        for y in 0..h {
            for x in 0..w {
                let ramp = 0.2 + 0.01 * x as f32 + 0.005 * y as f32;
                let sign = if (x + y) % 2 == 0 { 1.0 } else { -1.0 };
                d[(y * w + x) * 3] = ramp + s * sign;
                d[(y * w + x) * 3 + 1] = ramp;
                d[(y * w + x) * 3 + 2] = 0.5 * ramp;
            }
        }
        let sg = noise_sigma(&ImageRef::new(&d, h, w).unwrap());
        let want = 16.0 * f64::from(s) / (6.0 * 0.6745);
        assert!((sg[0] - want).abs() < 1e-4 * want, "{sg:?} vs {want}");
        assert!(sg[1] < 1e-5 && sg[2] < 1e-5, "{sg:?}");
    }

    fn water(name: &str, br: f64, bg: f64) -> WaterType {
        WaterType { name: name.into(), beta_br: br, beta_bg: bg }
    }

    #[test]
    fn the_quantisation_floor_is_a_code_step_through_the_srgb_slope() {
        // the slope of the sRGB decoding by central differences at the code
        // value V of v, times 1/255/sqrt(12)
        let decode = |x: f64| if x <= 0.04045 { x / 12.92 } else { ((x + 0.055) / 1.055).powf(2.4) };
        let encode = |v: f64| if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        for v in [0.001f64, 0.01, 0.05, 0.2, 0.5, 0.9, 1.0] {
            let (x, h) = (encode(v), 1e-6);
            let want = (decode(x + h) - decode(x - h)) / (2.0 * h) / 255.0 / 12f64.sqrt();
            let got = quantisation_sigma(v as f32);
            assert!((got - want).abs() < 1e-4 * want, "{v}: {got} vs {want}");
        }
        // below 0: the floor of 0
        assert_eq!(quantisation_sigma(-0.5), quantisation_sigma(0.0));
    }

    #[test]
    fn a_clear_flat_scene_keeps_its_colours_but_for_its_quantisation() {
        // t_B = 1 everywhere: t_c = 1, J = I >= 0, no veil excess. A flat
        // image has sigma = 0; its noise is then the 8-bit floor, by hand:
        // q = (1/255/sqrt 12) (2.4/1.055) v^(1.4/2.4) = 0.0012759, 0.0017189,
        // 0.0010072 for v = 0.3, 0.5, 0.2; the gains of J's colour
        // (1.1111, 0.6667, 1.6667), |g J| = 0.57735, so theta = sqrt(2/3 x
        // 6.1410e-6) / 0.57735 = 0.0035046, c = 1 / (1 + (theta / 0.15)^2) =
        // 0.99945 and w = 0.3 (1 - c) = 1.637e-4: D = (0.25, 0.5, 0.75)
        // moves by w toward B' = (0.5, 0.5, 0.5)
        let (h, w) = (4, 5);
        let px = [0.3f32, 0.5, 0.2];
        let d: Vec<f32> = (0..h * w).flat_map(|_| px).collect();
        let img = ImageRef::new(&d, h, w).unwrap();
        let tb = vec![1.0f32; h * w];
        let shown = [0.25f32, 0.5, 0.75].repeat(h * w);
        let mut out = shown.clone();
        let tr = trust(&img, &|_| true, [0.1, 0.4, 0.6], &water("II", 0.2773, 0.7937), &tb, &d, &mut out, true);
        assert_eq!(tr.veil_excess, 0.0);
        assert!(!tr.unreliable());
        assert!(tr.confidence.iter().all(|&c| (c - 0.99945).abs() < 2e-5), "{:?}", tr.confidence[0]);
        for p in out.chunks(3) {
            let want = [0.25 + 1.637e-4 * 0.25, 0.5, 0.75 - 1.637e-4 * 0.25];
            assert!(p.iter().zip(want).all(|(&a, b)| (f64::from(a) - b).abs() < 2e-6), "{p:?}");
        }
        let share = tr.fallback_share.unwrap();
        assert!((share - 1.637e-4).abs() < 1e-6, "{share}");
    }

    #[test]
    fn a_channel_the_water_took_is_empty_when_nine_pixels_in_ten_lack_it_and_another_is_exposed() {
        // 20 object pixels; red at 0.003 (LIT, a few 8-bit codes) in k of
        // them, 0.002 in the rest: empty while k < 2 (10% of 20), not at 2;
        // pixels that are not objects (here the last 20) do not count
        let (h, w) = (8, 5);
        let tb = vec![1.0f32; h * w];
        for (k, empty) in [(0, true), (1, true), (2, false), (20, false)] {
            let d: Vec<f32> = (0..h * w)
                .flat_map(|i| [if i < k || i >= 20 { 0.003f32 } else { 0.002 }, 0.4, 0.5])
                .collect();
            let img = ImageRef::new(&d, h, w).unwrap();
            let mut out = d.clone();
            let tr = trust(&img, &|i| i < 20, [0.01, 0.4, 0.6], &water("II", 0.2773, 0.7937), &tb, &d, &mut out, false);
            assert_eq!(tr.channel_empty, empty, "k = {k}");
        }
        // every channel dark (an underexposed photo, green and blue under
        // 0.03 everywhere): not a channel the water took
        let d: Vec<f32> = (0..h * w).flat_map(|_| [0.002f32, 0.02, 0.029]).collect();
        let img = ImageRef::new(&d, h, w).unwrap();
        let mut out = d.clone();
        let tr = trust(&img, &|i| i < 20, [0.01, 0.4, 0.6], &water("II", 0.2773, 0.7937), &tb, &d, &mut out, false);
        assert!(!tr.channel_empty);
    }

    #[test]
    fn a_veil_brighter_than_the_light_falls_back_to_the_inputs_balance() {
        // red is 0 where A_R = 0.5 and t_R < 1: t_R J_R = -(1 - t_R) 0.5 < 0 = -sigma
        // at every pixel, so veil_excess = 1 > 0.3 (unreliable), w_p = 1 and the
        // output is the input's shades-of-gray balance at the displayed brightness:
        // input (0, 0.4, 0.2) has e = (0, 0.4, 0.2), gains (1 (e_R = 0), 0.5, 1),
        // B = (0, 0.2, 0.2), sum(D) = 0.9 -> B' = (0, 0.45, 0.45); confidence 0
        let (h, w) = (4, 4);
        let d: Vec<f32> = (0..h * w).flat_map(|_| [0.0f32, 0.4, 0.2]).collect();
        let img = ImageRef::new(&d, h, w).unwrap();
        let tb = vec![0.5f32; h * w];
        let radiance = [0.0f32, 0.3, 0.3].repeat(h * w);
        let mut out = [0.2f32, 0.3, 0.4].repeat(h * w);
        let tr = trust(&img, &|_| true, [0.5, 0.6, 0.3], &water("3C", 0.6515, 1.1244), &tb, &radiance, &mut out, true);
        assert_eq!(tr.veil_excess, 1.0);
        assert!(tr.unreliable());
        assert!(tr.confidence.iter().all(|&c| c == 0.0));
        // w_p = 1: w = 1 at every pixel, all of the colour is the balance's
        assert_eq!(tr.fallback_share, Some(1.0));
        for p in out.chunks(3) {
            assert!(p[0].abs() < 1e-6 && (p[1] - 0.45).abs() < 1e-6 && (p[2] - 0.45).abs() < 1e-6, "{p:?}");
        }
        // without the blend the image stays and the findings are the same
        let mut kept = [0.2f32, 0.3, 0.4].repeat(h * w);
        let tr2 = trust(&img, &|_| true, [0.5, 0.6, 0.3], &water("3C", 0.6515, 1.1244), &tb, &radiance, &mut kept, false);
        assert_eq!(kept, [0.2f32, 0.3, 0.4].repeat(h * w));
        assert_eq!(tr2.veil_excess, 1.0);
        assert_eq!(tr2.fallback_share, None);
    }

    #[test]
    fn a_veil_of_no_waters_colour_shows_the_inputs_balance_at_the_displays_brightness() {
        // A = (0.5, 0.4, 0.3): red the most, no water's veil (METHOD §3). The input is
        // one colour (0.2, 0.4, 0.1) at brightness b = 1 (left half) and 1/2 (right):
        // its balance is gray, b v. The display sums to 0.9 on the left, 0.3 on the
        // right (mean 0.6 a pixel), so 3 v (1 + 1/2) / 2 = 0.6: v = 0.2667 on the left,
        // 0.1333 on the right, not the displayed brightness of each pixel (0.3 / 0.1)
        let (h, w) = (4, 4);
        let b = |x: usize| if x < w / 2 { 1.0f32 } else { 0.5 };
        let d: Vec<f32> = (0..h * w).flat_map(|i| [0.2 * b(i % w), 0.4 * b(i % w), 0.1 * b(i % w)]).collect();
        let img = ImageRef::new(&d, h, w).unwrap();
        let tb = vec![0.8f32; h * w];
        let radiance = d.clone();
        let mut out: Vec<f32> = (0..h * w).flat_map(|i| if b(i % w) == 1.0 { [0.3f32; 3] } else { [0.1; 3] }).collect();
        let tr = trust(&img, &|_| true, [0.5, 0.4, 0.3], &water("3C", 0.6515, 1.1244), &tb, &radiance, &mut out, true);
        assert!(tr.confidence.iter().all(|&c| c == 0.0));
        assert_eq!(tr.fallback_share, Some(1.0));
        for (i, p) in out.chunks(3).enumerate() {
            let v = if b(i % w) == 1.0 { 0.6 / 2.25 } else { 0.3 / 2.25 };
            assert!(p.iter().all(|&x| (x - v).abs() < 1e-5), "{i}: {p:?} against {v}");
        }
        // the same veil coloured as water (red the least): the per-pixel blend, its brightness the display's
        let mut out: Vec<f32> = (0..h * w).flat_map(|i| if b(i % w) == 1.0 { [0.3f32; 3] } else { [0.1; 3] }).collect();
        trust(&img, &|_| true, [0.3, 0.4, 0.5], &water("3C", 0.6515, 1.1244), &tb, &radiance, &mut out, true);
        for (i, p) in out.chunks(3).enumerate() {
            let sum = if b(i % w) == 1.0 { 0.9 } else { 0.3 };
            assert!((p.iter().sum::<f32>() - sum).abs() < 1e-5, "{i}: {p:?}");
        }
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut []), 0.0);
    }
}
