//! Choosing the water type by the gray-world assumption (METHOD §9 / METHOD §9).

use crate::util::{det_sums, REDUCE_ROWS};

/// Initial exclusion threshold on the t_R difference (METHOD §9).
pub const EXCLUDE_THRESHOLD: f64 = 0.1;
/// Halvings of the threshold tried before giving up on exclusion.
pub const MAX_HALVINGS: usize = 30;
/// Flag: no threshold left any type, so none was excluded.
pub const FLAG_RELAXED: &str = "exclusion_relaxed";

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

/// Score and t_R difference for one type (METHOD §9). `stretched` is
/// interleaved RGB, `t_red` per pixel; counted pixels are masked-in and
/// not in VL.
pub fn type_stats(
    stretched: &[f32],
    t_red: &[f32],
    vl: &[bool],
    mask: Option<&[bool]>,
    width: usize,
) -> TypeStats {
    let n = t_red.len();
    let s = det_sums::<7, _>(n, width.max(1) * REDUCE_ROWS, |i, acc| {
        if mask.is_some_and(|m| !m.get(i).copied().unwrap_or(false)) {
            return;
        }
        let t = t_red.get(i).copied().unwrap_or(0.0) as f64;
        if vl.get(i).copied().unwrap_or(false) {
            acc[5] += t;
            acc[6] += 1.0;
        } else {
            if let Some(p) = stretched.get(3 * i..3 * i + 3) {
                acc.iter_mut().zip(p).for_each(|(a, v)| *a += *v as f64);
            }
            acc[3] += t;
            acc[4] += 1.0;
        }
    });
    SelectionSums {
        channels: [s[0], s[1], s[2]],
        tr_counted: s[3],
        counted: s[4],
        tr_vl: s[5],
        vl: s[6],
    }
    .stats()
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

#[cfg(test)]
mod tests {
    use super::*;

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
