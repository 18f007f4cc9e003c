//! Shared helpers of the integration tests: a small rendered underwater
//! scene (METHOD §0 model) and a seeded generator.
#![allow(dead_code)]

/// A seeded 64-bit LCG: uniform values in [0, 1).
pub struct Lcg(pub u64);

impl Lcg {
    /// The next value in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A linear H x W x 3 scene: water (A = (0.04, 0.22, 0.30)) in the top
/// third, below it a checkered seabed whose distance grows upward, through
/// I = t J + (1 - t) A with type III ratios, plus 0.2% noise.
pub fn scene(h: usize, w: usize, seed: u64) -> Vec<f32> {
    let (br, bg) = (0.4051f64, 0.9539f64);
    let a = [0.04f64, 0.22, 0.30];
    let colors = [[0.8, 0.4, 0.3], [0.3, 0.7, 0.4], [0.4, 0.4, 0.8], [0.7, 0.7, 0.6]];
    let mut rng = Lcg(seed);
    let mut out = Vec::with_capacity(h * w * 3);
    for y in 0..h {
        for x in 0..w {
            let water = y < h / 3;
            let z = 2.0 + 8.0 * (h - y) as f64 / h as f64;
            let tb = if water { 0.0 } else { (-0.25 * z).exp() };
            let t = [tb.powf(1.0 / br), tb.powf(1.0 / bg), tb];
            let j = colors[(x / 6 + y / 6) % colors.len()];
            for c in 0..3 {
                let v = t[c] * j[c] + (1.0 - t[c]) * a[c] + 0.002 * (rng.next() - 0.5);
                out.push(v.clamp(0.0, 1.0) as f32);
            }
        }
    }
    out
}

/// Pearson correlation of two samples (METHOD §11's rho).
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}
