//! Exact order statistics of large value streams without copying or
//! sorting them (percentiles of DECISIONS "P", medians of S3).
//!
//! A strided sample of the rows brackets each wanted rank between two
//! sample values; one parallel pass then counts the values below each
//! bracket and keeps only those inside it (a few per thousand for the tail
//! percentiles), where the wanted ranks are selected. If the sample was
//! unlucky and a rank falls outside its bracket, that stream is collected in
//! full: the answer is always exact, only the time depends on the sample.
//! The order is `cmp`'s total order, so the result does not depend on the
//! number of threads.

use rayon::prelude::*;
use std::cmp::Ordering;

/// Rows per chunk of the counting pass.
const CHUNK_ROWS: usize = 16;
/// Sample values wanted per stream.
const SAMPLE: usize = 4096;

/// A range of values [lo, hi] (None = unbounded) whose members are kept.
#[derive(Clone, Copy)]
struct Bracket<T> {
    lo: Option<T>,
    hi: Option<T>,
}

/// The values at `ranks[k]` (0-based, ascending in `cmp`) of stream k, for
/// K streams whose values `row_values(y, bufs)` pushes row by row (y in
/// 0..rows; `bufs` are cleared before each call). `counts[k]` is the number
/// of values stream k yields in total; ranks >= counts[k] are ignored
/// (the output holds one value per valid rank, in the order asked).
pub fn order_stats<T, const K: usize, F, C>(
    rows: usize,
    counts: [usize; K],
    ranks: [&[usize]; K],
    cmp: C,
    row_values: F,
) -> [Vec<T>; K]
where
    T: Copy + Send + Sync,
    F: Fn(usize, &mut [Vec<T>; K]) + Sync,
    C: Fn(&T, &T) -> Ordering + Sync,
{
    // 1. a strided sample: every s_r-th row, every s_c-th value of it
    let s_r = (rows / 64).max(1);
    let strides = counts.map(|n| (n / s_r / SAMPLE).max(1));
    let parts: Vec<[Vec<T>; K]> = (0..rows)
        .into_par_iter()
        .step_by(s_r)
        .map(|y| {
            let mut bufs: [Vec<T>; K] = std::array::from_fn(|_| Vec::new());
            row_values(y, &mut bufs);
            let mut out: [Vec<T>; K] = std::array::from_fn(|_| Vec::new());
            for ((o, b), s) in out.iter_mut().zip(&bufs).zip(&strides) {
                o.extend(b.iter().step_by(*s).copied());
            }
            out
        })
        .collect();
    let mut samples: [Vec<T>; K] = std::array::from_fn(|_| Vec::new());
    for p in parts {
        for (s, v) in samples.iter_mut().zip(p) {
            s.extend(v);
        }
    }
    for s in samples.iter_mut() {
        s.sort_unstable_by(&cmp);
    }
    // 2. one bracket per wanted rank, widened by 8 binomial standard deviations
    let brackets: [Vec<Bracket<T>>; K] = std::array::from_fn(|k| {
        let (n, sample) = (counts.get(k).copied().unwrap_or(0), samples.get(k));
        let sample = sample.map_or(&[][..], |s| s.as_slice());
        let m = sample.len();
        let mut out: Vec<Bracket<T>> = ranks
            .get(k)
            .map_or(&[][..], |r| *r)
            .iter()
            .filter(|&&r| r < n)
            .map(|&r| {
                let f = r as f64 / (n.max(2) - 1) as f64;
                let delta = 8.0 * (f * (1.0 - f) / m.max(1) as f64).sqrt() + 4.0 / m.max(1) as f64;
                let at = |g: f64| sample.get((g * (m.max(1) - 1) as f64) as usize).copied();
                Bracket {
                    lo: if f - delta <= 0.0 { None } else { at((f - delta).max(0.0)) },
                    hi: if f + delta >= 1.0 { None } else { at(f + delta).filter(|_| m > 0) },
                }
            })
            .collect();
        if m == 0 {
            out.iter_mut().for_each(|b| *b = Bracket { lo: None, hi: None });
        }
        out
    });
    let found = collect(rows, &brackets, &cmp, &row_values);
    // 3. select each rank inside its bracket, or fall back to the whole stream
    let mut result: [Vec<T>; K] = std::array::from_fn(|_| Vec::new());
    for (k, ((res, mut groups), (&n, rk))) in result
        .iter_mut()
        .zip(found)
        .zip(counts.iter().zip(ranks))
        .enumerate()
    {
        for &r in rk.iter().filter(|&&r| r < n) {
            let inside = |g: &(usize, Vec<T>)| g.0 <= r && r < g.0 + g.1.len();
            if !groups.iter().any(inside) {
                let all: [Vec<Bracket<T>>; K] = std::array::from_fn(|j| {
                    if j == k {
                        vec![Bracket { lo: None, hi: None }]
                    } else {
                        Vec::new()
                    }
                });
                groups = collect(rows, &all, &cmp, &row_values)
                    .into_iter()
                    .nth(k)
                    .unwrap_or_default();
            }
            if let Some((below, vals)) = groups.iter_mut().find(|g| inside(g)) {
                if let Some(v) = select(vals, r - *below, &cmp) {
                    res.push(v);
                }
            }
        }
    }
    result
}

