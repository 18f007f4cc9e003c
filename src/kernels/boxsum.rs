//! Exact streaming box sums: the clipped-window means of METHOD §6 over
//! several channels at once, in row bands that run in parallel.
//!
//! Every value is first rounded to an integer multiple of 2^-k (a per-channel
//! scale 2^k chosen from a bound on the values and the largest number of
//! terms a sum can hold, so that every partial sum stays below 2^52). Sums
//! of such values are exact in f64, so running sums (add the row entering
//! the window, subtract the row leaving it) never drift, and the result
//! does not depend on where the bands start, in which direction they run,
//! or on the number of threads. The rounding error of a window mean is at
//! most 2^-(k+1), i.e. below bound * 2^-(51 - log2 terms): 1e-8 of the
//! bound for a 12 MP image.
//!
//! The image is streamed once per band: a band keeps the column sums of
//! the window rows (vertical pass) and forms each output row's horizontal
//! window sums from their prefix sums, so no full-size intermediate plane
//! exists. The caller supplies the rows (`source`, which may compute them
//! on the fly, e.g. products of planes) and consumes the means row by row
//! (`sink`).

use rayon::prelude::*;
use std::ops::Range;

/// 1.5 * 2^52: adding and subtracting it rounds |x| < 2^51 to an integer.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;
/// Partial sums are kept below this magnitude (exact in f64).
const SUM_LIMIT: f64 = 2_251_799_813_685_248.0; // 2^51

/// Geometry of a box filter: image size and window radius.
#[derive(Debug, Clone, Copy)]
pub struct BoxGeom {
    /// rows
    pub h: usize,
    /// columns
    pub w: usize,
    /// window radius: the window is (2r + 1) x (2r + 1), clipped to the image
    pub r: usize,
}

impl BoxGeom {
    /// The largest number of values a partial sum can hold: a row of column
    /// sums (prefix sums run over the whole row).
    fn max_terms(&self) -> f64 {
        ((2 * self.r + 1).min(self.h) * self.w).max(1) as f64
    }

    /// The quantisation scale 2^k for values with |v| <= `bound`: the largest
    /// power of two keeping every partial sum below 2^51 (1 for a zero or
    /// non-finite bound).
    pub fn scale(&self, bound: f64) -> f64 {
        if !(bound.is_finite() && bound > 0.0) {
            return 1.0;
        }
        let k = (SUM_LIMIT / (bound * self.max_terms())).log2().floor();
        2f64.powi(k.clamp(-1000.0, 1000.0) as i32)
    }

    /// Number of window rows for output row `y` (the window clipped to the image).
    fn rows_in_window(&self, y: usize) -> usize {
        (y + self.r).min(self.h.saturating_sub(1)) + 1 - y.saturating_sub(self.r)
    }
}

/// Up to `bands` contiguous row ranges covering 0..h, each at least
/// `min_rows` rows (fewer bands for small images); at least one range.
pub fn band_ranges(h: usize, bands: usize, min_rows: usize) -> Vec<Range<usize>> {
    let nb = bands.min(h / min_rows.max(1)).max(1);
    (0..nb).map(|b| b * h / nb..(b + 1) * h / nb).collect()
}

/// Splits a row-major buffer holding `row_len` items per row into the
/// (contiguous, increasing) bands of [`band_ranges`].
pub fn split_bands<'a, T>(
    buf: &'a mut [T],
    row_len: usize,
    bands: &[Range<usize>],
) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(bands.len());
    let mut rest = buf;
    for b in bands {
        let (head, tail) = rest.split_at_mut((b.len() * row_len).min(rest.len()));
        out.push(head);
        rest = tail;
    }
    out
}

/// A band's rows with the usual sink state: (its first row, its slice).
pub type BandSlice<'a, T> = (Range<usize>, (usize, &'a mut [T]));

/// Pairs each band with (its first row, its slice): the usual sink state.
pub fn with_starts<'a, T>(ranges: &[Range<usize>], slices: Vec<&'a mut [T]>) -> Vec<BandSlice<'a, T>> {
    ranges
        .iter()
        .cloned()
        .zip(slices)
        .map(|(r, s)| (r.clone(), (r.start, s)))
        .collect()
}

