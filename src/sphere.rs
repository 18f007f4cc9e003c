//! Points on the unit sphere and an exact nearest-neighbour index (SPEC 4.3).

use crate::error::{Error, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Largest number of sphere points accepted.
pub const MAX_POINTS: usize = 1_000_000;

/// `n` near-uniform points on the unit sphere: the Fibonacci lattice
/// (DECISIONS S4): z = 1 - (2i + 1)/n, phi = i * pi * (3 - sqrt 5).
pub fn fibonacci_points(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let rho = (1.0 - z * z).max(0.0).sqrt();
            let phi = i as f64 * golden;
            [rho * phi.cos(), rho * phi.sin(), z]
        })
        .collect()
}

/// The cluster centres of SPEC 4.3 with an exact nearest-neighbour query
/// (kiddo's immutable k-d tree, squared Euclidean distance, which orders
/// unit vectors the same way as the angle does).
pub struct SphereIndex {
    points: Vec<[f32; 3]>,
    tree: ImmutableKdTree<f32, 3>,
}

impl SphereIndex {
    /// Builds the index over `n` Fibonacci points (1 <= n <= [`MAX_POINTS`]).
    pub fn new(n: usize) -> Result<Self> {
        if n == 0 || n > MAX_POINTS {
            return Err(Error::Param {
                name: "sphere_points",
                msg: format!("{n} is not in 1..={MAX_POINTS}"),
            });
        }
        let points: Vec<[f32; 3]> = fibonacci_points(n)
            .into_iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        let tree = ImmutableKdTree::new_from_slice(&points)
            .map_err(|e| Error::Internal(format!("k-d tree construction failed: {e:?}")))?;
        Ok(Self { points, tree })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Never true for a built index.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points, as stored (f32).
    pub fn points(&self) -> &[[f32; 3]] {
        &self.points
    }

    /// Index of the point nearest to `u` (exact).
    #[inline]
    pub fn nearest(&self, u: &[f32; 3]) -> usize {
        let r = self
            .tree
            .query(u)
            .nearest_one::<SquaredEuclidean<f32>>()
            .execute();
        r.item as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
        (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
    }

    #[test]
    fn lattice_is_unit_and_near_uniform() {
        let p = fibonacci_points(500);
        let mut nn = Vec::new();
        for (i, a) in p.iter().enumerate() {
            let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            assert!((norm - 1.0).abs() < 1e-12);
            let mut best = f64::INFINITY;
            for (j, b) in p.iter().enumerate() {
                if i != j {
                    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                        .sqrt();
                    best = best.min(d);
                }
            }
            nn.push(best);
        }
        let mean = nn.iter().sum::<f64>() / nn.len() as f64;
        // SPEC 4.3: nearest-neighbour spacing about 0.16 for 500 points.
        assert!((0.14..0.18).contains(&mean), "mean spacing {mean}");
        let min = nn.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min > 0.1, "two points too close: {min}");
    }

    #[test]
    fn nearest_matches_brute_force() {
        let idx = SphereIndex::new(500).unwrap();
        // deterministic pseudo-random unit vectors (xorshift)
        let mut s: u64 = 0x9E3779B97F4A7C15;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..20_000 {
            let v = [rnd(), rnd(), rnd()];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n < 1e-6 {
                continue;
            }
            let u = [(v[0] / n) as f32, (v[1] / n) as f32, (v[2] / n) as f32];
            let k = idx.nearest(&u);
            let best = idx
                .points()
                .iter()
                .map(|p| dist2(p, &u))
                .fold(f32::INFINITY, f32::min);
            assert_eq!(dist2(&idx.points()[k], &u), best);
        }
    }

    #[test]
    fn bad_counts_are_errors() {
        assert!(SphereIndex::new(0).is_err());
        assert!(SphereIndex::new(MAX_POINTS + 1).is_err());
        assert_eq!(SphereIndex::new(1).unwrap().nearest(&[1.0, 0.0, 0.0]), 0);
    }
}
