//! `uwhl-rs demo`: renders the crate's scene (`src/cli/scene.rs`) with a known
//! water type, restores it and reports true against estimated, as
//! `uwhl demo` does with the Python package's scene.

use super::args::{Demo, Format};
use crate::files::encode::{encode_image, encode_transmission_color, Encoding};
use super::{Failure, Kind};
use crate::{restore, ImageRef, Input, Params};
use std::io::Write;
use std::time::Instant;

fn put(path: &std::path::Path, bytes: &[u8]) -> Result<(), Failure> {
    crate::files::commit::write_file(path, bytes)
        .map_err(|e| Failure::new(Kind::Write, format!("cannot write {}: {e}", path.display())))
}

/// Runs the demo; returns the exit code.
pub fn run_demo(d: &Demo, out: &mut dyn Write) -> Result<u8, Failure> {
    let (h, w) = d.size;
    // the folder first: one that cannot be made is said before any work
    std::fs::create_dir_all(&d.out)
        .map_err(|e| Failure::new(Kind::Write, format!("cannot create {}: {e}", d.out.display())))?;
    let scene = crate::cli::scene::render(h, w, &d.water_type, d.seed);
    let input = Input { image: ImageRef::new(&scene.img, h, w)?, mask: None, water_mask: None };
    let t0 = Instant::now();
    let res = restore(&input, &Params::default())?;
    let secs = t0.elapsed().as_secs_f64();
    // the output files' own encoders: 8-bit sRGB PNGs and the colour map
    let png = Encoding { format: Format::Png, bits: 8, srgb: true, quality: 95 };
    for (name, linear) in [("input.png", &scene.img), ("restored.png", &res.image), ("clean_truth.png", &scene.clean)] {
        let path = d.out.join(name);
        put(&path, &encode_image(&path, linear, h, w, png)?)?;
    }
    let path = d.out.join("transmission.png");
    put(&path, &encode_transmission_color(&path, &res.transmission, h, w)?)?;
    let mut ranking: Vec<&(String, f64)> = res.scores.iter().collect();
    ranking.sort_by(|a, b| a.1.total_cmp(&b.1));
    let names = |v: &[&(String, f64)]| v.iter().map(|s| s.0.as_str()).collect::<Vec<_>>().join(" ");
    let rho = crate::cli::scene::rho(&scene, &res.transmission);
    let vl = res.veiling_mask.iter().filter(|&&b| b).count() as f64 / (h * w) as f64;
    let flags: Vec<&str> = res.flags.iter().map(|f| f.name()).collect();
    let a3 = |a: [f32; 3]| format!("({:.4}, {:.4}, {:.4})", a[0], a[1], a[2]);
    let lines = [
        format!("uwhl-rs {}: built-in rendered scene {h}x{w} (height x width, as --size), seed {}", env!("CARGO_PKG_VERSION"), d.seed),
        format!("true water type:      {}", d.water_type.name),
        format!(
            "estimated water type: {}   (scores, lowest first: {}; the default chooses among the three lowest, METHOD §12.2; excluded by the t_R rule: {})",
            res.water_type.name,
            names(&ranking),
            if res.excluded.is_empty() { "none".to_string() } else { res.excluded.join(", ") }
        ),
        format!("veiling light A: true {}, estimated {}", a3(scene.a), a3(res.veiling_light)),
        format!(
            "water region: {:.1}% of the image; flags: {}",
            100.0 * vl,
            if flags.is_empty() { "none".to_string() } else { flags.join(", ") }
        ),
        format!("rho(true distance, -ln t_B) = {rho:.3}"),
        format!(
            "restore took {secs:.3} s; wrote input.png, restored.png, transmission.png, clean_truth.png to {}",
            d.out.display()
        ),
    ];
    for l in lines {
        // the folder's name as every other line quotes a name (`-o` may hold control characters)
        let _ = writeln!(out, "{}", crate::cli::run::printable(&l));
    }
    Ok(0)
}
