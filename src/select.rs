//! Choosing the water type by the gray-world assumption (SPEC 9 / DECISIONS S9).

use crate::util::{det_sums, REDUCE_ROWS};

/// Initial exclusion threshold on the t_R difference (SPEC 9).
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

/// Score and t_R difference for one type (SPEC 9). `stretched` is
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
        if mask.is_some_and(|m| !m[i]) {
            return;
        }
        if vl[i] {
            acc[5] += t_red[i] as f64;
            acc[6] += 1.0;
        } else {
            for c in 0..3 {
                acc[c] += stretched[3 * i + c] as f64;
            }
            acc[3] += t_red[i] as f64;
            acc[4] += 1.0;
        }
    });
    let cnt = s[4].max(1.0);
    let means = [s[0] / cnt, s[1] / cnt, s[2] / cnt];
    let mu = (means[0] + means[1] + means[2]) / 3.0;
    let var = means.iter().map(|m| (m - mu).powi(2)).sum::<f64>() / 2.0;
    let tr_diff = if s[6] > 0.0 {
        Some(s[3] / cnt - s[5] / s[6])
    } else {
        None
    };
    TypeStats {
        score: var.sqrt(),
        tr_diff,
    }
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
}

/// SPEC 9: exclude types whose t_R difference is below the threshold
/// (halving it while none survives), then the lowest score wins; ties go
/// to the first type. Empty `stats` gives winner 0.
pub fn choose(stats: &[TypeStats]) -> Choice {
    let n = stats.len();
    let mut excluded = vec![false; n];
    let mut relaxed = false;
    if stats.iter().all(|s| s.tr_diff.is_some()) && n > 0 {
        let mut thr = EXCLUDE_THRESHOLD;
        let mut found = false;
        for _ in 0..=MAX_HALVINGS {
            let ex: Vec<bool> = stats
                .iter()
                .map(|s| s.tr_diff.is_none_or(|d| d.is_nan() || d < thr))
                .collect();
            if ex.iter().any(|&e| !e) {
                excluded = ex;
                found = true;
                break;
            }
            thr /= 2.0;
        }
        relaxed = !found;
    }
    let mut winner = None::<usize>;
    for (i, s) in stats.iter().enumerate() {
        if excluded[i] {
            continue;
        }
        // NaN scores never win
        if winner.is_none_or(|w| s.score < stats[w].score || stats[w].score.is_nan()) {
            winner = Some(i);
        }
    }
    Choice {
        winner: winner.unwrap_or(0),
        excluded,
        relaxed,
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
        assert_eq!((c.winner, c.relaxed), (1, false));
        // all negative: the rule is given up, the best score wins
        let c = choose(&[t(0.02, -0.5), t(0.01, -0.4)]);
        assert_eq!((c.winner, c.relaxed), (1, true));
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
