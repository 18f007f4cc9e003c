//! End-to-end tests of the `uwhl-rs` binary (feature `cli`), run as a
//! subprocess: the files of docs/OUTPUTS.md, exit codes, JSON errors,
//! hostile files, stream mode, and bit-identical outputs for any thread count.

mod common;

use serde_json::{json, Value};
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_uwhl-rs"))
}

/// A fresh, empty folder for one test.
fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("uwhl-bin-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// Writes the common scene as an 8-bit sRGB PNG.
fn scene_png(path: &Path, h: usize, w: usize, seed: u64) {
    let lin = common::scene(h, w, seed);
    let codes = uwhl::files::color::quantize_u8(&lin, true);
    image::RgbImage::from_raw(w as u32, h as u32, codes)
        .unwrap()
        .save(path)
        .unwrap();
}

fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    let mut c = bin();
    for a in args {
        c.arg(a);
    }
    c.output().unwrap()
}

fn code(o: &Output) -> i32 {
    o.status.code().unwrap_or(-1)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `uwhl-rs --stream ARGS -o OUT` fed `lines` on stdin.
fn stream(args: &[&str], out: &Path, lines: &[String]) -> std::process::Output {
    let mut child = bin()
        .arg("--stream")
        .args(args)
        .arg("-o")
        .arg(out)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        let mut stdin = child.stdin.take().unwrap();
        for l in lines {
            writeln!(stdin, "{l}").unwrap();
        }
    }
    child.wait_with_output().unwrap()
}

fn json_lines(bytes: &[u8]) -> Vec<Value> {
    String::from_utf8_lossy(bytes)
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect()
}

/// The files of an output folder, less the batch's `summary.csv` (checked
/// by `the_summary_has_a_row_per_input`).
fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .map(|rd| {
            rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n != "summary.csv")
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn the_summary_has_a_row_per_input() {
    let d = tmp("summary");
    let (good, bad, out) = (d.join("good.png"), d.join("bad.jpg"), d.join("out"));
    scene_png(&good, 24, 32, 1);
    fs::write(&bad, b"\xff\xd8\xff not a jpeg").unwrap();
    let o = bin().args([&good, &bad]).arg("-o").arg(&out).arg("-q").output().unwrap();
    assert_eq!(code(&o), 3, "{}", stderr(&o));
    let read = || {
        let text = fs::read_to_string(out.join("summary.csv")).unwrap();
        let lines: Vec<Vec<String>> = text.split("\r\n").filter(|l| !l.is_empty())
            .map(|l| l.split(',').map(String::from).collect()).collect();
        let head = lines[0].clone();
        let rows: Vec<std::collections::HashMap<String, String>> =
            lines[1..].iter().map(|r| head.iter().cloned().zip(r.iter().cloned()).collect()).collect();
        rows
    };
    let rows = read();
    assert_eq!(rows.len(), 2);
    let side: serde_json::Value = serde_json::from_slice(&fs::read(out.join("good.json")).unwrap()).unwrap();
    let g = rows.iter().find(|r| r["input"].ends_with("good.png")).unwrap();
    assert_eq!(g["status"], "done");
    assert_eq!(g["water_type"], side["water_type"].as_str().unwrap());
    assert_eq!(g["A_G"].parse::<f64>().unwrap(), side["veiling_light"][1].as_f64().unwrap());
    assert!(g["sidecar"].ends_with("good.json") && g["image"].ends_with("good.jpg"));
    let b = rows.iter().find(|r| r["input"].ends_with("bad.jpg")).unwrap();
    assert_eq!((b["status"].as_str(), b["error_kind"].as_str(), b["exit_code"].as_str()), ("failed", "unreadable_input", "3"));
    // the rerun given the good input only: it is skipped, its row filled from
    // its sidecar; the bad one's failure stays listed, first (docs/OUTPUTS.md)
    let o = bin().arg(&good).arg("-o").arg(&out).arg("-q").output().unwrap();
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let rows = read();
    assert_eq!(rows.len(), 2);
    assert!(rows[0]["input"].ends_with("bad.jpg") && rows[0]["status"] == "failed");
    assert_eq!((rows[1]["status"].as_str(), rows[1]["water_type"].as_str()), ("skipped", side["water_type"].as_str().unwrap()));
}

#[test]
fn help_documents_the_exit_codes() {
    let o = run(&[&"--help"]);
    assert_eq!(code(&o), 0);
    let text = String::from_utf8_lossy(&o.stdout);
    for needle in ["exit codes", "--max-memory", "--stream", "--reuse-estimates", "--guided-subsample", "  6    internal", "  130  interrupted", "uwhl-rs restore"] {
        assert!(text.contains(needle), "{needle}");
    }
    let o = run(&[&"--version"]);
    assert_eq!(code(&o), 0);
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("uwhl-rs 0."));
}