/// The bits of [`ROUND_MAGIC`]: f64 values in (2^52, 2^53) have one
/// exponent, so their bits grow by one per integer step.
const MAGIC_BITS: i64 = 0x4338_0000_0000_0000;

/// round(v s) as an integer (ties to even), for |v s| < 2^51 (the sums
/// use wrapping integer operations: values out of that range give wrong
/// sums, never a panic).
#[inline(always)]
fn quantize(v: f64, s: f64) -> i64 {
    ((v * s + ROUND_MAGIC).to_bits() as i64).wrapping_sub(MAGIC_BITS)
}

/// An integer of magnitude below 2^51 as f64 (exact), without the
/// general conversion that baseline x86-64 and AVX2 lack in SIMD form.
#[inline(always)]
fn to_f64(i: i64) -> f64 {
    f64::from_bits(i.wrapping_add(MAGIC_BITS) as u64) - ROUND_MAGIC
}

/// Box means of `C` channels over the rows of each band of `work`, each band
/// with its own state `O` (typically the band's slices of the output
/// buffers). `source(y, row)` fills `row` (w entries) with the values of
/// row y; `sink(state, y, means)` receives the window means of row y
/// (w entries). Channel c's values must satisfy `|v| <= bounds[c]` (else sums
/// may lose exactness; never a panic). The first band runs downwards, the
/// last (of two or more) upwards, so both start at an image border where
/// the window is half empty; bands in between start with a full window.
/// Returns the band states in band order.
pub fn box_means<const C: usize, O, S, K>(
    geom: BoxGeom,
    bounds: [f64; C],
    work: Vec<(Range<usize>, O)>,
    source: &S,
    sink: &K,
) -> Vec<O>
where
    O: Send,
    S: Fn(usize, &mut [[f64; C]]) + Sync,
    K: Fn(&mut O, usize, &[[f64; C]]) + Sync,
{
    let scale = bounds.map(|b| geom.scale(b));
    let nbands = work.len();
    work.into_par_iter()
        .enumerate()
        .map(|(i, (rows, mut state))| {
            let down = i == 0 || i + 1 < nbands;
            run_band(geom, scale, rows, down, &mut state, source, sink);
            state
        })
        .collect()
}

