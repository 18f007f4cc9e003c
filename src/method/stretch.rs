//! The contrast stretch of METHOD §3.1 and the guide image of METHOD §6
//! built from it, with the lane layout of the row kernels that apply
//! per-channel stretch constants to interleaved pixels.

use crate::kernels::util::{channel_percentiles, reuse, ChannelStretch, Normalize};
use rayon::prelude::*;

/// Fractions of the guide stretch's percentiles (METHOD §3.1).
pub(crate) const GUIDE_QS: [f64; 2] = [0.01, 0.99];

/// The normalisation and per-channel limits of METHOD §3.1 (METHOD §3.1).
pub(crate) fn stretch_limits(data: &[f32], mask: Option<&[bool]>) -> (Normalize, ChannelStretch) {
    let norm = Normalize::masked(data, mask);
    let p = channel_percentiles(data, mask, &GUIDE_QS, |_, v| norm.apply(v));
    let limits = p.map(|p| match (p.first(), p.get(1)) {
        (Some(&lo), Some(&hi)) if hi - lo > 1e-12 => Some((lo, hi)),
        _ => None,
    });
    (norm, ChannelStretch::new(limits))
}

#[cfg(any(test, feature = "internals"))]
/// The contrast stretch of METHOD §3.1 (METHOD §3.1): global min-max, then
/// per channel between its 1% and 99% percentiles, clipped to [0, 1].
/// Statistics over masked-in pixels (all without a mask), applied to all.
pub fn stretch_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let (norm, st) = stretch_limits(data, mask);
    st.map_rgb(data, |v| norm.apply(v))
}

#[cfg(any(test, feature = "internals"))]
/// The guide of METHOD §6: the stretched input raised to 1/2.2, 0 on masked-out pixels.
pub fn guide_image(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    guide_image_into(data, mask, Vec::new())
}

/// [`guide_image`] written into `buf` when it has the right length (a
/// [`Buffers`] plane from an earlier frame: every value is overwritten),
/// else into a new buffer.
pub(crate) fn guide_image_into(data: &[f32], mask: Option<&[bool]>, buf: Vec<f32>) -> Vec<f32> {
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
/// step 1) raised to 1/2.2 ([`crate::kernels::fastmath::pow_pos`]), 0 where `mask`
/// is false. Compiled for baseline x86-64, AVX2 and AVX-512, picked at
/// run time; the same bits on each (METHOD appendix, same bits on every CPU, F7).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
pub(crate) fn guide_row(norm: &Normalize, st: &ChannelStretch, src: &[[f32; 3]], out: &mut [[f32; 3]], mask: Option<&[bool]>) {
    let gamma = 1.0 / 2.2;
    let map = |v: f32, lo: f64, inv: f64, on: bool| -> f32 {
        let x = norm.apply(v);
        let s = ((x as f64 - lo) * inv).clamp(0.0, 1.0) as f32;
        crate::kernels::fastmath::pow_pos(if on { s } else { x }, gamma)
    };
    let tail = |c: usize, x: f32| crate::kernels::fastmath::pow_pos(st.apply(c, norm.apply(x)), gamma);
    map_lanes(st, src, out, map, tail);
    if let Some(m) = mask {
        for (o, &k) in out.iter_mut().zip(m) {
            if !k {
                *o = [0.0; 3];
            }
        }
    }
}

/// Values per run of [`map_lanes`] and [`sum_lanes`]: 8 pixels of 3 channels.
pub(crate) const LANES: usize = 24;

/// The stretch constants of a run of [`LANES`] interleaved values (lane k
/// holds channel k % 3): lo, 1 / (hi - lo), and whether the channel is
/// stretched (lo 0 and 1 when not).
#[inline(always)]
pub(crate) fn lane_constants(st: &ChannelStretch) -> ([f64; LANES], [f64; LANES], [bool; LANES]) {
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
pub(crate) fn map_lanes<M, T>(st: &ChannelStretch, src: &[[f32; 3]], out: &mut [[f32; 3]], map: M, tail: T)
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

