//! The crate's rendered test scene: an underwater scene through the image
//! formation model of METHOD §0, I_c = t_c J_c + (1 - t_c) A_c with
//! t_c = t_B^(beta_B / beta_c), with its truth (radiance, distances, water
//! region, A). `uwhl-rs demo` shows it; the Rust tests and benches include
//! this file (tests/common), so there is one generator.
#![allow(clippy::indexing_slicing, dead_code)]

use super::WaterType;

/// A deterministic hash of a lattice point to [0, 1).
fn hash(x: i64, y: i64, seed: u64) -> f64 {
    let mut h = (x as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
        .wrapping_add(seed.wrapping_mul(0x1656_67B1_9E37_79F9));
    h ^= h >> 31;
    h = h.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [0, 1) with lattice spacing `cell` pixels.
fn noise(x: f64, y: f64, cell: f64, seed: u64) -> f64 {
    let (fx, fy) = (x / cell, y / cell);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let (i, j) = (x0 as i64, y0 as i64);
    let top = hash(i, j, seed) * (1.0 - sx) + hash(i + 1, j, seed) * sx;
    let bottom = hash(i, j + 1, seed) * (1.0 - sx) + hash(i + 1, j + 1, seed) * sx;
    top * (1.0 - sy) + bottom * sy
}

/// A rendered scene and its truth.
pub struct Rendered {
    /// rows
    pub h: usize,
    /// columns
    pub w: usize,
    /// linear RGB, interleaved, in [0, 1]
    pub img: Vec<f32>,
    /// the object radiance J, interleaved (water pixels: the seabed colour the
    /// model never shows there)
    pub clean: Vec<f32>,
    /// distance in metres per pixel; infinite on open water
    pub z: Vec<f64>,
    /// true on open water
    pub water: Vec<bool>,
    /// the veiling light
    pub a: [f32; 3],
    /// beta_B in 1 / m
    pub beta_b: f64,
}

/// An h x w scene in water type `wt`: open water above a wavy horizon near
/// h / 3, a seabed from 1.5 m (bottom row) to 10 m (horizon) with nearer
/// rocks, textured objects of five colours, A = (0.04, 0.25, 0.34),
/// beta_B = 0.2 / m, uniform sensor noise of +-0.003.
pub fn render(h: usize, w: usize, wt: &WaterType, seed: u64) -> Rendered {
    let a = [0.04f64, 0.25, 0.34];
    let beta_b = 0.2;
    let palette = [
        [0.75, 0.62, 0.45],
        [0.25, 0.55, 0.30],
        [0.70, 0.25, 0.20],
        [0.30, 0.30, 0.65],
        [0.20, 0.18, 0.16],
    ];
    let scale = h.max(w) as f64 / 512.0;
    let (mut img, mut clean) = (Vec::with_capacity(h * w * 3), Vec::with_capacity(h * w * 3));
    let (mut zs, mut water) = (Vec::with_capacity(h * w), Vec::with_capacity(h * w));
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let horizon = h as f64 * (0.33 + 0.05 * (noise(xf, 0.0, 90.0 * scale, seed) - 0.5));
            let z = if yf < horizon {
                f64::INFINITY
            } else {
                let floor = 1.5 + 8.5 * (h as f64 - yf) / (h as f64 - horizon).max(1.0);
                if noise(xf, yf, 40.0 * scale, seed + 1) > 0.72 {
                    (floor * 0.5).max(1.0)
                } else {
                    floor
                }
            };
            let k = (noise(xf, yf, 14.0 * scale, seed + 2) * palette.len() as f64) as usize;
            let base = palette.get(k).or(palette.last()).copied().unwrap_or([0.5; 3]);
            let shade = 0.6 + 0.4 * noise(xf, yf, 3.0 * scale, seed + 3);
            let tb = if z.is_finite() { (-beta_b * z).exp() } else { 0.0 };
            let t = [tb.powf(1.0 / wt.beta_br), tb.powf(1.0 / wt.beta_bg), tb];
            for c in 0..3 {
                let n = 0.006 * (hash(x as i64, y as i64 * 3 + c as i64, seed + 4) - 0.5);
                let j = base[c] * shade;
                let v = t[c] * j + (1.0 - t[c]) * a[c] + n;
                img.push(v.clamp(0.0, 1.0) as f32);
                clean.push(j as f32);
            }
            zs.push(z);
            water.push(!z.is_finite());
        }
    }
    Rendered { h, w, img, clean, z: zs, water, a: a.map(|v| v as f32), beta_b }
}


/// Pearson correlation of two samples (METHOD §11's rho).
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(1) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// rho(z, -ln t_B) over the object pixels of a rendered scene (METHOD §11).
pub fn rho(r: &Rendered, t: &[f32]) -> f64 {
    let (z, lt): (Vec<f64>, Vec<f64>) = r
        .z
        .iter()
        .zip(t)
        .filter(|(z, _)| z.is_finite())
        .map(|(z, t)| (*z, -f64::from(*t).ln()))
        .unzip();
    pearson(&z, &lt)
}