#[test]
fn bad_arguments_exit_2_with_one_json_error() {
    let d = tmp("args");
    for args in [
        vec!["x.png"],
        vec!["x.png", "-o", "o", "--frobnicate"],
        vec!["x.png", "-o", "o", "--water-type", "XI"],
        vec!["x.png", "-o", "o", "--max-memory", "a lot"],
        vec!["x.png", "-o", "o", "--guided-subsample", "fast"],
    ] {
        let o = bin().args(&args).arg("--json-errors").current_dir(&d).output().unwrap();
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        let errs = json_lines(&o.stderr);
        assert_eq!(errs.len(), 1, "{}", stderr(&o));
        assert_eq!(errs[0]["error"], "bad_arguments");
        assert_eq!(errs[0]["exit_code"], 2);
        assert!(errs[0]["message"].as_str().is_some_and(|m| !m.is_empty()));
    }
    // a mask of the wrong size is the caller's mistake too
    let (img, mask, out) = (d.join("a.png"), d.join("m.png"), d.join("out"));
    scene_png(&img, 24, 32, 1);
    image::GrayImage::from_pixel(8, 8, image::Luma([255])).save(&mask).unwrap();
    let o = run(&[&img, &"-o", &out, &"--mask", &mask]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("--mask is 8x8"), "{}", stderr(&o));
    assert!(files(&out).is_empty());
}

