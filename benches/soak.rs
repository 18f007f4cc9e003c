//! Soak: 1000 consecutive calls in one process must not grow its memory.
//!
//!     cargo bench --features cli --bench soak              # 1000 calls each
//!     cargo bench --features cli --bench soak -- 200       # fewer
//!
//! Two loops on a 192x256 scene: `restore` alone, then the binary's
//! decode + restore path on PNG bytes (`fuzz_one`, which also exercises the
//! decoder's allocations). VmRSS is printed after calls 10, 100, 250, 500,
//! 750 and the last; the loop fails (exit 1) if RSS after the last call is
//! more than 8 MiB above RSS after call 100 (allocator warm-up done).
//! Not part of CI (several minutes). Linux only.

#[path = "../tests/common/mod.rs"]
mod common;

fn rss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// The scene of the tests (tests/common), seed `seed`.
fn scene(h: usize, w: usize, seed: usize) -> Vec<f32> {
    common::scene(h, w, seed as u64)
}

fn soak(name: &str, calls: usize, mut f: impl FnMut(usize)) -> bool {
    let marks = [10, 100, 250, 500, 750, calls];
    let mut at100 = 0;
    let t = std::time::Instant::now();
    for i in 1..=calls {
        f(i);
        if marks.contains(&i) {
            let r = rss_kb();
            if i == 100.min(calls) {
                at100 = r;
            }
            println!("{name:>14} call {i:>5}: VmRSS {:>8.1} MB  ({:.1} s)", r as f64 / 1024.0, t.elapsed().as_secs_f64());
        }
    }
    let growth = rss_kb() as i64 - at100 as i64;
    println!("{name:>14}: growth after call 100: {:+.2} MB", growth as f64 / 1024.0);
    growth <= 8 * 1024
}

fn main() {
    let calls: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(1000);
    let (h, w) = (192, 256);
    let images: Vec<Vec<f32>> = (0..4).map(|s| scene(h, w, s)).collect();
    let ok_core = soak("restore", calls, |i| {
        let data = &images[i % images.len()];
        let input = uwhl::Input {
            image: uwhl::ImageRef::new(data, h, w).expect("image"),
            mask: None,
            water_mask: None,
        };
        let r = uwhl::restore(&input, &uwhl::Params::default()).expect("restore");
        std::hint::black_box(r);
    });
    let pngs: Vec<Vec<u8>> = images
        .iter()
        .map(|img| {
            let codes = uwhl::files::color::quantize_u8(img, true);
            let mut png = Vec::new();
            image::RgbImage::from_raw(w as u32, h as u32, codes)
                .expect("buffer")
                .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .expect("png");
            // fuzz_one's option byte 0: default options
            [vec![0u8], png].concat()
        })
        .collect();
    let ok_bin = soak("decode+restore", calls, |i| {
        let r = uwhl::files::pipeline::fuzz_one(&pngs[i % pngs.len()]).expect("decode_and_restore");
        std::hint::black_box(r);
    });
    if !(ok_core && ok_bin) {
        eprintln!("memory grew by more than 8 MiB");
        std::process::exit(1);
    }
}