fn select<T: Copy, C: Fn(&T, &T) -> Ordering>(vals: &mut [T], k: usize, cmp: &C) -> Option<T> {
    if k >= vals.len() {
        return None;
    }
    let (_, v, _) = vals.select_nth_unstable_by(k, cmp);
    Some(*v)
}

/// Per stream, per bracket: the number of values below it and the values inside it.
type Groups<T, const K: usize> = [Vec<(usize, Vec<T>)>; K];

/// For every stream and bracket: the number of values below the bracket
/// and the values inside it.
fn collect<T, const K: usize, F, C>(
    rows: usize,
    brackets: &[Vec<Bracket<T>>; K],
    cmp: &C,
    row_values: &F,
) -> Groups<T, K>
where
    T: Copy + Send + Sync,
    F: Fn(usize, &mut [Vec<T>; K]) + Sync,
    C: Fn(&T, &T) -> Ordering + Sync,
{
    let empty = || -> Groups<T, K> {
        std::array::from_fn(|k| {
            let nb = brackets.get(k).map_or(0, Vec::len);
            (0..nb).map(|_| (0usize, Vec::new())).collect()
        })
    };
    let chunks = rows.div_ceil(CHUNK_ROWS);
    let parts: Vec<Groups<T, K>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut acc = empty();
            let mut bufs: [Vec<T>; K] = std::array::from_fn(|_| Vec::new());
            for y in c * CHUNK_ROWS..((c + 1) * CHUNK_ROWS).min(rows) {
                bufs.iter_mut().for_each(Vec::clear);
                row_values(y, &mut bufs);
                for ((a, b), br) in acc.iter_mut().zip(&bufs).zip(brackets) {
                    for v in b {
                        for ((below, vals), bk) in a.iter_mut().zip(br) {
                            if bk.lo.is_some_and(|lo| cmp(v, &lo) == Ordering::Less) {
                                *below += 1;
                            } else if bk.hi.is_none_or(|hi| cmp(v, &hi) != Ordering::Greater) {
                                vals.push(*v);
                            }
                        }
                    }
                }
            }
            acc
        })
        .collect();
    let mut out = empty();
    for p in parts {
        for (o, q) in out.iter_mut().zip(p) {
            for ((ob, ov), (qb, qv)) in o.iter_mut().zip(q) {
                *ob += qb;
                ov.extend(qv);
            }
        }
    }
    out
}

