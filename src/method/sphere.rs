//! Points on the unit sphere and an exact nearest-neighbour index (METHOD §4.3).

use crate::error::{Error, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::sync::{Arc, Mutex, OnceLock};

/// Largest number of sphere points accepted.
pub const MAX_POINTS: usize = 1_000_000;

/// `n` near-uniform points on the unit sphere: the Fibonacci lattice
/// (METHOD §4): z = 1 - (2i + 1)/n, phi = i * pi * (3 - sqrt 5).
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

/// Largest number of points served by the direction grid (its lists hold
/// 16-bit indices); above it the index answers with a k-d tree (the same
/// answer up to near-ties, slower per query).
pub const GRID_MAX_POINTS: usize = 20_000;

/// Bytes the index and the per-haze-line state of a restoration take for
/// each sphere point, with a margin (measured: 53 B a point, the binary's
/// peak with 1,000,000 points against 1,000 on a 64 x 64 photo, 2026-12-05).
pub const BYTES_PER_POINT: u64 = 64;

/// The bytes of the sphere index and the haze-line state of `points`
/// points: counted in every memory plan (`--sphere-points` up to a million
/// is some 60 MB whatever the image's size).
pub fn index_bytes(points: usize) -> u64 {
    (points as u64).saturating_mul(BYTES_PER_POINT)
}
/// Angular slack (radians) added to every cell's candidate radius: covers
/// the f32 rounding of a query (|u| = 1 +- 1e-7, its cell computed in f32)
/// and of the stored points, which are below 1e-6 rad.
const CELL_MARGIN: f64 = 1e-4;

/// The cluster centres of METHOD §4.3 with an exact nearest-neighbour query.
///
/// "Nearest" to a direction v (any length) means the largest dot product
/// computed in f32 as `p0 v0 + p1 v1 + p2 v2`, ties to the lowest index:
/// exactly what a brute-force scan over all points returns. For unit points
/// this orders them as the angle to v does (as the Euclidean distance to
/// v / |v| does), so v need not be normalised.
///
/// Up to [`GRID_MAX_POINTS`] points, queries use a direction grid: the six
/// faces of a cube, each cut into G x G cells in gnomonic coordinates; each
/// cell stores every point that can be the nearest for some direction in the
/// cell (all points within theta0 + 2 rho + margin of the cell centre c,
/// theta0 = angle from c to its nearest point, rho = the cell's angular
/// radius around c: a direction u in the cell is within rho of c, so its
/// nearest point is within theta0 + rho of u and thus theta0 + 2 rho of c).
/// A query scans the few candidates of its cell.
pub struct SphereIndex {
    points: Vec<[f32; 3]>,
    lookup: Lookup,
}

enum Lookup {
    Grid(DirectionGrid),
    Tree(ImmutableKdTree<f32, 3>),
}

/// The cube-map grid of candidate lists, each padded to the same length
/// (repeating its last candidate, which cannot change the answer) so that
/// every query scans the same number of entries. Lists hold 16-bit point
/// indices in increasing order (small enough to stay in cache).
struct DirectionGrid {
    /// cells per face side
    g: usize,
    /// candidates per cell (the longest list; the statistics of the grid)
    #[cfg_attr(not(any(test, feature = "internals")), allow(dead_code))]
    width: usize,
    /// groups of four candidates per cell: ceil(width / 4)
    quads: usize,
    /// `quads` groups of four point indices per cell
    cands: Vec<[u16; 4]>,
    /// the points again, for the queries
    points: Vec<[f32; 3]>,
    /// mean length of the unpadded lists
    #[cfg_attr(not(any(test, feature = "internals")), allow(dead_code))]
    mean: f64,
    /// the same lists in fixed-size tables when each fits one group
    quad: Option<QuadTable>,
}

/// Cells a [`QuadTable`] holds (6 x 64 x 64 = 24576 fit).
const QUAD_CELLS: usize = 32_768;
/// Points a [`QuadTable`] holds: every u16 index.
const QUAD_POINTS: usize = 65_536;

/// The candidate lists of a grid whose every list fits one group of four,
/// in tables of fixed size indexed by masked values: no index can be out
/// of bounds, so a row of lookups compiles to gathers without branches
/// (see [`SphereIndex::nearest_row`]).
pub struct QuadTable {
    cands: Box<[[u16; 4]; QUAD_CELLS]>,
    points: Box<[[f32; 3]; QUAD_POINTS]>,
}

impl QuadTable {
    fn new(cands: &[[u16; 4]], points: &[[f32; 3]]) -> Option<Self> {
        if cands.len() > QUAD_CELLS || points.len() > QUAD_POINTS {
            return None;
        }
        let mut c = vec![[0u16; 4]; QUAD_CELLS];
        c.iter_mut().zip(cands).for_each(|(d, s)| *d = *s);
        let mut p = vec![[f32::NAN; 3]; QUAD_POINTS];
        p.iter_mut().zip(points).for_each(|(d, s)| *d = *s);
        Some(Self {
            cands: c.into_boxed_slice().try_into().ok()?,
            points: p.into_boxed_slice().try_into().ok()?,
        })
    }

    /// [`DirectionGrid::nearest_in`] for a one-group list: the first
    /// largest dot product of the four candidates (the same tournament,
    /// the same answer).
    #[inline(always)]
    fn nearest(&self, cell: u32, v: &[f32; 3]) -> u32 {
        let q = self.cands.get(cell as usize % QUAD_CELLS).copied().unwrap_or([0; 4]);
        let dot = |c: u16| {
            let p = self.points.get(c as usize).copied().unwrap_or([f32::NAN; 3]);
            p[0] * v[0] + p[1] * v[1] + p[2] * v[2]
        };
        let (dq, kq) = tournament(q, dot);
        if dq > f32::NEG_INFINITY {
            u32::from(kq)
        } else {
            0
        }
    }
}

/// The largest of four candidates' dot products and its candidate, the
/// first on ties: 0 vs 1 and 2 vs 3, then the winners (independent
/// comparisons instead of a chain of four).
#[inline(always)]
fn tournament(q: [u16; 4], dot: impl Fn(u16) -> f32) -> (f32, u16) {
    let [c0, c1, c2, c3] = q;
    let (d0, d1, d2, d3) = (dot(c0), dot(c1), dot(c2), dot(c3));
    let (da, ka) = if d1 > d0 { (d1, c1) } else { (d0, c0) };
    let (db, kb) = if d3 > d2 { (d3, c3) } else { (d2, c2) };
    if db > da {
        (db, kb)
    } else {
        (da, ka)
    }
}

/// The nearest point for each (cell, v) of a row with a [`QuadTable`].
/// Compiled for AVX-512 (where gathers are fast and the loop vectorizes),
/// AVX2 and baseline x86-64, picked at run time; integer answers, the same
/// on every path.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512bw+avx512dq+avx2+fma", "x86_64+avx2+fma"))]
fn quad_row(t: &QuadTable, cells: &[u32], vs: &[[f32; 3]], out: &mut [u32]) {
    for ((o, &c), v) in out.iter_mut().zip(cells).zip(vs) {
        *o = t.nearest(c, v);
    }
}

/// Face of the cube and gnomonic coordinates (s, t) in [-1, 1] of a direction.
#[inline(always)]
fn face_coords(u: &[f32; 3]) -> (i32, f32, f32) {
    let [x, y, z] = *u;
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    // the major axis, chosen with selects rather than branches (directions
    // of neighbouring pixels jump between faces unpredictably)
    let fx = ax >= ay && ax >= az;
    let fy = !fx && ay >= az;
    let m = if fx { ax } else if fy { ay } else { az };
    let s = if fx { y } else { x };
    let t = if fx || fy { z } else { y };
    let neg = if fx { x < 0.0 } else if fy { y < 0.0 } else { z < 0.0 };
    let axis = i32::from(!fx) + i32::from(!fx && !fy);
    let inv = 1.0 / m;
    (2 * axis + i32::from(neg), s * inv, t * inv)
}

/// The direction (not normalised) of gnomonic point (s, t) on `face`.
fn face_dir(face: usize, s: f64, t: f64) -> [f64; 3] {
    let sign = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
    match face / 2 {
        0 => [sign, s, t],
        1 => [s, sign, t],
        _ => [s, t, sign],
    }
}

fn normalized(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Chord |a - b| between two unit vectors (monotone in their angle).
fn chord(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Angle of a chord, and chord of an angle (angles capped at pi).
fn chord_angle(c: f64) -> f64 {
    2.0 * (c / 2.0).min(1.0).asin()
}
fn angle_chord(a: f64) -> f64 {
    2.0 * (a.min(std::f64::consts::PI) / 2.0).sin()
}

impl DirectionGrid {
    /// Builds the grid over Fibonacci points (sorted by decreasing z, which
    /// lets a z band bound every search).
    fn new(points: &[[f32; 3]]) -> Self {
        let n = points.len();
        // fine enough that the default 500 points need one group of candidates
        let g = ((2.9 * (n as f64).sqrt()).ceil() as usize).clamp(1, 64);
        let p64: Vec<[f64; 3]> = points
            .iter()
            .map(|p| normalized([p[0] as f64, p[1] as f64, p[2] as f64]))
            .collect();
        // indices whose z lies in [lo, hi] (Fibonacci: z_i = 1 - (2i + 1)/n), with slack
        let band = |lo: f64, hi: f64| -> std::ops::Range<usize> {
            let idx = |z: f64| ((1.0 - z) * n as f64 - 1.0) / 2.0;
            let a = (idx(hi.min(1.0)).floor() - 1.0).max(0.0) as usize;
            let b = ((idx(lo.max(-1.0)).ceil() + 2.0).max(0.0) as usize).min(n);
            a.min(b)..b
        };
        let step = 2.0 / g as f64;
        let mut lists: Vec<Vec<u16>> = Vec::with_capacity(6 * g * g);
        for face in 0..6 {
            for i in 0..g {
                for j in 0..g {
                    let (s0, t0) = (-1.0 + step * i as f64, -1.0 + step * j as f64);
                    let c = normalized(face_dir(face, s0 + step / 2.0, t0 + step / 2.0));
                    let rho = [(0.0, 0.0), (step, 0.0), (0.0, step), (step, step)]
                        .iter()
                        .map(|&(ds, dt)| chord(&c, &normalized(face_dir(face, s0 + ds, t0 + dt))))
                        .fold(0.0, f64::max);
                    // nearest point to c: search a z band, widen until the
                    // best found is nearer than the band's half-width
                    let mut half = 4.0 / (n as f64).sqrt();
                    let near = loop {
                        let best = p64
                            .get(band(c[2] - half, c[2] + half))
                            .unwrap_or(&[])
                            .iter()
                            .map(|p| chord(&c, p))
                            .fold(f64::INFINITY, f64::min);
                        // |dz| <= chord: a nearer point lies in the band
                        if best <= half || half >= 2.0 {
                            break best;
                        }
                        half *= 2.0;
                    };
                    let radius = angle_chord(chord_angle(near) + 2.0 * chord_angle(rho) + CELL_MARGIN);
                    let r = band(c[2] - radius, c[2] + radius);
                    let list = p64
                        .iter()
                        .zip(points)
                        .enumerate()
                        .skip(r.start)
                        .take(r.len())
                        .filter(|(_, (p, _))| chord(&c, p) <= radius)
                        .map(|(k, _)| k as u16)
                        .collect();
                    lists.push(list);
                }
            }
        }
        let width = lists.iter().map(Vec::len).max().unwrap_or(1).max(1);
        let mean = lists.iter().map(Vec::len).sum::<usize>() as f64 / lists.len().max(1) as f64;
        let quads = width.div_ceil(4);
        let mut cands = Vec::with_capacity(lists.len() * quads);
        for l in &lists {
            // an empty list cannot happen (the nearest point is always in it); pad anyway
            let last = l.last().copied().unwrap_or(0);
            let mut it = l.iter().copied().chain(std::iter::repeat(last));
            for _ in 0..quads {
                cands.push(std::array::from_fn(|_| it.next().unwrap_or(last)));
            }
        }
        let quad = if quads == 1 { QuadTable::new(&cands, points) } else { None };
        Self {
            g,
            width,
            quads,
            cands,
            points: points.to_vec(),
            mean,
            quad,
        }
    }

    /// The grid cell of direction v (gnomonic coordinates in [-1, 1] cut
    /// into g cells per axis, in i32 arithmetic, which vectorizes).
    #[inline(always)]
    fn cell(&self, v: &[f32; 3]) -> usize {
        let (face, s, t) = face_coords(v);
        let g = self.g as i32;
        let (gf, top) = (0.5 * g as f32, (g - 1) as f32);
        // clamp first (NaN -> 0), then truncate: in [0, g - 1]
        let c1 = |u: f32| ((u + 1.0) * gf).max(0.0).min(top) as i32;
        ((face * g + c1(s)) * g + c1(t)) as usize
    }

    #[inline(always)]
    fn nearest(&self, v: &[f32; 3]) -> usize {
        self.nearest_in(self.cell(v), v)
    }

    /// The nearest point to v among the candidates of `cell` (v's cell).
    #[inline(always)]
    fn nearest_in(&self, cell: usize, v: &[f32; 3]) -> usize {
        let nq = self.quads;
        let run = self.cands.get(cell * nq..(cell + 1) * nq).unwrap_or(&[]);
        let pts = &self.points;
        let dot = |c: u16| {
            let p = pts.get(c as usize).copied().unwrap_or([f32::NAN; 3]);
            p[0] * v[0] + p[1] * v[1] + p[2] * v[2]
        };
        // The first largest dot product in list order (the lists are in
        // index order, padding repeats the last entry): strict > with the
        // earlier entry kept on ties. Within a group of four, a tournament
        // (0 vs 1 and 2 vs 3, then the winners) keeps the four products
        // independent instead of chaining four compare-and-selects.
        let (mut best, mut k) = (f32::NEG_INFINITY, 0u16);
        for q in run {
            let (dq, kq) = tournament(*q, dot);
            if dq > best {
                best = dq;
                k = kq;
            }
        }
        k as usize
    }
}

/// Whether `n` points on the sphere can be made: 1 <= n <= [`MAX_POINTS`]
/// (the `sphere_points` parameter).
pub fn check_points(n: usize) -> Result<()> {
    if n == 0 || n > MAX_POINTS {
        return Err(Error::Param {
            name: "sphere_points",
            msg: format!("{n} is not in 1..={MAX_POINTS}"),
        });
    }
    Ok(())
}

impl SphereIndex {
    /// Builds the index over `n` Fibonacci points (1 <= n <= [`MAX_POINTS`]).
    pub fn new(n: usize) -> Result<Self> {
        check_points(n)?;
        let points: Vec<[f32; 3]> = fibonacci_points(n)
            .into_iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        let lookup = if n <= GRID_MAX_POINTS {
            Lookup::Grid(DirectionGrid::new(&points))
        } else {
            Lookup::Tree(
                ImmutableKdTree::new_from_slice(&points)
                    .map_err(|e| Error::Internal(format!("k-d tree construction failed: {e:?}")))?,
            )
        };
        Ok(Self { points, lookup })
    }

    /// The index over `n` points, built once per process and count (the
    /// grid takes milliseconds to build; a video needs it once, not per frame).
    pub fn shared(n: usize) -> Result<Arc<Self>> {
        type Cache = Mutex<Vec<(usize, Arc<SphereIndex>)>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        if let Ok(c) = cache.lock() {
            if let Some((_, idx)) = c.iter().find(|(k, _)| *k == n) {
                return Ok(idx.clone());
            }
        }
        let idx = Arc::new(Self::new(n)?);
        // a poisoned or busy cache only costs a rebuild next time
        if let Ok(mut c) = cache.try_lock() {
            if c.len() >= 8 {
                c.remove(0);
            }
            c.push((n, idx.clone()));
        }
        Ok(idx)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    #[cfg(any(test, feature = "internals"))]
    /// Never true for a built index.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    #[cfg(any(test, feature = "internals"))]
    /// The points, as stored (f32).
    pub fn points(&self) -> &[[f32; 3]] {
        &self.points
    }

    /// Index of the point nearest to the direction `v` (exact; see the
    /// type's documentation). Above [`GRID_MAX_POINTS`] the k-d tree answers
    /// for v / |v| by Euclidean distance, which may break near-ties differently.
    #[inline]
    pub fn nearest(&self, v: &[f32; 3]) -> usize {
        match &self.lookup {
            Lookup::Grid(g) => g.nearest(v),
            Lookup::Tree(t) => {
                let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                t.query(&[v[0] / r, v[1] / r, v[2] / r])
                    .nearest_one::<SquaredEuclidean<f32>>()
                    .execute()
                    .item as usize
            }
        }
    }

    /// The lookup cell of direction v (for [`SphereIndex::nearest_in_cell`]):
    /// the first half of [`SphereIndex::nearest`], branch-free, so that a
    /// loop of it vectorizes; 0 for the k-d tree.
    #[inline(always)]
    pub fn cell(&self, v: &[f32; 3]) -> u32 {
        match &self.lookup {
            Lookup::Grid(g) => g.cell(v) as u32,
            Lookup::Tree(_) => 0,
        }
    }

    /// [`SphereIndex::nearest`] given v's cell from [`SphereIndex::cell`]
    /// (the same answer).
    #[inline(always)]
    pub fn nearest_in_cell(&self, cell: u32, v: &[f32; 3]) -> usize {
        match &self.lookup {
            Lookup::Grid(g) => g.nearest_in(cell as usize, v),
            Lookup::Tree(_) => self.nearest(v),
        }
    }

    /// [`SphereIndex::nearest_in_cell`] for a row: `out[i]` = the nearest
    /// point to `vs[i]` given its cell `cells[i]` (the same answers, in
    /// vectorized gathers where the grid's lists fit one group).
    pub fn nearest_row(&self, cells: &[u32], vs: &[[f32; 3]], out: &mut [u32]) {
        match &self.lookup {
            Lookup::Grid(DirectionGrid { quad: Some(t), .. }) => quad_row(t, cells, vs, out),
            _ => {
                for ((o, &c), v) in out.iter_mut().zip(cells).zip(vs) {
                    *o = self.nearest_in_cell(c, v) as u32;
                }
            }
        }
    }

    #[cfg(any(test, feature = "internals"))]
    /// Average number of candidates a grid query scans (None for the k-d tree).
    pub fn mean_candidates(&self) -> Option<f64> {
        match &self.lookup {
            Lookup::Grid(g) => Some(g.mean),
            Lookup::Tree(_) => None,
        }
    }

    #[cfg(any(test, feature = "internals"))]
    /// Largest number of candidates a grid query scans (None for the k-d tree).
    pub fn max_candidates(&self) -> Option<usize> {
        match &self.lookup {
            Lookup::Grid(g) => Some(g.width),
            Lookup::Tree(_) => None,
        }
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
        // METHOD §4.3: nearest-neighbour spacing about 0.16 for 500 points.
        assert!((0.14..0.18).contains(&mean), "mean spacing {mean}");
        let min = nn.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min > 0.1, "two points too close: {min}");
    }

    /// The definition of "nearest": the largest f32 dot product, ties to the lowest index.
    fn brute(points: &[[f32; 3]], v: &[f32; 3]) -> usize {
        let mut best = (f32::NEG_INFINITY, 0);
        for (k, p) in points.iter().enumerate() {
            let d = p[0] * v[0] + p[1] * v[1] + p[2] * v[2];
            if d > best.0 {
                best = (d, k);
            }
        }
        best.1
    }

    /// Deterministic pseudo-random numbers in [-1, 1) (xorshift).
    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
    }

    fn unit(v: [f64; 3]) -> [f32; 3] {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [(v[0] / n) as f32, (v[1] / n) as f32, (v[2] / n) as f32]
    }

    /// Query directions that stress the grid: random ones, the points
    /// themselves, midpoints between neighbouring points (ties), directions
    /// on cell boundaries and on cube edges and corners, and the poles.
    fn hard_queries(idx: &SphereIndex, seed: u64) -> Vec<[f32; 3]> {
        let mut r = rng(seed);
        let mut q: Vec<[f32; 3]> = (0..20_000).map(|_| unit([r(), r(), r()])).collect();
        let pts = idx.points();
        q.extend_from_slice(pts);
        for (i, a) in pts.iter().enumerate() {
            // midpoint with the nearest other point: an exact tie up to rounding
            let other = pts
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .min_by(|x, y| dist2(x.1, a).total_cmp(&dist2(y.1, a)));
            if let Some((_, b)) = other {
                let m = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
                if m.iter().any(|v| *v != 0.0) {
                    q.push(unit([m[0] as f64, m[1] as f64, m[2] as f64]));
                }
            }
        }
        if let Lookup::Grid(g) = &idx.lookup {
            // cell boundaries s or t = -1 + 2k/G (and a hair either side), on every face
            for face in 0..6 {
                for k in 0..=g.g {
                    let edge = -1.0 + 2.0 * k as f64 / g.g as f64;
                    for e in [edge, edge + 1e-7, edge - 1e-7] {
                        let t = r();
                        q.push(unit(face_dir(face, e, t)));
                        q.push(unit(face_dir(face, t, e)));
                    }
                }
            }
        }
        for v in [
            [1.0, 1.0, 0.3],
            [1.0, -1.0, 1.0],
            [-1.0, -1.0, -1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
        ] {
            q.push(unit(v));
        }
        q
    }

    #[test]
    fn grid_equals_brute_force_including_ties_and_cell_edges() {
        for n in [1usize, 2, 3, 37, 500, 2000] {
            let idx = SphereIndex::new(n).unwrap();
            assert!(matches!(idx.lookup, Lookup::Grid(_)));
            for u in hard_queries(&idx, n as u64 + 1) {
                assert_eq!(idx.nearest(&u), brute(idx.points(), &u), "n={n} u={u:?}");
                // any length: the direction counts
                let v = [u[0] * 37.5, u[1] * 37.5, u[2] * 37.5];
                assert_eq!(idx.nearest(&v), brute(idx.points(), &v), "n={n} v={v:?}");
                let v = [u[0] * 1e-3, u[1] * 1e-3, u[2] * 1e-3];
                assert_eq!(idx.nearest(&v), brute(idx.points(), &v), "n={n} v={v:?}");
            }
        }
        // the default size scans at most 4 candidates per query
        assert!(SphereIndex::new(500).unwrap().max_candidates() <= Some(4));
    }

    #[test]
    fn row_lookups_equal_brute_force() {
        // nearest_row: the fixed-table gathers (one group per cell, as at
        // 500 points) and the general path (2000 points) give the
        // brute-force answers on the hard queries, in rows of odd length
        for n in [1usize, 37, 500, 2000] {
            let idx = SphereIndex::new(n).unwrap();
            let quad = matches!(&idx.lookup, Lookup::Grid(DirectionGrid { quad: Some(_), .. }));
            assert_eq!(quad, idx.max_candidates() <= Some(4), "n={n}");
            let qs = hard_queries(&idx, n as u64 + 7);
            for row in qs.chunks(61) {
                let cells: Vec<u32> = row.iter().map(|u| idx.cell(u)).collect();
                let mut out = vec![u32::MAX; row.len()];
                idx.nearest_row(&cells, row, &mut out);
                for (u, &k) in row.iter().zip(&out) {
                    assert_eq!(k as usize, brute(idx.points(), u), "n={n} u={u:?}");
                }
            }
        }
    }

    #[test]
    fn grid_equals_brute_force_at_the_largest_grid_size() {
        let idx = SphereIndex::new(GRID_MAX_POINTS).unwrap();
        let mut r = rng(99);
        for _ in 0..3_000 {
            let u = unit([r(), r(), r()]);
            assert_eq!(idx.nearest(&u), brute(idx.points(), &u));
        }
    }

    #[test]
    fn tree_above_the_grid_size_is_exact_up_to_ties() {
        let idx = SphereIndex::new(GRID_MAX_POINTS + 1).unwrap();
        assert!(matches!(idx.lookup, Lookup::Tree(_)));
        let mut r = rng(5);
        for _ in 0..2_000 {
            let u = unit([r(), r(), r()]);
            let (k, b) = (idx.nearest(&u), brute(idx.points(), &u));
            let d = |k: usize| dist2(&idx.points()[k], &u);
            assert!((d(k) - d(b)).abs() <= 1e-6, "{} vs {}", d(k), d(b));
        }
    }

    #[test]
    fn shared_index_is_built_once() {
        let a = SphereIndex::shared(123).unwrap();
        let b = SphereIndex::shared(123).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert!(SphereIndex::shared(0).is_err());
    }

    #[test]
    fn bad_counts_are_errors() {
        assert!(SphereIndex::new(0).is_err());
        assert!(SphereIndex::new(MAX_POINTS + 1).is_err());
        assert_eq!(SphereIndex::new(1).unwrap().nearest(&[1.0, 0.0, 0.0]), 0);
    }
}