/// One band, sequentially (see [`box_means`]). Compiled for baseline
/// x86-64 and for AVX2, picked at run time (the same bits either way:
/// no fused multiply-add, METHOD appendix, same bits on every CPU).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn run_band<const C: usize, O, S, K>(
    geom: BoxGeom,
    scale: [f64; C],
    rows: Range<usize>,
    down: bool,
    state: &mut O,
    source: &S,
    sink: &K,
) where
    S: Fn(usize, &mut [[f64; C]]),
    K: Fn(&mut O, usize, &[[f64; C]]),
{
    let BoxGeom { h, w, r } = geom;
    if rows.is_empty() || w == 0 {
        return;
    }
    let inv_scale = scale.map(|s| 1.0 / s);
    let inv_nx: Vec<f64> = (0..w)
        .map(|x| 1.0 / ((x + r).min(w - 1) + 1 - x.saturating_sub(r)) as f64)
        .collect();
    // column sums and their prefix sums in units of 2^-k per channel: exact
    // integers below 2^51 (see the module documentation), so integer adds
    // (one cycle of latency along the prefix chain, against four for f64)
    // give the same values the f64 sums did
    let mut col = vec![[0i64; C]; w];
    let mut enter = vec![[0f64; C]; w];
    let mut leave = vec![[0f64; C]; w];
    // Prefix sums of the column sums, padded so that for every x the window
    // sum is ext[x + 2r + 1] - ext[x]: r zeros, P[0..=w], then r copies of P[w].
    let mut ext = vec![[0i64; C]; w + 2 * r + 1];
    let mut means = vec![[0f64; C]; w];
    let first = if down { rows.start } else { rows.end - 1 };
    for y in first.saturating_sub(r)..=(first + r).min(h - 1) {
        source(y, &mut enter);
        for (c, v) in col.iter_mut().zip(&enter) {
            for ((cc, vv), s) in c.iter_mut().zip(v).zip(&scale) {
                *cc = cc.wrapping_add(quantize(*vv, *s));
            }
        }
    }
    let order: Box<dyn Iterator<Item = usize>> = if down {
        Box::new(rows.clone())
    } else {
        Box::new(rows.clone().rev())
    };
    let mut order = order.peekable();
    while let Some(y) = order.next() {
        // horizontal window sums from the padded prefix sums
        let (_, body) = ext.split_at_mut(r);
        let (body, pad) = body.split_at_mut(w + 1);
        let mut acc = [0i64; C];
        for (p, c) in body.iter_mut().skip(1).zip(&col) {
            for ((a, cc), pp) in acc.iter_mut().zip(c).zip(p.iter_mut()) {
                *a = a.wrapping_add(*cc);
                *pp = *a;
            }
        }
        pad.iter_mut().for_each(|p| *p = acc);
        let fy = 1.0 / geom.rows_in_window(y) as f64;
        let g = inv_scale.map(|s| s * fy);
        let upper = ext.iter().skip(2 * r + 1);
        for (((m, u), l), ix) in means.iter_mut().zip(upper).zip(&ext).zip(&inv_nx) {
            for (((mm, uu), ll), gg) in m.iter_mut().zip(u).zip(l).zip(&g) {
                *mm = to_f64(uu.wrapping_sub(*ll)) * ix * gg;
            }
        }
        sink(state, y, &means);
        // slide the window to the next row of the band: one row enters, one leaves
        if order.peek().is_some() {
            let (inc, dec) = if down {
                ((y + r + 1 < h).then_some(y + r + 1), y.checked_sub(r))
            } else {
                (y.checked_sub(r + 1), (y + r < h).then_some(y + r))
            };
            match (inc, dec) {
                (Some(a), Some(b)) => {
                    source(a, &mut enter);
                    source(b, &mut leave);
                    for ((c, v), u) in col.iter_mut().zip(&enter).zip(&leave) {
                        for (((cc, vv), uu), s) in c.iter_mut().zip(v).zip(u).zip(&scale) {
                            *cc = cc.wrapping_add(quantize(*vv, *s).wrapping_sub(quantize(*uu, *s)));
                        }
                    }
                }
                (Some(a), None) => {
                    source(a, &mut enter);
                    for (c, v) in col.iter_mut().zip(&enter) {
                        for ((cc, vv), s) in c.iter_mut().zip(v).zip(&scale) {
                            *cc = cc.wrapping_add(quantize(*vv, *s));
                        }
                    }
                }
                (None, Some(b)) => {
                    source(b, &mut leave);
                    for (c, u) in col.iter_mut().zip(&leave) {
                        for ((cc, uu), s) in c.iter_mut().zip(u).zip(&scale) {
                            *cc = cc.wrapping_sub(quantize(*uu, *s));
                        }
                    }
                }
                (None, None) => {}
            }
        }
    }
}

