//! Small shared tools: percentiles (METHOD conventions, percentiles), deterministic parallel
//! reductions, per-count thread pools.

use crate::error::{Error, Result};
use crate::kernels::rank::{f32_key, key_f32, order_stats, percentiles_from, ranks_for};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// Rows per chunk for deterministic reductions: partial sums are formed per
/// fixed chunk of rows and combined serially in chunk order, so the result
/// does not depend on the number of threads.
pub const REDUCE_ROWS: usize = 16;

/// `f` applied to the matching channels of two RGB triples, in channel
/// order (per-channel arithmetic without indexing).
#[inline]
pub fn zip3<A: Copy, B: Copy, R>(a: [A; 3], b: [B; 3], f: impl Fn(A, B) -> R) -> [R; 3] {
    let ([a0, a1, a2], [b0, b1, b2]) = (a, b);
    [f(a0, b0), f(a1, b1), f(a2, b2)]
}

/// Percentiles of `values` at the fractions `qs` with linear interpolation
/// between order statistics (NumPy's default "linear" method), in f64.
/// Returns 0 for an empty input.
pub fn percentiles(buf: Vec<f32>, qs: &[f64]) -> Vec<f64> {
    let n = buf.len();
    let ranks = ranks_for(n, qs);
    let rows = n.div_ceil(PSEUDO_ROW);
    let [stats] = order_stats(rows, [n], [&ranks], |y, b: &mut [Vec<u32>; 1]| {
        if let (Some(o), Some(v)) = (b.first_mut(), buf.get(y * PSEUDO_ROW..((y + 1) * PSEUDO_ROW).min(n))) {
            o.extend(v.iter().map(|&x| f32_key(x)));
        }
    });
    let stats: Vec<f64> = stats.iter().map(|&k| key_f32(k) as f64).collect();
    percentiles_from(n, qs, &stats)
}

/// Pixels per pseudo-row when a flat buffer is streamed to [`order_stats`].
const PSEUDO_ROW: usize = 4096;

/// Number of pixels whose mask entry is true (all without a mask).
pub fn masked_count(n: usize, mask: Option<&[bool]>) -> usize {
    mask.map_or(n, |m| m.par_iter().filter(|&&b| b).count())
}

/// Per channel c of an interleaved RGB buffer: the percentiles at `qs`
/// (METHOD conventions, percentiles) of `map(c, v)` over the masked-in pixels. `map` must be
/// non-decreasing in v (it then commutes with taking order statistics, so
/// only the few values at the wanted ranks are mapped).
pub fn channel_percentiles<M>(rgb: &[f32], mask: Option<&[bool]>, qs: &[f64], map: M) -> [Vec<f64>; 3]
where
    M: Fn(usize, f32) -> f32,
{
    let npx = rgb.len() / 3;
    let n = masked_count(npx, mask);
    let ranks = ranks_for(n, qs);
    let rows = npx.div_ceil(PSEUDO_ROW);
    let stats = order_stats(rows, [n; 3], [&ranks; 3], |y, b: &mut [Vec<u32>; 3]| {
        let (start, end) = (y * PSEUDO_ROW, ((y + 1) * PSEUDO_ROW).min(npx));
        let px = rgb.get(3 * start..3 * end).unwrap_or(&[]);
        let [b0, b1, b2] = b;
        match mask.and_then(|m| m.get(start..end)) {
            None => {
                // exact-size extends (no per-value capacity check)
                let px = px.as_chunks::<3>().0;
                b0.extend(px.iter().map(|p| f32_key(p[0])));
                b1.extend(px.iter().map(|p| f32_key(p[1])));
                b2.extend(px.iter().map(|p| f32_key(p[2])));
            }
            Some(m) => {
                for (&[r, g, bl], _) in px.as_chunks::<3>().0.iter().zip(m).filter(|(_, &k)| k) {
                    b0.push(f32_key(r));
                    b1.push(f32_key(g));
                    b2.push(f32_key(bl));
                }
            }
        }
    });
    let mut c = 0;
    stats.map(|v| {
        let mapped: Vec<f64> = v.iter().map(|&k| map(c, key_f32(k)) as f64).collect();
        c += 1;
        percentiles_from(n, qs, &mapped)
    })
}

/// The global min-max normalisation of METHOD §3.1 / METHOD §8 (first half):
/// x = (v - lo) / (hi - lo) in f32, or 0 everywhere when hi - lo is not a
/// finite number > 0.
#[derive(Debug, Clone, Copy)]
pub struct Normalize {
    lo: f32,
    range: Option<f32>,
}

impl Normalize {
    /// From the minimum and maximum of the values.
    pub fn new(lo: f32, hi: f32) -> Self {
        let range = hi - lo;
        Self {
            lo,
            range: (range.is_finite() && range > 0.0).then_some(range),
        }
    }

    /// From the min and max over the masked-in pixels' channels (all pixels without a mask).
    pub fn masked(rgb: &[f32], mask: Option<&[bool]>) -> Self {
        let (lo, hi) = masked_min_max(rgb, mask);
        Self::new(lo, hi)
    }

