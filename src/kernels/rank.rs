//! Exact order statistics of large value streams without copying or
//! sorting them (percentiles of METHOD conventions, percentiles, medians of S3).
//!
//! A strided sample of the rows brackets each wanted rank between two
//! sample values; one parallel pass then counts the values below each
//! bracket and keeps only those inside it (a few per thousand for the tail
//! percentiles), where the wanted ranks are selected. If the sample was
//! unlucky and a rank falls outside its bracket, that stream is collected in
//! full: the answer is always exact, only the time depends on the sample.
//! Values are ranked by integer keys that order as the total order of the
//! floats they encode ([`f32_key`]), so the result does not depend on the
//! number of threads.

use rayon::prelude::*;

/// Rows per chunk of the counting pass.
const CHUNK_ROWS: usize = 16;
/// Sample values wanted per stream.
const SAMPLE: usize = 4096;

/// An ordered key: unsigned integers, whose order is the order of the
/// values they encode (see [`f32_key`], [`f64_key`]).
pub trait Key: Copy + Ord + Send + Sync {
    /// the smallest key
    const MIN: Self;
    /// the largest key
    const MAX: Self;
}

impl Key for u32 {
    const MIN: Self = 0;
    const MAX: Self = u32::MAX;
}

impl Key for u128 {
    const MIN: Self = 0;
    const MAX: Self = u128::MAX;
}

/// The key of an f32: its bits mapped so that keys order as
/// `f32::total_cmp` orders the values.
#[inline(always)]
pub fn f32_key(v: f32) -> u32 {
    let b = v.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The f32 of a key made by [`f32_key`].
#[inline(always)]
pub fn key_f32(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

/// The key of an f64 (ordered as `f64::total_cmp`).
#[inline(always)]
pub fn f64_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | 0x8000_0000_0000_0000
    }
}

/// Kept values: keys k with lo <= k <= hi (inclusive; MIN / MAX = unbounded).
type Bracket<T> = (T, T);

/// Per stream, per bracket: the number of keys below it and the keys inside it.
type Groups<T, const K: usize> = [Vec<(usize, Vec<T>)>; K];

/// The keys at `ranks[k]` (0-based, ascending) of stream k, for K streams
/// whose keys `row_values(y, bufs)` pushes row by row (y in 0..rows).
/// `counts[k]` is the number of keys stream k yields in total; ranks >=
/// `counts[k]` are ignored (the output holds one key per valid rank, in the
/// order asked).
pub fn order_stats<T, const K: usize, F>(
    rows: usize,
    counts: [usize; K],
    ranks: [&[usize]; K],
    row_values: F,
) -> [Vec<T>; K]
where
    T: Key,
    F: Fn(usize, &mut [Vec<T>; K]) + Sync,
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
        s.sort_unstable();
    }
    // 2. one bracket per wanted rank, widened by 8 binomial standard deviations
    let brackets: [Vec<Bracket<T>>; K] = std::array::from_fn(|k| {
        let n = counts.get(k).copied().unwrap_or(0);
        let sample = samples.get(k).map_or(&[][..], |s| s.as_slice());
        let m = sample.len();
        ranks
            .get(k)
            .map_or(&[][..], |r| *r)
            .iter()
            .filter(|&&r| r < n)
            .map(|&r| {
                if m == 0 {
                    return (T::MIN, T::MAX);
                }
                let f = r as f64 / (n.max(2) - 1) as f64;
                let delta = 8.0 * (f * (1.0 - f) / m as f64).sqrt() + 4.0 / m as f64;
                let at = |g: f64| sample.get((g * (m - 1) as f64) as usize).copied();
                let lo = if f - delta <= 0.0 { None } else { at(f - delta) };
                let hi = if f + delta >= 1.0 { None } else { at(f + delta) };
                (lo.unwrap_or(T::MIN), hi.unwrap_or(T::MAX))
            })
            .collect()
    });
    // overlapping brackets (neighbouring ranks have nearly the same ones)
    // become one: one counting scan per distinct bracket
    let brackets = brackets.map(merge_brackets);
    let found = collect(rows, &brackets, &row_values);
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
                        vec![(T::MIN, T::MAX)]
                    } else {
                        Vec::new()
                    }
                });
                groups = collect(rows, &all, &row_values)
                    .into_iter()
                    .nth(k)
                    .unwrap_or_default();
            }
            if let Some((below, vals)) = groups.iter_mut().find(|g| inside(g)) {
                if let Some(v) = select(vals, r - *below) {
                    res.push(v);
                }
            }
        }
    }
    result
}

/// The union of overlapping brackets, in ascending order: each key lies in
/// the merged bracket iff it lies in one of the given ones.
fn merge_brackets<T: Key>(mut b: Vec<Bracket<T>>) -> Vec<Bracket<T>> {
    b.sort_unstable();
    let mut out: Vec<Bracket<T>> = Vec::with_capacity(b.len());
    for (lo, hi) in b {
        match out.last_mut() {
            Some(last) if lo <= last.1 => last.1 = last.1.max(hi),
            _ => out.push((lo, hi)),
        }
    }
    out
}

fn select<T: Key>(vals: &mut [T], k: usize) -> Option<T> {
    if k >= vals.len() {
        return None;
    }
    let (_, v, _) = vals.select_nth_unstable(k);
    Some(*v)
}