/// Percentiles (DECISIONS "P", NumPy's "linear" method) at the fractions
/// `qs` of a stream of `n` values, from its order statistics: position
/// h = q (n - 1), x_floor(h) + (h - floor(h)) (x_floor(h)+1 - x_floor(h)),
/// where `value(rank)` maps an order statistic to the value whose
/// percentile is wanted (a non-decreasing map commutes with ranking).
/// Returns 0 for every q when n == 0.
pub fn ranks_for(n: usize, qs: &[f64]) -> Vec<usize> {
    let mut out = Vec::new();
    for &q in qs {
        let h = q.clamp(0.0, 1.0) * n.saturating_sub(1) as f64;
        let lo = h.floor() as usize;
        out.push(lo);
        if h > lo as f64 && lo + 1 < n {
            out.push(lo + 1);
        }
    }
    out
}

/// The percentiles at `qs` given the values at [`ranks_for`]`(n, qs)` (in
/// that order, already mapped to f64).
pub fn percentiles_from(n: usize, qs: &[f64], stats: &[f64]) -> Vec<f64> {
    let mut it = stats.iter();
    qs.iter()
        .map(|&q| {
            let h = q.clamp(0.0, 1.0) * n.saturating_sub(1) as f64;
            let lo = h.floor() as usize;
            let a = it.next().copied().unwrap_or(0.0);
            if h > lo as f64 && lo + 1 < n {
                let b = it.next().copied().unwrap_or(a);
                a + (h - lo as f64) * (b - a)
            } else {
                a
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|i| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                // structured: smooth gradient + noise + repeated values
                let noise = ((s >> 40) as f32) / (1u64 << 24) as f32;
                if i % 7 == 0 { 0.5 } else { (i % 300) as f32 / 300.0 * 0.3 + noise * 0.7 }
            })
            .collect()
    }

    fn check(v: &[f32], rows: usize, ranks: &[usize]) {
        let w = v.len() / rows;
        let mut sorted = v.to_vec();
        sorted.sort_by(f32::total_cmp);
        let [got] = order_stats(rows, [v.len()], [ranks], f32::total_cmp, |y, b: &mut [Vec<f32>; 1]| {
            b[0].extend_from_slice(&v[y * w..(y + 1) * w]);
        });
        let exp: Vec<f32> = ranks.iter().filter(|&&r| r < v.len()).map(|&r| sorted[r]).collect();
        assert_eq!(got, exp, "ranks {ranks:?}");
    }

    #[test]
    fn equals_sorting() {
        for (n, rows) in [(1usize, 1usize), (10, 2), (1000, 10), (200_000, 400)] {
            let v = data(n, n as u64);
            let all: Vec<usize> = vec![0, 1, n / 1000, n / 2, n.saturating_sub(n / 1000 + 1), n - 1, n];
            check(&v, rows, &all);
        }
    }

    #[test]
    fn unlucky_sample_falls_back() {
        // every sampled row holds only small values; the unsampled rows the
        // large ones: brackets from the sample miss, the fallback is exact
        let (rows, w) = (640usize, 50usize);
        let v: Vec<f32> = (0..rows * w)
            .map(|i| if (i / w) % 10 == 0 { (i % w) as f32 } else { 1000.0 + (i % 97) as f32 })
            .collect();
        check(&v, rows, &[10, rows * w / 2, rows * w - 3]);
    }

    #[test]
    fn percentiles_interpolate_like_numpy() {
        // sorted 1 2 3 4: q=0.1 -> 1.3, q=0.5 -> 2.5, q=1 -> 4
        let n = 4;
        let qs = [0.1, 0.5, 1.0];
        let r = ranks_for(n, &qs);
        let vals = [1.0, 2.0, 3.0, 4.0];
        let stats: Vec<f64> = r.iter().map(|&k| vals[k]).collect();
        let p = percentiles_from(n, &qs, &stats);
        assert!((p[0] - 1.3).abs() < 1e-12 && p[1] == 2.5 && p[2] == 4.0);
        assert_eq!(percentiles_from(0, &[0.3], &[]), vec![0.0]);
    }
}
