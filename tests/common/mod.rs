//! Shared helpers of the Rust tests and benches: the crate's one scene
//! generator (`src/cli/scene.rs`, included by path) and the statistics of
//! METHOD §11.
#![allow(dead_code, unused_imports)]

pub use uwhl::WaterType;

#[path = "../../src/cli/scene.rs"]
mod scene;
pub use scene::{pearson, render, rho, Rendered};

/// [`render`] in water type III: the image only.
pub fn scene(h: usize, w: usize, seed: u64) -> Vec<f32> {
    let iii = WaterType::by_name("III").expect("III is a Jerlov type");
    render(h, w, &iii, seed).img
}
