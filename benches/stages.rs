//! Criterion benchmarks: each stage at 2.7 MP (2010 x 1340, the reference
//! code's working size) and the whole `restore` at 1, 2.7 and 12 MP on
//! rendered scenes, plus the fast selection mode and the sequence mode
//! (one type, veiling light given) at 1920 x 1080, also as the frames of a
//! `Sequence`; and the encoding of a restored 1080p frame's outputs.
//!
//!     cargo bench --manifest-path benches/stages/Cargo.toml              # everything (minutes)
//!     cargo bench --manifest-path benches/stages/Cargo.toml -- stage/    # only the stages
//!
//! Timings on a shared machine are noisy: compare runs made together.

use rayon::prelude::*;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::hint::black_box;
use std::time::Duration;
use uwhl::method::guided::GuideStats;
use uwhl::method::hazelines::initial_transmission;
use uwhl::method::matting::Matting;
use uwhl::method::stretch::guide_image;
use uwhl::method::recover::{display_stretch, recover};
use uwhl::method::select::{choose, type_stats};
use uwhl::method::sphere::SphereIndex;
use uwhl::method::veiling::estimate;
use uwhl::{default_radius, restore, ImageRef, Input, Params, Selection, WaterType};

#[path = "../tests/common/mod.rs"]
mod common;

/// The reference code's working size.
const REF: (usize, usize) = (1340, 2010);

fn input(data: &[f32], h: usize, w: usize) -> Input<'_> {
    Input {
        image: ImageRef::new(data, h, w).expect("bench image"),
        mask: None,
        water_mask: None,
    }
}

fn stages(c: &mut Criterion) {
    let (h, w) = REF;
    let wt = WaterType::by_name("III").expect("type III");
    let data = common::render(h, w, &wt, 1).img;
    let img = ImageRef::new(&data, h, w).expect("bench image");
    let veil = estimate(&img, None, None, None);
    let index = SphereIndex::new(500).expect("index");
    let r = default_radius(h, w);
    let mut g = c.benchmark_group("stage");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    g.bench_function("veiling_light", |b| {
        b.iter(|| estimate(black_box(&img), None, None, None))
    });
    g.bench_function("haze_lines_one_type", |b| {
        b.iter(|| initial_transmission(black_box(&img), veil.a, &wt, &index, None))
    });
    g.bench_function("matting_model_and_weights", |b| {
        b.iter(|| {
            let m = Matting::fit(black_box(&img), &veil.vl);
            m.map(|m| img.data.chunks_exact(3).map(|p| m.weight([p[0], p[1], p[2]])).sum::<f32>())
        })
    });
    g.bench_function("guide_image", |b| b.iter(|| guide_image(black_box(&data), None)));
    let guide = guide_image(&data, None);
    g.bench_function("guide_statistics", |b| {
        b.iter(|| GuideStats::new(black_box(guide.clone()), h, w, r, 1e-3))
    });
    let gs = GuideStats::new(guide.clone(), h, w, r, 1e-3);
    let t = initial_transmission(&img, veil.a, &wt, &index, None);
    g.bench_function("guided_filter_one_type", |b| b.iter(|| gs.filter(black_box(&t))));
    let q = gs.filter(&t);
    g.bench_function("recovery_one_type", |b| {
        b.iter(|| recover(black_box(&img), veil.a, &q, &wt, None))
    });
    let (j, tb) = recover(&img, veil.a, &q, &wt, None);
    g.bench_function("display_stretch", |b| b.iter(|| display_stretch(black_box(&j), None)));
    let s = display_stretch(&j, None);
    let tr: Vec<f32> = tb.iter().map(|&t| uwhl::method::recover::channel_t(t, &wt)[0]).collect();
    g.bench_function("selection_statistics_one_type", |b| {
        b.iter(|| choose(&[type_stats(black_box(&s), &tr, &veil.vl, None, w)]))
    });
    g.finish();
}

fn whole(c: &mut Criterion) {
    let wt = WaterType::by_name("III").expect("type III");
    let mut g = c.benchmark_group("restore");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (name, (h, w)) in [("1MP", (1000, 1000)), ("2.7MP", REF), ("12MP", (3000, 4000))] {
        let data = common::render(h, w, &wt, 2).img;
        let inp = input(&data, h, w);
        g.bench_with_input(BenchmarkId::new("all_ten_types", name), &inp, |b, inp| {
            b.iter(|| restore(inp, &Params::default()).expect("restore"))
        });
        if h * w > 2_000_000 {
            let p = Params {
                selection: Some(Selection::Fast),
                ..Params::default()
            };
            g.bench_with_input(BenchmarkId::new("fast_selection", name), &inp, |b, inp| {
                b.iter(|| restore(inp, &p).expect("restore"))
            });
        }
    }
    // sequence mode: the type and the veiling light of a previous frame
    let (h, w) = (1080, 1920);
    let data = common::render(h, w, &wt, 3).img;
    let inp = input(&data, h, w);
    let a = restore(&inp, &Params::default()).expect("restore").veiling_light;
    let p = Params {
        water_types: vec![wt.clone()],
        veiling_light: Some(a),
        ..Params::default()
    };
    g.bench_with_input(BenchmarkId::new("sequence_one_type_given_A", "1080p"), &inp, |b, inp| {
        b.iter(|| restore(inp, &p).expect("restore"))
    });
    // the same frames through a Sequence (estimates of a first frame, work
    // buffers kept between frames)
    let mut seq = uwhl::Sequence::new(Params::default());
    seq.restore(&inp).expect("restore");
    g.bench_with_input(BenchmarkId::new("sequence_frames", "1080p"), &inp, |b, inp| {
        b.iter(|| seq.restore(inp).expect("restore"))
    });
    g.finish();
}

/// Output encoding of a 1080p frame's restored image: the sRGB quantiser
/// (code thresholds) against the per-value formula it reproduces, run
/// side by side as the baseline, and the colour map of t.
fn outputs(c: &mut Criterion) {
    let (h, w) = (1080, 1920);
    let wt = WaterType::by_name("III").expect("type III");
    let data = common::render(h, w, &wt, 2).img;
    let res = restore(&input(&data, h, w), &Params { water_types: vec![wt], ..Params::default() }).expect("restore");
    let mut g = c.benchmark_group("outputs");
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    g.bench_function("srgb_8bit_formula_per_value", |b| {
        // the baseline: the formula per value, in parallel (the quantiser settles table estimates instead)
        b.iter(|| black_box(&res.image).par_iter().map(|&v| uwhl::files::color::quantize_one(v, 255.0, true) as u8).collect::<Vec<u8>>())
    });
    g.bench_function("srgb_8bit_quantize_u8", |b| b.iter(|| uwhl::files::color::quantize_u8(black_box(&res.image), true)));
    g.bench_function("srgb_16bit_quantize_u16", |b| b.iter(|| uwhl::files::color::quantize_u16(black_box(&res.image), true)));
    g.bench_function("colormap", |b| b.iter(|| uwhl::files::color::colormap(black_box(&res.transmission))));
    g.finish();
}

criterion_group!(benches, stages, whole, outputs);
criterion_main!(benches);
