//! Small shared tools: percentiles (DECISIONS "P"), deterministic parallel
//! reductions, per-count thread pools.

use crate::error::{Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// Rows per chunk for deterministic reductions: partial sums are formed per
/// fixed chunk of rows and combined serially in chunk order, so the result
/// does not depend on the number of threads.
pub const REDUCE_ROWS: usize = 16;

/// Percentiles of `values` at the fractions `qs` with linear interpolation
/// between order statistics (NumPy's default "linear" method), in f64.
/// Takes the values by value: it reorders them in place (selection, no
/// copy). Returns 0 for an empty input.
pub fn percentiles(mut buf: Vec<f32>, qs: &[f64]) -> Vec<f64> {
    let n = buf.len();
    if n == 0 {
        return vec![0.0; qs.len()];
    }
    qs.iter()
        .map(|&q| {
            let h = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let lo = h.floor() as usize;
            let (_, &mut a, rest) = buf.select_nth_unstable_by(lo, f32::total_cmp);
            let frac = h - lo as f64;
            if frac > 0.0 {
                let b = rest.iter().copied().fold(f32::INFINITY, f32::min);
                a as f64 + frac * (b as f64 - a as f64)
            } else {
                a as f64
            }
        })
        .collect()
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
        for k in 0..K {
            out[k] += p[k];
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
                px.chunks(3).zip(mm).filter(|(_, &b)| b).fold(
                    (f32::INFINITY, f32::NEG_INFINITY),
                    |(a, b), (p, _)| {
                        (
                            a.min(p[0]).min(p[1]).min(p[2]),
                            b.max(p[0]).max(p[1]).max(p[2]),
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

/// Global min-max normalisation (x - min) / (max - min) of every value,
/// with min and max over all channels of the masked-in pixels (all pixels
/// without a mask); all zeros when they are equal (SPEC 3.1 first half,
/// SPEC 8 first half).
pub fn normalize_masked(data: &[f32], mask: Option<&[bool]>) -> Vec<f32> {
    let (lo, hi) = masked_min_max(data, mask);
    let range = hi - lo;
    if range.is_finite() && range > 0.0 {
        data.par_iter().map(|&v| (v - lo) / range).collect()
    } else {
        vec![0.0; data.len()]
    }
}

/// Per-channel linear stretch of interleaved RGB: channel c becomes
/// clip((x - lo_c) / (hi_c - lo_c), 0, 1), or is left as it is where its
/// limits are None.
pub fn stretch_channels(x: &[f32], limits: [Option<(f64, f64)>; 3]) -> Vec<f32> {
    x.par_chunks(3)
        .flat_map_iter(|px| {
            (0..3).map(move |c| match limits[c] {
                Some((lo, hi)) => ((px[c] as f64 - lo) / (hi - lo)).clamp(0.0, 1.0) as f32,
                None => px[c],
            })
        })
        .collect()
}

/// Channel `c` of an interleaved RGB slice over the pixels whose mask entry
/// is true (all pixels without a mask), in raster order.
pub fn masked_channel(rgb: &[f32], c: usize, mask: Option<&[bool]>) -> Vec<f32> {
    match mask {
        None => rgb.par_chunks(3).map(|p| p[c]).collect(),
        Some(m) => rgb
            .par_chunks(3)
            .zip(m.par_iter())
            .filter(|(_, &b)| b)
            .map(|(p, _)| p[c])
            .collect(),
    }
}

/// Bumped by [`after_fork`] in a forked child: pools made before the fork
/// have no threads there, so every pool is keyed by this generation.
static GENERATION: AtomicUsize = AtomicUsize::new(0);

/// To be called in the child after `fork()` (the Python package registers it
/// with `os.register_at_fork`): rayon's global pool and every cached pool
/// lost their threads in the fork, so from now on each call runs on a fresh
/// pool of this process.
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
    type Pools = Mutex<HashMap<(usize, usize), Arc<rayon::ThreadPool>>>;
    static POOLS: OnceLock<Pools> = OnceLock::new();
    let pools = POOLS.get_or_init(|| Mutex::new(HashMap::new()));
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
        Some(mut map) => match map.get(&(generation, n)) {
            Some(p) => p.clone(),
            None => {
                let p = build_pool(n)?;
                map.insert((generation, n), p.clone());
                p
            }
        },
        None => build_pool(n)?,
    };
    Ok(pool.install(f))
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