/// Clipped-window box mean of one plane (METHOD §6) with `bands` parallel
/// bands; identical for any band count.
pub fn box_mean_plane(src: &[f32], geom: BoxGeom, bands: usize) -> Vec<f32> {
    let BoxGeom { h, w, .. } = geom;
    let mut out = vec![0f32; h * w];
    if h == 0 || w == 0 || src.len() != h * w {
        return out;
    }
    let bound = src.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
    let ranges = band_ranges(h, bands, 8);
    let work = with_starts(&ranges, split_bands(&mut out, w, &ranges));
    let source = |y: usize, row: &mut [[f64; 1]]| {
        let line = src.get(y * w..(y + 1) * w).unwrap_or(&[]);
        for (d, s) in row.iter_mut().zip(line) {
            *d = [*s as f64];
        }
    };
    let sink = |o: &mut (usize, &mut [f32]), y: usize, means: &[[f64; 1]]| {
        let off = (y - o.0) * w;
        if let Some(line) = o.1.get_mut(off..off + w) {
            for (d, m) in line.iter_mut().zip(means) {
                *d = m[0] as f32;
            }
        }
    };
    box_means(geom, [bound], work, &source, &sink);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values in [-0.3, 0.7): negative ones too.
    fn lcg(n: usize, seed: u64) -> Vec<f32> {
        crate::kernels::util::test_noise(n, seed).into_iter().map(|v| v - 0.3).collect()
    }

    fn brute(x: &[f32], h: usize, w: usize, r: usize) -> Vec<f64> {
        let mut out = vec![0f64; h * w];
        for y in 0..h {
            for xx in 0..w {
                let (mut s, mut n) = (0f64, 0f64);
                for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                    for xq in xx.saturating_sub(r)..=(xx + r).min(w - 1) {
                        s += x[yy * w + xq] as f64;
                        n += 1.0;
                    }
                }
                out[y * w + xx] = s / n;
            }
        }
        out
    }

    #[test]
    fn matches_brute_force_for_any_band_count() {
        for (h, w) in [(1usize, 1usize), (7, 9), (40, 23), (5, 60)] {
            let x = lcg(h * w, (h * 31 + w) as u64);
            for r in [0usize, 1, 3, 10, 100] {
                let geom = BoxGeom { h, w, r };
                let exp = brute(&x, h, w, r);
                let one = box_mean_plane(&x, geom, 1);
                for (g, e) in one.iter().zip(&exp) {
                    assert!((*g as f64 - e).abs() < 1e-6, "h={h} w={w} r={r}: {g} vs {e}");
                }
                // exact sums: every band split (and direction) gives the same bits
                for bands in [2usize, 3, 5, 8] {
                    let got = box_mean_plane(&x, geom, bands);
                    assert!(got.iter().zip(&one).all(|(a, b)| a.to_bits() == b.to_bits()), "bands={bands}");
                }
            }
        }
    }

    #[test]
    fn several_channels_and_large_values() {
        // channel 1 is 1e6 times channel 0: each keeps its own precision
        let (h, w, r) = (30usize, 20usize, 4usize);
        let x = lcg(h * w, 5);
        let exp = brute(&x, h, w, r);
        let geom = BoxGeom { h, w, r };
        let ranges = band_ranges(h, 3, 1);
        let mut out = vec![[0f64; 2]; h * w];
        let y0s: Vec<usize> = ranges.iter().map(|r| r.start).collect();
        let work: Vec<_> = ranges
            .iter()
            .cloned()
            .zip(y0s.into_iter().zip(split_bands(&mut out, w, &ranges)))
            .collect();
        let source = |y: usize, row: &mut [[f64; 2]]| {
            for (d, s) in row.iter_mut().zip(&x[y * w..(y + 1) * w]) {
                *d = [*s as f64, *s as f64 * 1e6];
            }
        };
        let sink = |o: &mut (usize, &mut [[f64; 2]]), y: usize, m: &[[f64; 2]]| {
            o.1[(y - o.0) * w..(y - o.0 + 1) * w].copy_from_slice(m);
        };
        box_means(geom, [0.7, 0.7e6], work, &source, &sink);
        for (o, e) in out.iter().zip(&exp) {
            assert!((o[0] - e).abs() < 1e-9 && (o[1] - e * 1e6).abs() < 1e-3);
        }
    }

    #[test]
    fn scale_keeps_sums_exact() {
        let g = BoxGeom { h: 3000, w: 4000, r: 750 };
        let s = g.scale(1.0);
        assert!(s * g.max_terms() <= SUM_LIMIT && 2.0 * s * g.max_terms() > SUM_LIMIT);
        assert_eq!(g.scale(0.0), 1.0);
        assert_eq!(g.scale(f64::NAN), 1.0);
        assert!(g.scale(1e-300).is_finite());
        assert_eq!(band_ranges(5, 4, 8), vec![0..5]);
        assert_eq!(band_ranges(100, 2, 8), vec![0..50, 50..100]);
    }
}