    /// The normalised value (non-decreasing in v).
    #[inline(always)]
    pub fn apply(&self, v: f32) -> f32 {
        // a select rather than a branch, so that loops of it vectorize
        let x = (v - self.lo) / self.range.unwrap_or(1.0);
        if self.range.is_some() {
            x
        } else {
            0.0
        }
    }
}

/// Per-channel linear stretch: channel c becomes clip((x - lo_c) / (hi_c -
/// lo_c), 0, 1) (computed in f64, as a product with the reciprocal), or is
/// left as it is where its limits are None.
#[derive(Debug, Clone, Copy)]
pub struct ChannelStretch {
    /// per channel: lo and 1 / (hi - lo), or None
    limits: [Option<(f64, f64)>; 3],
}

impl ChannelStretch {
    /// From per-channel limits (lo, hi) with hi > lo, or None for "unchanged".
    pub fn new(limits: [Option<(f64, f64)>; 3]) -> Self {
        Self {
            limits: limits.map(|l| l.map(|(lo, hi)| (lo, 1.0 / (hi - lo)))),
        }
    }

    /// Channel c's (lo, 1 / (hi - lo)), or None for "unchanged".
    pub fn channel(&self, c: usize) -> Option<(f64, f64)> {
        self.limits.get(c).copied().flatten()
    }

    /// The stretched value of channel c.
    #[inline(always)]
    pub fn apply(&self, c: usize, x: f32) -> f32 {
        // a select rather than a branch, so that loops of it vectorize
        let l = self.limits.get(c).copied().flatten();
        let (lo, inv) = l.unwrap_or((0.0, 1.0));
        let s = ((x as f64 - lo) * inv).clamp(0.0, 1.0) as f32;
        if l.is_some() {
            s
        } else {
            x
        }
    }

    /// Applies `f(v)` then the stretch to every value of an interleaved RGB buffer.
    pub fn map_rgb<F: Fn(f32) -> f32 + Sync>(&self, rgb: &[f32], f: F) -> Vec<f32> {
        let mut out = vec![0f32; rgb.len()];
        out.par_chunks_mut(3 * PSEUDO_ROW)
            .zip(rgb.par_chunks(3 * PSEUDO_ROW))
            .for_each(|(o, s)| {
                for (op, sp) in o.chunks_exact_mut(3).zip(s.chunks_exact(3)) {
                    for (c, (d, v)) in op.iter_mut().zip(sp).enumerate() {
                        *d = self.apply(c, f(*v));
                    }
                }
            });
        out
    }
}

/// Sum of `f(i)` for i in 0..n, accumulated in f64 in fixed chunks so that it
/// is bit-identical for any thread count.
pub fn det_sum<F: Fn(usize) -> f64 + Sync>(n: usize, chunk: usize, f: F) -> f64 {
    let chunk = chunk.max(1);
    let parts: Vec<f64> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let mut s = 0.0;
            for i in c * chunk..((c + 1) * chunk).min(n) {
                s += f(i);
            }
            s
        })
        .collect();
    parts.iter().sum()
}

/// Several sums at once (same determinism as [`det_sum`]).
pub fn det_sums<const K: usize, F: Fn(usize, &mut [f64; K]) + Sync>(
    n: usize,
    chunk: usize,
    f: F,
) -> [f64; K] {
    let chunk = chunk.max(1);
    let parts: Vec<[f64; K]> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let mut s = [0.0; K];
            for i in c * chunk..((c + 1) * chunk).min(n) {
                f(i, &mut s);
            }
            s
        })
        .collect();
    let mut out = [0.0; K];
    for p in parts {
        for (o, v) in out.iter_mut().zip(p) {
            *o += v;
        }
    }
    out
}

/// Minimum and maximum of a slice (NaN-free input).
pub fn min_max(v: &[f32]) -> (f32, f32) {
    v.par_chunks(1 << 16)
        .map(|c| {
            c.iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                })
        })
        .reduce(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        )
}

/// Minimum and maximum over all channels of the pixels of an interleaved
/// RGB slice whose mask entry is true (all pixels without a mask).
/// (inf, -inf) when no pixel counts.
pub fn masked_min_max(rgb: &[f32], mask: Option<&[bool]>) -> (f32, f32) {
    match mask {
        None => min_max(rgb),
        Some(m) => rgb
            .par_chunks(3 * 4096)
            .zip(m.par_chunks(4096))
            .map(|(px, mm)| {
                px.as_chunks::<3>().0.iter().zip(mm).filter(|(_, &b)| b).fold(
                    (f32::INFINITY, f32::NEG_INFINITY),
                    |(a, b), (&[r, g, bl], _)| {
                        (
                            a.min(r).min(g).min(bl),
                            b.max(r).max(g).max(bl),
                        )
                    },
                )
            })
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |(a, b), (c, d)| (a.min(c), b.max(d)),
            ),
    }
}

/// Bumped by [`after_fork`] in a forked child: pools made before the fork
/// have no threads there, so every pool is keyed by this generation.
static GENERATION: AtomicUsize = AtomicUsize::new(0);