/// Adds to `below` the number of keys under `lo` and pushes the keys in
/// [lo, hi] to `vals`, in their order. Runs of 16 keys are counted
/// branch-free and scanned only when one of them is inside (rare for the
/// tail brackets); compiled for baseline x86-64 and for AVX2, picked at run
/// time.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn count_and_keep<T: Key>(keys: &[T], lo: T, hi: T, below: &mut usize, vals: &mut Vec<T>) {
    let (runs, rest) = keys.as_chunks::<16>();
    let mut n = 0usize;
    for run in runs {
        let mut under = 0u32;
        let mut inside = false;
        for &v in run {
            under += u32::from(v < lo);
            inside |= (v >= lo) & (v <= hi);
        }
        n += under as usize;
        if inside {
            vals.extend(run.iter().filter(|&&v| v >= lo && v <= hi));
        }
    }
    for &v in rest {
        if v < lo {
            n += 1;
        } else if v <= hi {
            vals.push(v);
        }
    }
    *below += n;
}

/// For every stream and bracket: the number of keys below the bracket
/// and the keys inside it.
fn collect<T, const K: usize, F>(rows: usize, brackets: &[Vec<Bracket<T>>; K], row_values: &F) -> Groups<T, K>
where
    T: Key,
    F: Fn(usize, &mut [Vec<T>; K]) + Sync,
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
                    for ((below, vals), &(lo, hi)) in a.iter_mut().zip(br) {
                        count_and_keep(b, lo, hi, below, vals);
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

/// The ranks (0-based) whose values the percentiles at `qs` of `n` values
/// need: floor(h) and, when h is not whole, floor(h) + 1, h = q (n - 1).
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

/// Percentiles (METHOD conventions, percentiles, NumPy's "linear" method) at the fractions
/// `qs` of `n` values from their order statistics: position h = q (n - 1),
/// x_floor(h) + (h - floor(h)) (x_floor(h)+1 - x_floor(h)). `stats` holds
/// the values at [`ranks_for`]`(n, qs)` in that order (already mapped: a
/// non-decreasing map commutes with ranking). 0 for every q when n == 0.
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

    #[test]
    fn count_and_keep_partitions_like_a_plain_loop() {
        let keys: Vec<u32> = crate::kernels::util::test_noise(1000, 5).iter().map(|v| f32_key(*v)).collect();
        for (lo, hi) in [(f32_key(0.3), f32_key(0.31)), (u32::MIN, f32_key(0.5)), (f32_key(0.99), u32::MAX)] {
            for len in [0, 5, 16, 17, 999, 1000] {
                let (mut below, mut vals) = (3usize, vec![1u32]);
                count_and_keep(&keys[..len], lo, hi, &mut below, &mut vals);
                let want_below = 3 + keys[..len].iter().filter(|&&k| k < lo).count();
                let mut want = vec![1u32];
                want.extend(keys[..len].iter().filter(|&&k| k >= lo && k <= hi));
                assert_eq!((below, vals), (want_below, want));
            }
        }
    }

    #[test]
    fn merged_brackets_cover_the_same_keys() {
        let b = vec![(10u32, 20u32), (0, 3), (15, 30), (3, 4), (40, 50), (31, 35)];
        let m = merge_brackets(b.clone());
        assert_eq!(m, vec![(0, 4), (10, 30), (31, 35), (40, 50)]);
        for k in 0..60u32 {
            let any = b.iter().any(|&(lo, hi)| lo <= k && k <= hi);
            assert_eq!(m.iter().filter(|&&(lo, hi)| lo <= k && k <= hi).count(), usize::from(any), "{k}");
        }
        assert!(merge_brackets::<u32>(Vec::new()).is_empty());
    }

    #[test]
    fn neighbouring_ranks_share_a_bracket() {
        // the tail percentiles' ranks come in pairs (floor and floor + 1)
        let n = 200_000;
        let v = data(n, 9);
        check(&v, 400, &[n / 1000, n / 1000 + 1, n - n / 1000 - 2, n - n / 1000 - 1]);
    }

    fn data(n: usize, seed: u64) -> Vec<f32> {
        // structured: a gradient plus noise, and a repeated value
        crate::kernels::util::test_noise(n, seed)
            .into_iter()
            .enumerate()
            .map(|(i, noise)| if i % 7 == 0 { 0.5 } else { (i % 300) as f32 / 300.0 * 0.3 + noise * 0.7 })
            .collect()
    }

    fn check(v: &[f32], rows: usize, ranks: &[usize]) {
        let w = v.len() / rows;
        let mut sorted = v.to_vec();
        sorted.sort_by(f32::total_cmp);
        let [got] = order_stats(rows, [v.len()], [ranks], |y, b: &mut [Vec<u32>; 1]| {
            b[0].extend(v[y * w..(y + 1) * w].iter().map(|&x| f32_key(x)));
        });
        let got: Vec<f32> = got.into_iter().map(key_f32).collect();
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
    fn keys_order_as_total_cmp() {
        let v = [f32::NEG_INFINITY, -3.5, -1e-40, -0.0, 0.0, 1e-40, 2.0, f32::INFINITY];
        for w in v.windows(2) {
            assert!(f32_key(w[0]) < f32_key(w[1]), "{w:?}");
            assert!(f64_key(w[0] as f64) < f64_key(w[1] as f64), "{w:?}");
        }
        for x in v {
            assert_eq!(key_f32(f32_key(x)).to_bits(), x.to_bits());
        }
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
