//! Choosing the water type by the gray-world assumption (METHOD §9 / METHOD §9).

use crate::method::recover::Stretch;
use crate::method::stretch::{lane_constants, LANES};
use crate::kernels::util::ChannelStretch;

/// Initial exclusion threshold on the t_R difference (METHOD §9).
pub const EXCLUDE_THRESHOLD: f64 = 0.1;
/// Halvings of the threshold tried before giving up on exclusion.
pub const MAX_HALVINGS: usize = 30;
/// What selection needs from one water type's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TypeStats {
    /// gray-world score: sample std (n - 1) of the 3 channel means of the
    /// stretched image over the counted pixels
    pub score: f64,
    /// mean t_R over counted pixels minus mean t_R over VL (None without VL)
    pub tr_diff: Option<f64>,
}

/// Sums over the pixels of one type's result that selection needs
/// (METHOD §9): over counted pixels (masked-in, not VL) the three channels of
/// the stretched image, t_R and their number; over VL pixels t_R and their
/// number.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SelectionSums {
    /// sum of each stretched channel over counted pixels
    pub channels: [f64; 3],
    /// sum of t_R over counted pixels
    pub tr_counted: f64,
    /// number of counted pixels
    pub counted: f64,
    /// sum of t_R over VL pixels
    pub tr_vl: f64,
    /// number of VL pixels
    pub vl: f64,
}

impl SelectionSums {
    /// Adds another partial sum (combine partials in a fixed order).
    pub fn add(&mut self, o: &Self) {
        self.channels.iter_mut().zip(&o.channels).for_each(|(a, b)| *a += b);
        self.tr_counted += o.tr_counted;
        self.counted += o.counted;
        self.tr_vl += o.tr_vl;
        self.vl += o.vl;
    }

    /// Score and t_R difference (METHOD §9): the sample std (n - 1) of the
    /// three channel means; mean t_R over counted minus over VL pixels.
    pub fn stats(&self) -> TypeStats {
        let cnt = self.counted.max(1.0);
        let means = self.channels.map(|s| s / cnt);
        let mu = (means[0] + means[1] + means[2]) / 3.0;
        let var = means.iter().map(|m| (m - mu).powi(2)).sum::<f64>() / 2.0;
        let tr_diff = (self.vl > 0.0).then(|| self.tr_counted / cnt - self.tr_vl / self.vl);
        TypeStats {
            score: var.sqrt(),
            tr_diff,
        }
    }
}

#[cfg(any(test, feature = "internals"))]
/// Score and t_R difference for one type (METHOD §9) from its displayed
/// image (`stretched`, interleaved RGB) and t_R, through the row kernels
/// that `restore` runs ([`row_stats`], [`counted_sums`]), rows combined in
/// row order. Counted pixels are masked-in and not in VL.
pub fn type_stats(
    stretched: &[f32],
    t_red: &[f32],
    vl: &[bool],
    mask: Option<&[bool]>,
    width: usize,
) -> TypeStats {
    let w = width.max(1);
    let (yes, no) = (vec![true; w], vec![false; w]);
    let rows: Vec<(RowStats, [f64; 3])> = t_red
        .chunks(w)
        .zip(stretched.chunks(3 * w))
        .enumerate()
        .map(|(y, (tr, px))| {
            let row = y * w..(y + 1) * w;
            let inside = mask.map_or(&yes[..], |m| m.get(row.clone()).unwrap_or(&no));
            let vlr = vl.get(row).unwrap_or(&no);
            let px = px.as_chunks::<3>().0;
            let mut st = RowStats::default();
            row_stats(px, tr, inside, vlr, &mut st);
            let counted: Vec<bool> = inside.iter().zip(vlr).map(|(&i, &v)| i & !v).collect();
            (st, counted_sums(None, px, &counted))
        })
        .collect();
    let st = combine(&rows.iter().map(|r| r.0).collect::<Vec<_>>());
    let mut sums = st.sums;
    sums.channels = rows.iter().fold([0f64; 3], |a, r| [a[0] + r.1[0], a[1] + r.1[1], a[2] + r.1[2]]);
    sums.stats()
}

