//! Rendered test scenes for the benchmarks: an object image pushed through
//! the image formation model of METHOD §0, I = t J + (1 - t) A with
//! t_c = t_B^(beta_B / beta_c), so that every stage sees realistic data
//! (a flat water region on top, textured objects at growing distances).

use uwhl::WaterType;

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

/// An h x w linear RGB image (interleaved f32 in [0, 1]) of an underwater
/// scene in water type `wt`: open water above a wavy horizon near h / 3, a
/// seabed from 1.5 m (bottom row) to 10 m (horizon) with nearer rocks,
/// beta_B = 0.2 / m, sensor noise of std ~0.003.
pub fn render(h: usize, w: usize, wt: &WaterType, seed: u64) -> Vec<f32> {
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
    let mut img = Vec::with_capacity(h * w * 3);
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
            let base = palette[k.min(palette.len() - 1)];
            let shade = 0.6 + 0.4 * noise(xf, yf, 3.0 * scale, seed + 3);
            let tb = if z.is_finite() { (-beta_b * z).exp() } else { 0.0 };
            let t = [tb.powf(1.0 / wt.beta_br), tb.powf(1.0 / wt.beta_bg), tb];
            for c in 0..3 {
                let n = 0.006 * (hash(x as i64, y as i64 * 3 + c as i64, seed + 4) - 0.5);
                let v = t[c] * base[c] * shade + (1.0 - t[c]) * a[c] + n;
                img.push(v.clamp(0.0, 1.0) as f32);
            }
        }
    }
    img
}
