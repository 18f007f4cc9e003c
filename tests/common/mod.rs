//! Shared helpers of the Rust tests and benches: the crate's one scene
//! generator (`src/scene.rs`, included by path) and the statistics of
//! METHOD §11.
#![allow(dead_code)]

pub use uwhl::WaterType;

#[path = "../../src/scene.rs"]
mod scene;
pub use scene::{pearson, render, Rendered};

/// [`render`] in water type III: the image only.
pub fn scene(h: usize, w: usize, seed: u64) -> Vec<f32> {
    let iii = WaterType::by_name("III").expect("III is a Jerlov type");
    render(h, w, &iii, seed).img
}

/// rho(z, -ln t_B) over the object pixels of a rendered scene (METHOD §11).
pub fn rho(r: &Rendered, t: &[f32]) -> f64 {
    let (zz, lt): (Vec<f64>, Vec<f64>) = r
        .z
        .iter()
        .zip(t)
        .filter(|(z, _)| z.is_finite())
        .map(|(z, t)| (*z, -f64::from(*t).ln()))
        .unzip();
    pearson(&zz, &lt)
}
