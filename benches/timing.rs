//! Quick wall-clock timing of `restore` on a rendered scene (a development
//! aid next to the criterion benches; prints medians, asserts nothing).
//!
//!     cargo bench --bench timing -- H W MODE [REPS] [THREADS] [SUBSAMPLE]
//!
//! MODE: all (ten types, exhaustive), fast (fast selection), seq (one type
//! with the veiling light given, as in sequence mode), seqm (seq with the
//! water region given too), seqs (a `Sequence` reusing the estimates and
//! the water region of a first, untimed frame). SUBSAMPLE is
//! `guided_subsample` (1 exact, 0 automatic); with a factor above 1 the
//! result is also compared with the exact filter's. Prints each stage's
//! share (`Restoration::timings`).

use std::time::Instant;
use uwhl::{restore, ImageRef, Input, Params, Selection, Sequence, WaterType};

#[path = "../tests/common/mod.rs"]
mod common;

fn main() {
    // cargo bench adds "--bench": keep the positional arguments only
    let args: Vec<String> = std::env::args().filter(|a| !a.starts_with("--")).collect();
    let get = |i: usize, d: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (h, w) = (get(1, 1340), get(2, 2010));
    let mode = args.get(3).cloned().unwrap_or_else(|| "all".into());
    let reps = get(4, 3);
    let threads = args.get(5).and_then(|s| s.parse().ok());
    let wt = WaterType::by_name("III").unwrap_or_else(|e| panic!("{e}"));
    let data = common::render(h, w, &wt, 2).img;
    let mut inp = Input {
        image: ImageRef::new(&data, h, w).unwrap_or_else(|e| panic!("{e}")),
        mask: None,
        water_mask: None,
    };
    let sub: usize = args.get(6).and_then(|s| s.parse().ok()).unwrap_or(1);
    let mut p = Params { threads, guided_subsample: sub, ..Params::default() };
    // seq: the previous frame's A (and its water region with seqm, as the
    // README suggests for video) given
    let mut water = Vec::new();
    match mode.as_str() {
        "fast" => p.selection = Some(Selection::Fast),
        "seq" | "seqm" => {
            let prev = restore(&inp, &p).unwrap_or_else(|e| panic!("{e}"));
            p.water_types = vec![wt.clone()];
            p.veiling_light = Some(prev.veiling_light);
            water = prev.veiling_mask;
        }
        _ => {}
    }
    if mode == "seqm" {
        inp.water_mask = Some(&water);
    }
    // seqs: a Sequence (estimates on a first, untimed frame, then reused
    // with its water region; work buffers kept from frame to frame)
    let mut seq = (mode == "seqs").then(|| {
        let mut s = Sequence::new(p.clone());
        s.reuse_water_mask = true;
        s.restore(&inp).unwrap_or_else(|e| panic!("{e}"));
        s
    });
    let mut ts = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        last = Some(match seq.as_mut() {
            Some(s) => s.restore(&inp),
            None => restore(&inp, &p),
        }
        .unwrap_or_else(|e| panic!("{e}")));
        ts.push(t0.elapsed().as_secs_f64());
    }
    ts.sort_by(f64::total_cmp);
    let r = last.unwrap_or_else(|| panic!("no run"));
    println!(
        "{h}x{w} {mode} subsample {}: median {:.3} s (min {:.3}) over {reps}; chose {}",
        r.guided_subsample,
        ts[ts.len() / 2],
        ts[0],
        r.water_type.name
    );
    for (name, t) in &r.timings {
        println!("  {:>7.1} ms  {name}", t * 1e3);
    }
    if r.guided_subsample > 1 {
        // against the exact filter with the same type and A
        let e = restore(
            &inp,
            &Params {
                water_types: vec![r.water_type.clone()],
                veiling_light: Some(r.veiling_light),
                guided_subsample: 1,
                ..p.clone()
            },
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let diff = |a: &[f32], b: &[f32]| {
            let m = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
            let mean = a.iter().zip(b).map(|(x, y)| f64::from((x - y).abs())).sum::<f64>() / a.len() as f64;
            (m, mean)
        };
        let (t, i) = (diff(&r.transmission, &e.transmission), diff(&r.image, &e.image));
        println!(
            "  vs exact: t_B max {:.2e} mean {:.2e}; image max {:.2e} mean {:.2e}",
            t.0, t.1, i.0, i.1
        );
    }
}
