//! Fast selection (METHOD §9, option `selection="fast"`): the types scored
//! on a sampled copy of the image, the uncertain ones again at full
//! resolution.

use super::evaluate::{Print, Scored, Shared};
use super::work::{Kept, Work};
use crate::error::Result;
use crate::method::image::ImageRef;
use crate::method::params::{default_radius, fast_factor, Params};
use crate::method::select::{choose, Choice, TypeStats};
use crate::method::sphere::SphereIndex;
use crate::method::veiling::Veiling;
use crate::method::fallback::noise_sigma;
use crate::method::profile::TypeChoice;
use crate::method::water::WaterType;

/// How many of the copy's best-scoring surviving types fast selection
/// scores again at full resolution before choosing.
pub const FAST_RESCORE: usize = 3;

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
pub(crate) fn rescore_candidates(order: &[usize], copy: &[TypeStats], threshold: Option<f64>) -> Vec<usize> {
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


/// The copy of the image with its masks that [`Selection::Fast`] scores
/// the types on: every s-th pixel of every s-th row (the centre of each
/// s x s block). Point samples, not block averages: the statistics that
/// selection depends on (the largest radius of each haze-line cluster, the
/// 0.1% / 99.9% percentiles of the display stretch) are those of the
/// pixels' own distribution, which averaging would narrow by removing
/// noise.
pub(crate) struct Small {
    pub(crate) data: Vec<f32>,
    pub(crate) h: usize,
    pub(crate) w: usize,
    pub(crate) mask: Option<Vec<bool>>,
    pub(crate) vl: Vec<bool>,
}

impl Small {
    pub(crate) fn new(img: &ImageRef, mask: Option<&[bool]>, vl: &[bool], s: usize) -> Self {
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


/// The copy's statistics of every type, and their displayed colours at its probe.
pub(crate) type CopyScores = (Vec<TypeStats>, Vec<Option<Print>>);

/// Every type's selection statistics on the sampled copy of the image
/// (METHOD §9 there), with the full-resolution A and water region, and
/// under the central type choice its displayed colours at the copy's
/// probe (METHOD §12.2); None when the image is small enough to need no
/// copy.
pub(crate) fn copy_stats(
    img: &ImageRef,
    mask: Option<&[bool]>,
    veil: &Veiling,
    index: &SphereIndex,
    params: &Params,
    types: &[&WaterType],
) -> Result<Option<CopyScores>> {
    let s = fast_factor(img.height, img.width);
    if s <= 1 {
        return Ok(None);
    }
    let small = Small::new(img, mask, &veil.vl, s);
    let simg = ImageRef::new(&small.data, small.h, small.w)?;
    let sr = params
        .guided_radius
        .map_or_else(|| default_radius(small.h, small.w), |r| (r as f64 / s as f64).round() as usize);
    let mut sh = Shared::with_region(simg, small.mask.as_deref(), &small.vl, veil.a, index, sr, params, Vec::new());
    if params.type_choice_used() == TypeChoice::Central {
        sh.take_probe(Some(noise_sigma(img)));
    }
    let mut work = Work::new(simg.len());
    Ok(Some(types.iter().map(|wt| sh.evaluate(wt, &mut work)).unzip()))
}

/// The choice of fast selection from the copy's statistics: the copy's
/// best survivors are scored again at full resolution where its choice is
/// uncertain ([`rescore_candidates`]), and METHOD §9 chooses among them.
/// The displayed colours are the copy's (`prints`), the same pixels for
/// every type. The central choice ranks by the scores returned: the
/// re-scored types' full-resolution ones, the copy's for the rest. On 40
/// renders of 1100 x 1500 (ten types, four seeds) that differs from
/// exhaustive selection on 1; ranking by the copy's scores alone on 2;
/// re-scoring the copy's three best at full resolution still on 1, at
/// 1.43 x the time at 12 MP.
pub(crate) fn rescore(shared: &Shared, types: &[&WaterType], copy: Vec<TypeStats>, prints: Vec<Option<Print>>, work: &mut Work) -> Scored {
    let c = choose(&copy);
    let mut order: Vec<usize> = (0..copy.len()).filter(|&i| !c.excluded.get(i).copied().unwrap_or(true)).collect();
    let score = |i: usize| copy.get(i).map_or(f64::NAN, |s| s.score);
    order.sort_by(|&i, &j| score(i).total_cmp(&score(j)).then(i.cmp(&j)));
    let order = rescore_candidates(&order, &copy, c.threshold);
    let mut stats = copy;
    let mut excluded = c.excluded;
    let mut kept = None;
    let (winner, relaxed) = if order.len() > 1 {
        let picked: Vec<&WaterType> = order.iter().filter_map(|&i| types.get(i).copied()).collect();
        let (full, k, _) = shared.score(&picked, work);
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
    Scored { stats, choice: Choice { winner, excluded, relaxed, threshold: None }, kept, prints }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn fast_copy_is_never_thinner_than_the_method_needs() {
        use crate::method::image::MIN_SIDE;
        for (h, w) in [(4, 10000), (10000, 4), (5, 5000), (7, 9000), (40, 30000), (4, 4), (3000, 4000)] {
            let s = fast_factor(h, w);
            assert!(h.div_ceil(s) >= MIN_SIDE && w.div_ceil(s) >= MIN_SIDE, "{h}x{w}: s = {s}");
        }
        // ordinary photos keep the factor of METHOD §9 (and their outputs)
        assert_eq!(fast_factor(3000, 4000), 4);
        assert_eq!(fast_factor(1080, 1920), 2);
        // a long thin one whose copy fits stays fast, with a smaller factor
        assert_eq!(fast_factor(40, 30000), 10);
        assert_eq!(fast_factor(4, 10000), 1);
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
