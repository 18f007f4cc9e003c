//! Peak resident memory of one restore, measured in a fresh subprocess per
//! case, against `pipeline::memory_estimate` and against 8x the float32
//! input (12 bytes per pixel):
//!
//!     cargo bench --features cli --bench memory            # 1 MP and 12 MP
//!     cargo bench --features cli --bench memory -- 2000 3000   # any H W
//!
//! Each child builds its input, resets the kernel's high-water mark
//! (`echo 5 > /proc/self/clear_refs`), runs one call and reports
//! `VmHWM - VmRSS before`: the memory the call itself added at its peak.
//! "core" is `restore` on the linear image (input already in memory);
//! "binary" is the whole `uwhl-rs` path on an 8-bit PNG (decode, restore,
//! encode, write; the input is not in memory before). Linux only.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../tests/common/mod.rs"]
mod common;

fn status_kb(key: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

fn reset_peak() -> u64 {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    status_kb("VmRSS:")
}

/// The scene of the tests (tests/common).
fn scene(h: usize, w: usize) -> Vec<f32> {
    common::scene(h, w, 1)
}

fn child_core(h: usize, w: usize, threads: usize) {
    let data = scene(h, w);
    let input = uwhl::Input {
        image: uwhl::ImageRef::new(&data, h, w).expect("image"),
        mask: None,
        water_mask: None,
    };
    let p = uwhl::Params {
        threads: Some(threads),
        ..uwhl::Params::default()
    };
    let base = reset_peak();
    let t = std::time::Instant::now();
    let r = uwhl::restore(&input, &p).expect("restore");
    let secs = t.elapsed().as_secs_f64();
    let peak = status_kb("VmHWM:");
    drop(r);
    println!("{} {} {secs:.2}", (peak.saturating_sub(base)) * 1024, base * 1024);
}

fn child_binary(png: &Path, threads: usize) {
    uwhl::cli::run::init_threads(Some(threads));
    let out = std::env::temp_dir().join(format!("uwhl-mem-out-{}", std::process::id()));
    let opts = uwhl::files::settings::Settings {
        overwrite: true,
        ..Default::default()
    };
    let (jobs, _, _) = uwhl::files::jobs::collect_jobs(&[png.to_path_buf()], &out, &[".jpg".into(), "_t.png".into(), "_t_color.png".into()]);
    let base = reset_peak();
    let t = std::time::Instant::now();
    let masks = uwhl::files::pipeline::Masks::default();
    for job in &jobs {
        uwhl::files::pipeline::process(job, &opts, &masks, None).expect("process");
    }
    let secs = t.elapsed().as_secs_f64();
    let peak = status_kb("VmHWM:");
    let _ = std::fs::remove_dir_all(&out);
    println!("{} {} {secs:.2}", (peak.saturating_sub(base)) * 1024, base * 1024);
}

fn spawn(args: &[String]) -> (u64, f64) {
    let exe = std::env::current_exe().expect("exe");
    let o = Command::new(exe).args(args).output().expect("child");
    let s = String::from_utf8_lossy(&o.stdout);
    let mut it = s.split_whitespace();
    let bytes = it.next().and_then(|v| v.parse().ok()).unwrap_or(0);
    let _base: u64 = it.next().and_then(|v| v.parse().ok()).unwrap_or(0);
    let secs = it.next().and_then(|v| v.parse().ok()).unwrap_or(0.0);
    if !o.status.success() {
        eprintln!("child {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    (bytes, secs)
}

fn write_png(path: &PathBuf, h: usize, w: usize) {
    let codes = uwhl::files::color::quantize_u8(&scene(h, w), true);
    image::RgbImage::from_raw(w as u32, h as u32, codes)
        .expect("buffer")
        .save(path)
        .expect("png");
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    match args.first().map(String::as_str) {
        Some("--child-core") => {
            let n: Vec<usize> = args[1..4].iter().map(|v| v.parse().expect("number")).collect();
            return child_core(n[0], n[1], n[2]);
        }
        Some("--child-binary") => {
            return child_binary(Path::new(&args[1]), args[2].parse().expect("threads"));
        }
        _ => {}
    }
    let sizes: Vec<(usize, usize)> = match args.as_slice() {
        [h, w] => vec![(h.parse().expect("H"), w.parse().expect("W"))],
        _ => vec![(1000, 1000), (3000, 4000)],
    };
    let dir = std::env::temp_dir().join(format!("uwhl-mem-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp");
    println!(
        "{:>10} {:>3} {:>7} | {:>9} {:>9} {:>6} | {:>9} {:>6} | {:>9} {:>7}",
        "HxW", "thr", "what", "peak MB", "est. MB", "B/px", "8x in MB", "x in", "peak/est", "seconds"
    );
    for (h, w) in sizes {
        let n = (h * w) as f64;
        let png = dir.join(format!("scene_{h}x{w}.png"));
        write_png(&png, h, w);
        for threads in [1usize, 2] {
            let est = uwhl::memory_estimate(h, w, false) as f64;
            for what in ["core", "binary"] {
                let a: Vec<String> = match what {
                    "core" => vec!["--child-core".into(), h.to_string(), w.to_string(), threads.to_string()],
                    _ => vec!["--child-binary".into(), png.display().to_string(), threads.to_string()],
                };
                let (peak, secs) = spawn(&a);
                let peak = peak as f64;
                println!(
                    "{:>10} {:>3} {:>7} | {:>9.1} {:>9.1} {:>6.1} | {:>9.1} {:>6.2} | {:>9.2} {:>7.2}",
                    format!("{h}x{w}"),
                    threads,
                    what,
                    peak / 1e6,
                    est / 1e6,
                    peak / n,
                    96.0 * n / 1e6,
                    peak / (12.0 * n),
                    peak / est,
                    secs
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