/// To be called in the child after `fork()` (the Python package registers it
/// with `os.register_at_fork`): rayon's global pool and every cached pool
/// lost their threads in the fork, so from now on each call runs on a fresh
/// pool of this process.
#[cfg_attr(not(feature = "python"), allow(dead_code))]
pub fn after_fork() {
    GENERATION.fetch_add(1, Ordering::SeqCst);
}

fn build_pool(n: usize) -> Result<Arc<rayon::ThreadPool>> {
    Ok(Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(|i| format!("uwhl-{i}"))
            .build()
            .map_err(|e| Error::Internal(format!("cannot start {n} threads: {e}")))?,
    ))
}

/// Runs `f` on a rayon pool of `threads` threads (cached per count), or on
/// the global pool when `threads` is None (after a fork: on a pool of as
/// many threads as the machine has, see [`after_fork`]).
pub fn with_threads<T: Send, F: FnOnce() -> T + Send>(threads: Option<usize>, f: F) -> Result<T> {
    let generation = GENERATION.load(Ordering::SeqCst);
    let n = match threads {
        Some(n) => n,
        None if generation == 0 => return Ok(f()),
        None => std::thread::available_parallelism().map_or(1, |v| v.get()),
    };
    if n == 0 {
        return Err(Error::Param {
            name: "threads",
            msg: "must be at least 1".into(),
        });
    }
    if n > 1024 {
        return Err(Error::Param {
            name: "threads",
            msg: format!("{n} is more than 1024"),
        });
    }
    /// Thread counts whose pools are kept at once (the least recently used goes).
    const MAX_POOLS: usize = 8;
    type Pools = Mutex<(u64, HashMap<(usize, usize), (Arc<rayon::ThreadPool>, u64)>)>;
    static POOLS: OnceLock<Pools> = OnceLock::new();
    let pools = POOLS.get_or_init(|| Mutex::new((0, HashMap::new())));
    // In a forked child the lock may have been held by a thread that no
    // longer exists: never wait for it there, build an uncached pool instead.
    let guard = if generation == 0 {
        Some(
            pools
                .lock()
                .map_err(|_| Error::Internal("thread pool cache poisoned".into()))?,
        )
    } else {
        pools.try_lock().ok()
    };
    let pool = match guard {
        Some(mut cache) => {
            let (clock, map) = &mut *cache;
            *clock += 1;
            let now = *clock;
            match map.get_mut(&(generation, n)) {
                Some((p, used)) => {
                    *used = now;
                    p.clone()
                }
                None => {
                    // a caller cycling through thread counts (1..64 left 2,082 threads
                    // alive) keeps at most MAX_POOLS pools; the one dropped here ends
                    // its threads once no restoration still runs on it (the Arc)
                    if map.keys().filter(|k| k.0 == generation).count() >= MAX_POOLS {
                        let oldest = map.iter().filter(|(k, _)| k.0 == generation).min_by_key(|(_, v)| v.1).map(|(k, _)| *k);
                        if let Some(k) = oldest {
                            map.remove(&k);
                        }
                    }
                    let p = build_pool(n)?;
                    map.insert((generation, n), (p.clone(), now));
                    p
                }
            }
        }
        None => build_pool(n)?,
    };
    Ok(pool.install(f))
}

/// Deterministic pseudo-random values in [0, 1) for tests (a 64-bit LCG).
/// `buf` if it holds exactly `n` values, else n default values.
pub fn reuse<T: Copy + Default>(buf: Vec<T>, n: usize) -> Vec<T> {
    if buf.len() == n {
        buf
    } else {
        drop(buf);
        vec![T::default(); n]
    }
}

/// `buf` set to n default values: its allocation is reused when it holds
/// exactly n (the values are reset, so no result depends on them).
pub fn reuse_zeroed<T: Copy + Default>(mut buf: Vec<T>, n: usize) -> Vec<T> {
    if buf.len() == n {
        buf.fill(T::default());
        buf
    } else {
        drop(buf);
        vec![T::default(); n]
    }
}

#[cfg(test)]
pub(crate) fn test_noise(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_match_hand_values() {
        // sorted: 1 2 3 4 ; q=0.5 -> position 1.5 -> 2.5 ; q=0.1 -> 0.3 -> 1.3
        let v = [4.0f32, 1.0, 3.0, 2.0];
        let p = percentiles(v.to_vec(), &[0.0, 0.1, 0.5, 1.0]);
        assert_eq!(p[0], 1.0);
        assert!((p[1] - 1.3).abs() < 1e-12);
        assert_eq!(p[2], 2.5);
        assert_eq!(p[3], 4.0);
        assert_eq!(percentiles(vec![7.0], &[0.3]), vec![7.0]);
    }

    #[test]
    fn det_sum_is_thread_independent() {
        let f = |i: usize| (i as f64 * 0.1).sin() * 1e-3 + 1.0 / (i as f64 + 1.0);
        let a = with_threads(Some(1), || det_sum(100_000, 77, f)).unwrap();
        let b = with_threads(Some(3), || det_sum(100_000, 77, f)).unwrap();
        assert_eq!(a.to_bits(), b.to_bits());
    }

    #[test]
    fn zero_threads_is_an_error() {
        assert!(with_threads(Some(0), || 1).is_err());
    }
}