/// The outcome of [`choose`].
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// index of the chosen type
    pub winner: usize,
    /// per type: excluded by the t_R rule
    pub excluded: Vec<bool>,
    /// the exclusion rule was given up (no threshold left a type)
    pub relaxed: bool,
    /// the exclusion threshold that was applied (None: no exclusion)
    pub threshold: Option<f64>,
}

/// METHOD §9: exclude types whose t_R difference is below the threshold
/// (halving it while none survives), then the lowest score wins; ties go
/// to the first type. Empty `stats` gives winner 0.
pub fn choose(stats: &[TypeStats]) -> Choice {
    let n = stats.len();
    let mut excluded = vec![false; n];
    let mut relaxed = false;
    let mut threshold = None;
    if stats.iter().all(|s| s.tr_diff.is_some()) && n > 0 {
        let mut thr = EXCLUDE_THRESHOLD;
        for _ in 0..=MAX_HALVINGS {
            let ex: Vec<bool> = stats
                .iter()
                .map(|s| s.tr_diff.is_none_or(|d| d.is_nan() || d < thr))
                .collect();
            if ex.iter().any(|&e| !e) {
                excluded = ex;
                threshold = Some(thr);
                break;
            }
            thr /= 2.0;
        }
        relaxed = threshold.is_none();
    }
    // (index, stats) of the best type so far
    let mut winner = None::<(usize, &TypeStats)>;
    for (i, (s, &ex)) in stats.iter().zip(&excluded).enumerate() {
        if ex {
            continue;
        }
        // NaN scores never win
        if winner.is_none_or(|(_, w)| s.score < w.score || w.score.is_nan()) {
            winner = Some((i, s));
        }
    }
    Choice {
        winner: winner.map_or(0, |(i, _)| i),
        excluded,
        relaxed,
        threshold,
    }
}

/// How much more central (in summed median L1 chromaticity distance) a
/// type must be than the best-scored one to be chosen instead (METHOD
/// §12.2). Where the trust step shows the input's balance for every
/// candidate, their displays differ only where clipped, by less than
/// 1e-4 on the shared photos: the choice then rests on the scores, not on
/// that noise.
pub const CENTRAL_MARGIN: f64 = 1e-3;