#[test]
fn writes_the_contract_files_then_skips_then_overwrites() {
    let d = tmp("contract");
    let (img, out) = (d.join("dive.png"), d.join("out"));
    scene_png(&img, 48, 64, 2);
    let o = run(&[&img, &"-o", &out, &"--format", &"png", &"--bits", &"16"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert_eq!(
        files(&out),
        ["dive.json", "dive.png", "dive_confidence.png", "dive_t.png", "dive_t_color.png"]
    );
    let side: Value = serde_json::from_slice(&fs::read(out.join("dive.json")).unwrap()).unwrap();
    assert_eq!(side["implementation"], "rust");
    assert_eq!(side["outputs"]["image"], "dive.png");
    assert_eq!(side["source"]["format"], "PNG");
    assert_eq!(side["source"]["kind"], "srgb");
    assert_eq!(side["source"]["processed_width"], 64);
    assert_eq!(side["parameters"]["bits"], 16);
    assert_eq!((&side["parameters"]["guided_subsample"], &side["guided_subsample"]), (&json!(1), &json!(1)));
    let names: Vec<&str> = side["scores"].as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(names, ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]);
    assert!(side["veiling_light"].as_array().unwrap().len() == 3);
    let im = image::open(out.join("dive.png")).unwrap();
    assert_eq!(im.color(), image::ColorType::Rgb16);
    let t = image::open(out.join("dive_t.png")).unwrap();
    assert_eq!(t.color(), image::ColorType::L16);
    let tc = image::open(out.join("dive_t_color.png")).unwrap();
    assert_eq!((tc.color(), tc.width(), tc.height()), (image::ColorType::Rgb8, 64, 48));
    assert_eq!(side["outputs"]["confidence"], "dive_confidence.png");
    let c = image::open(out.join("dive_confidence.png")).unwrap();
    assert_eq!((c.color(), c.width(), c.height()), (image::ColorType::L16, 64, 48));

    let before = fs::metadata(out.join("dive.json")).unwrap().modified().unwrap();
    let o = run(&[&img, &"-o", &out, &"--format", &"png"]);
    assert_eq!(code(&o), 0);
    assert!(String::from_utf8_lossy(&o.stdout).contains("skipped"));
    assert_eq!(fs::metadata(out.join("dive.json")).unwrap().modified().unwrap(), before);

    let o = run(&[&img, &"-o", &out, &"--format", &"tiff", &"--overwrite", &"--max-side", &"32"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(files(&out).contains(&"dive.tif".to_string()));
    let side: Value = serde_json::from_slice(&fs::read(out.join("dive.json")).unwrap()).unwrap();
    assert_eq!(side["source"]["processed_width"], 32);
    assert_eq!(side["source"]["processed_height"], 24);
    let tif = image::open(out.join("dive.tif")).unwrap();
    assert_eq!((tif.color(), tif.width()), (image::ColorType::Rgb16, 32));

    // the fast guided filter: asked for and used are both recorded; a
    // factor larger than the (processed) image is the caller's mistake
    let o = run(&[&img, &"-o", &out, &"--overwrite", &"--guided-subsample", &"3"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let side: Value = serde_json::from_slice(&fs::read(out.join("dive.json")).unwrap()).unwrap();
    assert_eq!((&side["parameters"]["guided_subsample"], &side["guided_subsample"]), (&json!(3), &json!(3)));
    let o = run(&[&img, &"-o", &d.join("big"), &"--guided-subsample", &"65"]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(stderr(&o).contains("guided_subsample"), "{}", stderr(&o));
    assert!(files(&d.join("big")).is_empty());
}

#[test]
fn a_bad_input_leaves_nothing_and_the_batch_goes_on() {
    let d = tmp("batch");
    let (good, bad, out) = (d.join("good.png"), d.join("bad.png"), d.join("out"));
    scene_png(&good, 24, 32, 3);
    fs::write(&bad, b"\x89PNG\r\n\x1a\nthis is not a png").unwrap();
    let flat = d.join("flat.png");
    image::RgbImage::from_pixel(16, 16, image::Rgb([100, 100, 100])).save(&flat).unwrap();
    let o = bin()
        .args([&bad, &flat, &good, &d.join("missing.png")])
        .arg("-o")
        .arg(&out)
        .arg("--json-errors")
        .output()
        .unwrap();
    assert_eq!(code(&o), 3, "{}", stderr(&o));
    let errs = json_lines(&o.stderr);
    assert_eq!(errs.len(), 3, "{}", stderr(&o));
    assert!(errs.iter().all(|e| e["error"] == "unreadable_input" && e["exit_code"] == 3));
    let inputs: Vec<&str> = errs.iter().map(|e| e["input"].as_str().unwrap()).collect();
    assert!(inputs.iter().any(|i| i.ends_with("flat.png")));
    assert!(errs.iter().any(|e| e["message"].as_str().unwrap().contains("constant")));
    assert_eq!(
        files(&out),
        ["good.jpg", "good.json", "good_confidence.png", "good_t.png", "good_t_color.png"]
    );
}

#[test]
fn jpeg_output_is_the_png_output_within_jpeg_error() {
    // the same restoration written losslessly (8-bit PNG) and as JPEG at
    // the default quality 95 and at quality 50: the decoded JPEGs are close
    // to the PNG, closer at the higher quality. On this noisy scene libjpeg
    // (Pillow) gives 3.21 codes at quality 95 (4:4:4) and 15.2 at 50 (4:2:0):
    // the bounds allow 10% more
    let d = tmp("jpeg");
    let (img, out) = (d.join("s.png"), d.join("out"));
    scene_png(&img, 96, 160, 8);
    let decoded = |name: &str| image::open(out.join(name)).unwrap().to_rgb8();
    let o = run(&[&img, &"-o", &out, &"--format", &"png"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let png = decoded("s.png");
    let mean_error = |q: &str| {
        let o = run(&[&img, &"-o", &out, &"--overwrite", &"--quality", &q]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let jpg = decoded("s.jpg");
        assert_eq!(jpg.dimensions(), png.dimensions());
        let n = png.as_raw().len() as f64;
        png.as_raw().iter().zip(jpg.as_raw()).map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs()).sum::<f64>() / n
    };
    let (e95, e50) = (mean_error("95"), mean_error("50"));
    assert!(e95 < 3.21 * 1.1, "quality 95: mean error {e95} codes");
    assert!(e50 > 2.0 * e95 && e50 < 15.2 * 1.1, "quality 50: {e50}, quality 95: {e95}");
}

#[test]
fn a_budget_for_one_input_at_a_time_still_restores_every_input() {
    // --max-memory that holds one input's plan but not that plus the outputs
    // of the previous input still being written: the held outputs never
    // make an input fail (the reading thread waits for the writer instead,
    // see the gate's unit test), and every input is restored
    let d = tmp("tight");
    let out = d.join("out");
    let (h, w) = (400, 600);
    let imgs: Vec<PathBuf> = (0..3).map(|k| d.join(format!("f{k}.png"))).collect();
    for (k, p) in imgs.iter().enumerate() {
        scene_png(p, h, w, 20 + k as u64);
    }
    // the plan (uwhl::files::budget::Plan) plus what the process holds anyway,
    // as the refusal reports it; the held outputs (45 B/px) are more than
    // the 1 MiB of margin that absorbs the process's own size changing
    let o = run(&[&imgs[0], &"-o", &d.join("probe"), &"--max-memory", &"1M"]);
    let need: u64 = stderr(&o).split("need about ").nth(1).and_then(|r| r.split(' ').next()).unwrap().parse().unwrap();
    assert!(45 * (h * w) as u64 > 2 << 20);
    let budget = need + (1 << 20);
    let o = run(&[&imgs[0], &imgs[1], &imgs[2], &"-o", &out, &"--max-memory", &budget.to_string(), &"-q"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert_eq!(files(&out).iter().filter(|f| f.ends_with(".json")).count(), 3);
    // less than the plan: each input is refused
    let o = run(&[&imgs[0], &"-o", &d.join("out2"), &"--max-memory", &(need - (1 << 20)).to_string(), &"-q"]);
    assert_eq!(code(&o), 4, "{}", stderr(&o));
}

#[test]
fn over_budget_is_exit_4_before_decoding() {
    let d = tmp("budget");
    let (img, out) = (d.join("a.png"), d.join("out"));
    scene_png(&img, 600, 600, 4);
    let o = run(&[&img, &"-o", &out, &"--max-memory", &"30M", &"--json-errors"]);
    assert_eq!(code(&o), 4, "{}", stderr(&o));
    assert_eq!(json_lines(&o.stderr)[0]["error"], "over_budget");
    let o = run(&[&img, &"-o", &out, &"--max-pixels", &"1000"]);
    assert_eq!(code(&o), 4, "{}", stderr(&o));
    assert!(stderr(&o).contains("--max-pixels"));
    // --max-side brings it back under the budget
    let o = run(&[&img, &"-o", &out, &"--max-memory", &"30M", &"--max-side", &"10"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
}

#[test]
fn unwritable_output_is_exit_5() {
    let d = tmp("write");
    let img = d.join("a.png");
    scene_png(&img, 24, 32, 5);
    let blocker = d.join("file");
    fs::write(&blocker, b"x").unwrap();
    let o = run(&[&img, &"-o", &blocker.join("sub"), &"--json-errors"]);
    assert_eq!(code(&o), 5, "{}", stderr(&o));
    assert_eq!(json_lines(&o.stderr)[0]["error"], "write_failed");
}

fn hostile(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hostile")
        .join(name)
}

/// The hostile files of tests/data/hostile (see make_hostile.py): each gives
/// its documented exit code quickly, with no output files.
#[test]
fn hostile_files_give_clear_errors() {
    let d = tmp("hostile");
    let out = d.join("out");
    let cases: [(&str, &[&str], i32, &str); 6] = [
        ("huge_header.png", &[], 4, "--max-pixels"),
        ("huge_header.png", &["--max-pixels", "100000000000"], 4, "--max-memory"),
        ("truncated.jpg", &[], 3, "truncated JPEG"),
        // 12000 x 12000 from 0.4 MB: about 13 GB to restore, over an 8 GB budget
        ("bomb.tif", &["--max-memory", "8G"], 4, "--max-memory"),
        ("bomb.tif", &["--max-memory", "64G", "--max-side", "1000"], 3, "constant"),
        ("bad_offsets.tif", &[], 3, "cannot decode"),
    ];
    for (name, extra, want, msg) in cases {
        let t = Instant::now();
        let o = bin().arg(hostile(name)).arg("-o").arg(&out).args(extra).output().unwrap();
        let secs = t.elapsed();
        assert_eq!(code(&o), want, "{name} {extra:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(msg), "{name}: {}", stderr(&o));
        assert!(secs < Duration::from_secs(60), "{name} took {secs:?}");
        assert!(files(&out).is_empty(), "{name}: {:?}", files(&out));
    }
}

/// Output files are byte-identical for 1, 2 and 8 threads and across runs.
#[test]
fn outputs_identical_for_1_2_8_threads() {
    let d = tmp("threads");
    let img = d.join("a.png");
    scene_png(&img, 60, 80, 6);
    let mut outs = Vec::new();
    for (k, n) in ["1", "2", "8", "2", "1"].iter().enumerate() {
        let out = d.join(format!("out{k}"));
        let o = run(&[&img, &"-o", &out, &"--threads", n, &"--format", &"png", &"--bits", &"16"]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let bytes: Vec<Vec<u8>> = ["a.png", "a_t.png", "a_t_color.png"]
            .iter()
            .map(|f| fs::read(out.join(f)).unwrap())
            .collect();
        let mut side: Value = serde_json::from_slice(&fs::read(out.join("a.json")).unwrap()).unwrap();
        let obj = side.as_object_mut().unwrap();
        obj.remove("seconds");
        obj.get_mut("parameters").unwrap().as_object_mut().unwrap().remove("threads");
        outs.push((bytes, side));
    }
    for (k, o) in outs.iter().enumerate().skip(1) {
        assert!(o.0 == outs[0].0, "run {k}: files differ");
        assert_eq!(o.1, outs[0].1, "run {k}: sidecar differs");
    }
}

#[test]
fn colliding_names_get_their_extension() {
    let d = tmp("names");
    let (png, out) = (d.join("x.png"), d.join("out"));
    scene_png(&png, 24, 32, 7);
    image::open(&png).unwrap().save(d.join("x.jpg")).unwrap();
    let o = run(&[&png, &d.join("x.jpg"), &png, &"-o", &out, &"-q"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    let f = files(&out);
    assert!(f.contains(&"x_png.json".into()) && f.contains(&"x_jpg.json".into()), "{f:?}");
    assert_eq!(f.len(), 10);
}

#[test]
fn stream_mode_survives_bad_frames_and_reuses_estimates() {
    let d = tmp("stream");
    let out = d.join("out");
    let frames: Vec<PathBuf> = (0..4).map(|k| d.join(format!("f{k}.png"))).collect();
    for (k, f) in frames.iter().enumerate() {
        scene_png(f, 30, 40, 10 + k as u64);
    }
    let garbage = d.join("garbage.jpg");
    fs::write(&garbage, b"\xff\xd8\xff\xe0 nope").unwrap();
    let lines = [
        frames[0].display().to_string(),
        d.join("missing.png").display().to_string(),
        frames[1].display().to_string(),
        String::new(),
        garbage.display().to_string(),
        frames[2].display().to_string(),
        frames[3].display().to_string(),
    ];
    let o = stream(&["--reuse-estimates", "2", "--json-errors"], &out, &lines);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let res = json_lines(&o.stdout);
    assert_eq!(res.len(), 6, "{}", String::from_utf8_lossy(&o.stdout));
    let kinds: Vec<&str> = res
        .iter()
        .map(|r| if r.get("error").is_some() { "error" } else { "ok" })
        .collect();
    assert_eq!(kinds, ["ok", "error", "ok", "error", "ok", "ok"]);
    let reused: Vec<bool> = res
        .iter()
        .filter_map(|r| r.get("reused_estimates").and_then(Value::as_bool))
        .collect();
    // estimate, reuse, estimate, reuse
    assert_eq!(reused, [false, true, false, true]);
    assert_eq!(res[2]["water_type"], res[0]["water_type"]);
    assert_eq!(res[2]["veiling_light"], res[0]["veiling_light"]);
    assert_eq!(res[2]["scores"].as_object().unwrap().len(), 1);
    assert_eq!(json_lines(&o.stderr).len(), 2);
    // the frames are on disk; skipped without --overwrite when sent again
    let o = stream(&[], &out, &[frames[0].display().to_string()]);
    let res = json_lines(&o.stdout);
    assert_eq!(res[0]["skipped"], "sidecar exists");
}

#[test]
fn stream_mode_reuses_the_water_region_when_asked() {
    // frame 0: water in the top third; frame 1: the same scene upside down
    // (seabed at the top, where METHOD §3 looks for water)
    let d = tmp("stream_vl");
    let (h, w) = (30, 40);
    let f0 = d.join("f0.png");
    scene_png(&f0, h, w, 21);
    let lin = common::scene(h, w, 22);
    let flipped: Vec<f32> = (0..h).rev().flat_map(|y| lin[3 * w * y..3 * w * (y + 1)].to_vec()).collect();
    let f1 = d.join("f1.png");
    image::RgbImage::from_raw(w as u32, h as u32, uwhl::files::color::quantize_u8(&flipped, true))
        .unwrap()
        .save(&f1)
        .unwrap();
    let lines = [f0.display().to_string(), f1.display().to_string()];
    let run = |extra: &[&str], out: &str| {
        let o = stream(&[&["--reuse-estimates", "5"], extra].concat(), &d.join(out), &lines);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        json_lines(&o.stdout)
    };
    let kept = run(&["--reuse-water-mask"], "kept");
    assert_eq!(kept[1]["reused_estimates"], true);
    assert!(kept[0]["vl_pixels"].as_u64().unwrap() > 0);
    assert_eq!(kept[1]["vl_pixels"], kept[0]["vl_pixels"]);
    let own = run(&[], "own");
    assert_eq!(own[1]["reused_estimates"], true);
    assert_ne!(own[1]["vl_pixels"], own[0]["vl_pixels"]);
    assert_eq!(own[1]["veiling_light"], kept[1]["veiling_light"]);
}
