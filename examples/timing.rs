//! Quick wall-clock timing of `restore` on a rendered scene (a development
//! aid next to the criterion benches; prints medians, asserts nothing).
//!
//!     cargo run --release --example timing -- H W MODE [REPS] [THREADS]
//!
//! MODE: all (ten types, exhaustive), fast (fast selection), seq (one type
//! with the veiling light given, as in sequence mode).

use std::time::Instant;
use uwhl::pipeline::Selection;
use uwhl::{restore, ImageRef, Input, Params, WaterType};

#[path = "../benches/scene.rs"]
mod scene;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |i: usize, d: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (h, w) = (get(1, 1340), get(2, 2010));
    let mode = args.get(3).cloned().unwrap_or_else(|| "all".into());
    let reps = get(4, 3);
    let threads = args.get(5).and_then(|s| s.parse().ok());
    let wt = WaterType::by_name("III").unwrap_or_else(|e| panic!("{e}"));
    let data = scene::render(h, w, &wt, 2);
    let inp = Input {
        image: ImageRef::new(&data, h, w).unwrap_or_else(|e| panic!("{e}")),
        mask: None,
        water_mask: None,
    };
    let mut p = Params { threads, ..Params::default() };
    match mode.as_str() {
        "fast" => p.selection = Selection::Fast,
        "seq" => {
            let a = restore(&inp, &p).unwrap_or_else(|e| panic!("{e}")).veiling_light;
            p.water_types = vec![wt.clone()];
            p.veiling_light = Some(a);
        }
        _ => {}
    }
    let mut ts = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        last = Some(restore(&inp, &p).unwrap_or_else(|e| panic!("{e}")));
        ts.push(t0.elapsed().as_secs_f64());
    }
    ts.sort_by(f64::total_cmp);
    let r = last.unwrap_or_else(|| panic!("no run"));
    println!(
        "{h}x{w} {mode}: median {:.3} s (min {:.3}) over {reps}; chose {}",
        ts[ts.len() / 2],
        ts[0],
        r.water_type.name
    );
}