/// The central type choice (METHOD §12.2): of the `of` types that
/// `ranking` scores lowest (not excluded, not NaN; ties by index), the one
/// whose displayed colours `prints` (at the same pixels for every type)
/// are nearest the others': the smallest sum of median L1 distances
/// between the pixels' chromaticities, if it is smaller than the scores'
/// own choice `winner`'s by more than [`CENTRAL_MARGIN`]; else `winner`.
/// `winner` is one of those `of` types whenever the ranking is the one the
/// scores chose by (else the best-ranked type stands for it). None when
/// fewer than two types compete or a competitor has no colours.
pub fn central(ranking: &[TypeStats], excluded: &[bool], prints: &[Option<Vec<[f32; 3]>>], of: usize, winner: usize) -> Option<usize> {
    let score = |i: usize| ranking.get(i).map_or(f64::NAN, |s| s.score);
    let mut order: Vec<usize> = (0..ranking.len())
        .filter(|&i| !excluded.get(i).copied().unwrap_or(false) && !score(i).is_nan())
        .collect();
    order.sort_by(|&i, &j| score(i).total_cmp(&score(j)).then(i.cmp(&j)));
    order.truncate(of);
    if order.len() < 2 {
        return None;
    }
    let chroma = |p: &[f32; 3]| -> [f64; 3] {
        let v = p.map(|x| f64::from(x).max(1e-6));
        let s = v[0] + v[1] + v[2];
        v.map(|x| x / s)
    };
    let shown: Vec<Vec<[f64; 3]>> = order
        .iter()
        .map(|&i| prints.get(i).and_then(|p| p.as_ref()).map(|p| p.iter().map(chroma).collect()))
        .collect::<Option<_>>()?;
    let n = shown.first().map_or(0, Vec::len);
    if n == 0 || shown.iter().any(|s| s.len() != n) {
        return None;
    }
    let distance = |a: &[[f64; 3]], b: &[[f64; 3]]| -> f64 {
        let mut d: Vec<f64> = a
            .iter()
            .zip(b)
            .map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()).sum())
            .collect();
        crate::method::fallback::median(&mut d)
    };
    let spread: Vec<f64> = shown
        .iter()
        .map(|a| shown.iter().map(|b| distance(a, b)).sum())
        .collect();
    // the most central (the first of equals, the better score)
    let (best, least) = spread
        .iter()
        .enumerate()
        .fold((0, f64::INFINITY), |(b, m), (k, &v)| if v < m { (k, v) } else { (b, m) });
    // within the margin the scores' own choice stands (the best-ranked
    // one when the scores chose outside the ranking's best)
    let own = order.iter().position(|&i| i == winner);
    let kept = own.map_or(order.first().copied(), |_| Some(winner));
    let reference = spread.get(own.unwrap_or(0)).copied().unwrap_or(f64::INFINITY);
    if least < reference - CENTRAL_MARGIN {
        order.get(best).copied()
    } else {
        kept
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
pub(crate) fn counted_sums(sp: Option<&Stretch>, px: &[[f32; 3]], counted: &[bool]) -> [f64; 3] {
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
pub(crate) fn sum_lanes<M, T>(limits: &ChannelStretch, px: &[[f32; 3]], counted: &[bool], map: M, tail: T) -> [f64; 3]
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
pub(crate) fn row_stats(j: &[[f32; 3]], tr: &[f32], inside: &[bool], vl: &[bool], st: &mut RowStats) {
    const L: usize = 8;
    // one array per statistic, one entry per lane: each lane's values are
    // accumulated in pixel order, and lanes combined in lane order
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

/// What one pass over a row of recovered pixels gathers (METHOD §7-9).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowStats {
    /// min and max of J over the masked-in pixels' channels
    pub(crate) lo: f32,
    pub(crate) hi: f32,
    /// t_R sums over counted and VL pixels (the channel sums come later)
    pub(crate) sums: SelectionSums,
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
    pub(crate) fn add(&mut self, o: &Self) {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
        self.sums.add(&o.sums);
    }
}

/// The statistics of all rows combined in row order (the same for any
/// thread count).
pub(crate) fn combine(rows: &[RowStats]) -> RowStats {
    rows.iter().fold(RowStats::default(), |mut acc, r| {
        acc.add(r);
        acc
    })
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn central_picks_the_display_between_the_others() {
        let st = |score: f64| TypeStats { score, tr_diff: None };
        // chromaticities by hand: A (0.6, 0.2, 0.2), B (0.4, 0.3, 0.3),
        // C (0.2, 0.4, 0.4); L1 distances A-B 0.4, B-C 0.4, A-C 0.8: sums
        // A 1.2, B 0.8, C 1.2, so B though A scores best; D scores worst
        let print = |c: [f32; 3], n: usize| Some(vec![c; n]);
        let stats = [st(0.1), st(0.2), st(0.3), st(0.9)];
        let prints = [print([0.6, 0.2, 0.2], 5), print([0.4, 0.3, 0.3], 5), print([0.2, 0.4, 0.4], 5), print([0.4, 0.3, 0.3], 5)];
        assert_eq!(central(&stats, &[false; 4], &prints, 3, 0), Some(1));
        // brightness does not count: the same colours at half the level
        let dim = [print([0.3, 0.1, 0.1], 5), print([0.2, 0.15, 0.15], 5), print([0.1, 0.2, 0.2], 5), None];
        assert_eq!(central(&stats, &[false; 4], &dim, 3, 0), Some(1));
        // the median over pixels: two of three pixels decide
        let mixed = |a: [f32; 3], b: [f32; 3]| Some(vec![a, a, b]);
        let m = [mixed([0.6, 0.2, 0.2], [0.2, 0.4, 0.4]), mixed([0.4, 0.3, 0.3], [0.4, 0.3, 0.3]), mixed([0.2, 0.4, 0.4], [0.6, 0.2, 0.2]), None];
        assert_eq!(central(&stats, &[false; 4], &m, 3, 0), Some(1));
        // B excluded: A, C and D (= B's colours) compete, D is central
        assert_eq!(central(&stats, &[false, true, false, false], &prints, 3, 0), Some(3));
        // two competitors are equally central: the better score wins
        assert_eq!(central(&stats, &[false; 4], &prints, 2, 0), Some(0));
        // a NaN score never competes: B, C and D (B's colours) do, B and D
        // tie at 0.4 and B scores better; fewer than two, or a competitor
        // without colours, leave the choice to the scores
        let nan = [st(f64::NAN), st(0.2), st(0.3), st(0.9)];
        assert_eq!(central(&nan, &[false; 4], &prints, 3, 1), Some(1));
        let nan_b = [st(0.1), st(f64::NAN), st(0.3), st(0.9)];
        assert_eq!(central(&nan_b, &[false; 4], &prints, 3, 0), Some(3));
        assert_eq!(central(&stats, &[false; 4], &prints, 1, 0), None);
        assert_eq!(central(&stats, &[false; 4], &[print([0.6, 0.2, 0.2], 5), None, print([0.2, 0.4, 0.4], 5), None], 3, 0), None);
        // more central by less than the margin: the best score stands
        let near = [print([0.4, 0.3, 0.3], 5), print([0.4, 0.3, 0.3002], 5), print([0.4, 0.3, 0.3008], 5), None];
        assert_eq!(central(&stats, &[false; 4], &near, 3, 0), Some(0));
        // fast selection ranks by the copy's scores and chose by full-resolution
        // ones: within the margin its choice stands, even when not the copy's best
        assert_eq!(central(&stats, &[false; 4], &near, 3, 2), Some(2));
        // a choice outside the ranking's best: the best-ranked stands for it
        assert_eq!(central(&stats, &[false; 4], &near, 3, 3), Some(0));
        // and a clearly central type wins whichever the scores chose
        assert_eq!(central(&stats, &[false; 4], &prints, 3, 2), Some(1));
        // a zero pixel is gray (1/3 each), not a division by zero
        let zero = [print([0.0, 0.0, 0.0], 3), print([0.5, 0.5, 0.5], 3), print([0.9, 0.0, 0.0], 3), None];
        assert_eq!(central(&stats, &[false; 4], &zero, 3, 0), Some(0));
    }

    #[test]
    fn score_by_hand() {
        // two counted pixels with means (0.5, 0.4, 0.3): std (n-1) = 0.1
        let st = [0.4f32, 0.4, 0.2, 0.6, 0.4, 0.4, 0.9, 0.9, 0.9];
        let tr = [0.5f32, 0.7, 0.2];
        let vl = [false, false, true];
        let s = type_stats(&st, &tr, &vl, None, 3);
        assert!((s.score - 0.1).abs() < 1e-7);
        assert!((s.tr_diff.unwrap() - (0.6 - 0.2)).abs() < 1e-7);
        // masking out pixel 1 leaves only pixel 0: means (0.4, 0.4, 0.2)
        let s = type_stats(&st, &tr, &vl, Some(&[true, false, true]), 3);
        let e = ((2.0 * (0.4 - 1.0 / 3.0f64).powi(2) + (0.2 - 1.0 / 3.0f64).powi(2)) / 2.0).sqrt();
        assert!((s.score - e).abs() < 1e-7);
        assert!(type_stats(&st, &tr, &[false; 3], None, 3).tr_diff.is_none());
    }

    #[test]
    fn exclusion_and_ties() {
        let t = |score, d| TypeStats {
            score,
            tr_diff: Some(d),
        };
        // the best score is excluded (d < 0.1): the next best wins
        let c = choose(&[t(0.01, 0.05), t(0.02, 0.2), t(0.03, 0.3)]);
        assert_eq!(c.winner, 1);
        assert_eq!(c.excluded, vec![true, false, false]);
        // no type reaches 0.1: halve to 0.05 -> types with d >= 0.05 survive
        let c = choose(&[t(0.01, 0.04), t(0.02, 0.06), t(0.005, 0.01)]);
        assert_eq!((c.winner, c.relaxed, c.threshold), (1, false, Some(0.05)));
        // all negative: the rule is given up, the best score wins
        let c = choose(&[t(0.02, -0.5), t(0.01, -0.4)]);
        assert_eq!((c.winner, c.relaxed, c.threshold), (1, true, None));
        // ties go to the first
        let c = choose(&[t(0.02, 0.5), t(0.02, 0.5)]);
        assert_eq!(c.winner, 0);
        // no VL: no exclusion
        let c = choose(&[
            TypeStats {
                score: 0.3,
                tr_diff: None,
            },
            TypeStats {
                score: 0.2,
                tr_diff: None,
            },
        ]);
        assert_eq!((c.winner, c.excluded), (1, vec![false, false]));
    }
}
