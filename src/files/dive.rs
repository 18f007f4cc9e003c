//! `--water-from DIR`: a dive restored with the water fitted on its
//! photos that had a distance (METHOD §13, "A dive learns once"). The
//! sidecars in DIR whose `distance` was used give their fitted attenuation;
//! its median, each photo weighted by how far it pins its water down
//! (METHOD §13.6), is the water of every photo of the run (the veiling light stays each photo's
//! own: it follows the exposure and the light at that depth).

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Failure, Kind};
use crate::method::distance::{nearest_type, weighted_median};
use crate::method::water::WaterType;

/// Most sidecars read from one folder.
const MAX_SIDECARS: usize = 100_000;

/// Largest sidecar read for its fit: a photo's is a few KiB (a video's,
/// with a still for every frame, can be megabytes but records no fit), so
/// a folder of planted or sparse 16 MiB files is not read whole, nor
/// parsed beyond some 40 MB.
const MAX_FIT_SIDECAR: u64 = 1 << 20;

/// The water a folder of calibrated photos agrees on.
#[derive(Debug, Clone)]
pub struct DiveWater {
    /// the folder read
    pub folder: PathBuf,
    /// the median (beta_B/beta_R, beta_B/beta_G) as a type named after the nearest Jerlov type
    pub water_type: WaterType,
    /// the median attenuation per channel, 1/m
    pub beta: [f64; 3],
    /// the smallest and largest of each ratio over the photos
    pub spread: [[f64; 2]; 2],
    /// how many photos' fits were used
    pub photos: usize,
    /// whether the medians were weighted by each fit's range (every fit
    /// recorded one); else plain medians
    pub weighted: bool,
    /// the `*.json` files of the folder that gave no fit because they could
    /// not be read as a sidecar or record a fit none could write (a photo
    /// without a used distance is not among them): how many, and the first
    /// [`MAX_NOTES`] of them with why
    pub skipped: (usize, Vec<String>),
}

/// Most skipped sidecars named one by one on the console.
const MAX_NOTES: usize = 10;

impl DiveWater {
    /// The console's notes on the sidecars that gave no fit: one line each
    /// for the first [`MAX_NOTES`], then how many more.
    pub fn notes(&self) -> Vec<String> {
        let (n, named) = &self.skipped;
        let mut out: Vec<String> = named.iter().map(|x| format!("--water-from: {x}; not used")).collect();
        if *n > named.len() {
            out.push(format!("--water-from: {} more sidecars of {} not used", n - named.len(), self.folder.display()));
        }
        out
    }

    /// The sidecar's `parameters.water_from`.
    pub fn record(&self) -> Value {
        json!({
            "folder": self.folder.to_string_lossy(),
            "photos": self.photos,
            "beta": self.beta,
            "beta_ratios": [self.water_type.beta_br, self.water_type.beta_bg],
            "ratio_range": self.spread,
            "nearest_type": self.water_type.name,
            "weighted": self.weighted,
            "skipped": self.skipped.0,
        })
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => v.get(n / 2).copied().unwrap_or(f64::NAN),
        _ => (v.get(n / 2 - 1).copied().unwrap_or(f64::NAN) + v.get(n / 2).copied().unwrap_or(f64::NAN)) / 2.0,
    }
}

/// A fit's weight in the dive (METHOD §13.6): 1 / ln of the span of its
/// blue attenuation range (`distance.water.beta_range`, hi / lo, at least
/// 1.01), so that a photo whose content hides its water counts little.
/// None when the sidecar records no usable range: not three [lo, hi]
/// pairs, a blue pair that is not lo <= hi on the fit's attenuation grid,
/// or one that does not hold the sidecar's own blue attenuation `blue`
/// (the fit always lies in its range; a range that does not is none the
/// program wrote).
fn range_weight(side: &Value, blue: f64) -> Option<f64> {
    let pairs = side.pointer("/distance/water/beta_range")?.as_array()?;
    let [_, _, b] = pairs.as_slice() else { return None };
    let [lo, hi] = b.as_array()?.as_slice() else { return None };
    let (lo, hi) = (lo.as_f64()?, hi.as_f64()?);
    let span = hi / lo;
    let grid = crate::method::distance::BETA_MIN * (1.0 - 1e-9)..=crate::method::distance::BETA_MAX * (1.0 + 1e-9);
    let usable = grid.contains(&lo) && grid.contains(&hi) && lo <= hi && span.is_finite() && lo <= blue && blue <= hi;
    usable.then(|| 1.0 / span.max(1.01).ln())
}

/// Most weight one fit may have, as a multiple of the median weight of
/// the folder's fits (METHOD §13.6).
const MAX_WEIGHT_OVER_MEDIAN: f64 = 10.0;

/// `w` with each weight at most [`MAX_WEIGHT_OVER_MEDIAN`] times their
/// median: a narrow range is better evidence, not the whole of it. A
/// single sidecar whose range was [b, b] (weight 100) otherwise outweighed
/// sixty fits of weight 0.37 and set the dive's water alone.
fn cap_weights(mut w: Vec<f64>) -> Vec<f64> {
    let cap = MAX_WEIGHT_OVER_MEDIAN * median(&mut w.clone());
    if cap.is_finite() {
        w.iter_mut().for_each(|x| *x = x.min(cap));
    }
    w
}

/// The fitted attenuation a sidecar records, when its distance was used:
/// exactly three numbers that a fit could have written
/// ([`crate::method::distance::writable`]).
fn fitted_beta(side: &Value) -> Option<[f64; 3]> {
    if side.pointer("/distance/used") != Some(&Value::Bool(true)) {
        return None;
    }
    let [r, g, b] = side.pointer("/distance/water/beta")?.as_array()?.as_slice() else { return None };
    let v = [r.as_f64()?, g.as_f64()?, b.as_f64()?];
    crate::method::distance::writable(v).then_some(v)
}

/// The folders read in this run.
static SEEN: crate::files::jobs::PerRun<DiveWater> = crate::files::jobs::PerRun::new();

/// [`read_water_from`] once per folder and run: every photo of a run gets
/// the same water even when the run writes new sidecars into that folder
/// (the Python command makes its settings per photo).
pub fn water_from(dir: &Path) -> Result<DiveWater, Failure> {
    SEEN.get_or_read(dir, || read_water_from(dir))
}

/// A new run starts: the folders of [`water_from`] are read again (a
/// Python process, or a Dask worker, serves one run after another, and
/// the folder may have gained calibrated photos in between).
pub fn forget_water_from() {
    SEEN.forget();
}

/// Reads the sidecars (`*.json`, regular files, not recursing) of `dir`
/// and combines the fits of those whose distance was used. A folder with
/// none is a usage error naming it.
pub fn read_water_from(dir: &Path) -> Result<DiveWater, Failure> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| Failure::usage(format!("--water-from {}: cannot read the folder: {e}", dir.display())))?;
    // the sidecars: regular files named *.json (a link is not followed: a
    // link to a sidecar of the folder would count its fit twice), in name
    // order, at most MAX_SIDECARS of them (more is an error, not a silent cut)
    let mut paths = Vec::new();
    // a file with several names (hard links) is one photo's fit: read once
    let mut files = std::collections::HashSet::new();
    // *.json that are not regular files: named, not read
    let mut odd = Vec::new();
    for e in entries.flatten() {
        let p = e.path();
        if p.extension().and_then(|x| x.to_str()) != Some("json") {
            continue;
        }
        if !e.file_type().is_ok_and(|t| t.is_file()) {
            odd.push(p);
            continue;
        }
        if let Ok(m) = e.metadata() {
            use std::os::unix::fs::MetadataExt;
            if !files.insert((m.dev(), m.ino())) {
                continue;
            }
        }
        if paths.len() == MAX_SIDECARS {
            return Err(Failure::usage(format!(
                "--water-from {}: more than {MAX_SIDECARS} sidecars; give a folder of one dive's calibrated photos",
                dir.display()
            )));
        }
        paths.push(p);
    }
    paths.sort();
    let mut betas = Vec::new();
    let mut weights = Vec::new();
    let mut skipped = (0, Vec::new());
    let mut skip = |p: &Path, why: &str| {
        skipped.0 += 1;
        if skipped.1.len() < MAX_NOTES {
            skipped.1.push(format!("{}: {why}", p.display()));
        }
    };
    odd.sort();
    for p in &odd {
        skip(p, "not a regular file (a link, a folder or a pipe): not read");
    }
    for p in &paths {
        let Some(side) = crate::files::commit::read_sidecar_within(p, MAX_FIT_SIDECAR) else {
            skip(p, "not a photo's sidecar (not a regular file, over 1 MiB, or not JSON)");
            continue;
        };
        if let Some(b) = fitted_beta(&side) {
            betas.push(b);
            weights.push(range_weight(&side, b[2]));
        } else if side.pointer("/distance/used") == Some(&Value::Bool(true)) {
            skip(p, "its distance.water.beta is not three attenuations a fit gives (METHOD §13.2)");
        }
    }
    if betas.is_empty() {
        return Err(Failure::new(
            Kind::Usage,
            format!(
                "--water-from {}: no sidecar there records a water fitted from a distance (restore the calibrated photos with --distance first){}",
                dir.display(),
                if skipped.0 > 0 {
                    let first: Vec<&str> = skipped.1.iter().take(3).map(String::as_str).collect();
                    format!("; {} of its *.json files could not be used ({}{})", skipped.0, first.join("; "), if skipped.0 > 3 { "; ..." } else { "" })
                } else {
                    String::new()
                }
            ),
        ));
    }
    let br: Vec<f64> = betas.iter().map(|b| b[2] / b[0]).collect();
    let bg: Vec<f64> = betas.iter().map(|b| b[2] / b[1]).collect();
    let range = |v: &[f64]| [v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max)];
    let spread = [range(&br), range(&bg)];
    // weighted only when every fit has its range: a folder of sidecars
    // written before the range existed keeps its plain medians
    let weights: Option<Vec<f64>> = weights.into_iter().collect::<Option<Vec<f64>>>().map(cap_weights);
    let med = |v: &[f64]| match &weights {
        Some(w) => weighted_median(v, w, &mut Vec::new()),
        None => median(&mut v.to_vec()),
    };
    let beta: [f64; 3] = std::array::from_fn(|c| med(&betas.iter().filter_map(|b| b.get(c).copied()).collect::<Vec<_>>()));
    // one water: its ratios and its name from the median beta, so that the
    // name, the beta recorded and the ratios restored with agree (medians
    // of the ratios taken apart can be another type's)
    let (rbr, rbg) = (beta[2] / beta[0], beta[2] / beta[1]);
    let (name, _) = nearest_type([beta[0] as f32, beta[1] as f32, beta[2] as f32]);
    let water_type = WaterType::new(name, rbr, rbg)
        .map_err(|e| Failure::usage(format!("--water-from {}: the fitted water is not usable: {e}", dir.display())))?;
    Ok(DiveWater { folder: dir.to_path_buf(), water_type, beta, spread, photos: betas.len(), weighted: weights.is_some(), skipped })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_the_used_fits_and_nothing_else() {
        let d = std::env::temp_dir().join(format!("uwhl-dive-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let side = |b: [f64; 3], used: bool| json!({"distance": {"used": used, "water": {"beta": b}}}).to_string();
        std::fs::write(d.join("a.json"), side([0.5, 0.1, 0.05], true)).unwrap();
        std::fs::write(d.join("b.json"), side([0.4, 0.1, 0.05], true)).unwrap();
        std::fs::write(d.join("c.json"), side([0.6, 0.1, 0.05], true)).unwrap();
        // not used, not a sidecar, hostile: none counts
        std::fs::write(d.join("d.json"), side([9.0, 9.0, 0.05], false)).unwrap();
        std::fs::write(d.join("e.json"), "{not json").unwrap();
        std::fs::write(d.join("f.json"), json!({"distance": {"used": true, "water": {"beta": [-1, "x", 1e300]}}}).to_string()).unwrap();
        std::fs::write(d.join("g.txt"), side([9.0, 9.0, 0.05], true)).unwrap();
        // a fit padded past 1 MiB is no photo's sidecar: skipped and named, never read whole
        let padded = format!("{}{}", side([9.0, 9.0, 0.05], true), " ".repeat(1 << 20));
        std::fs::write(d.join("h.json"), padded).unwrap();
        // five more names of c.json: still one fit, not six that outvote a and b
        for k in 0..5 {
            std::fs::hard_link(d.join("c.json"), d.join(format!("c{k}.json"))).unwrap();
        }
        let w = read_water_from(&d).unwrap();
        assert_eq!(w.photos, 3);
        assert!((w.beta[0] - 0.5).abs() < 1e-12 && (w.beta[2] - 0.05).abs() < 1e-12);
        // ratios 0.1, 0.125, 0.0833: median 0.1; range
        assert!((w.water_type.beta_br - 0.1).abs() < 1e-12);
        assert!((w.spread[0][0] - 0.05 / 0.6).abs() < 1e-12 && (w.spread[0][1] - 0.125).abs() < 1e-12);
        let empty = d.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(read_water_from(&empty).unwrap_err().message.contains("no sidecar"));
        assert!(read_water_from(&d.join("nope")).unwrap_err().message.contains("cannot read"));
        assert!(!w.weighted);
        // e (not JSON), f (numbers no fit writes) and h (over 1 MiB) are named; d (not used) is a photo without distance
        assert_eq!(w.skipped.0, 3);
        let notes = w.notes().join("\n");
        assert!(notes.contains("e.json: not a photo's sidecar") && notes.contains("f.json: its distance.water.beta"), "{notes}");
        assert!(notes.contains("h.json: not a photo's sidecar (not a regular file, over 1 MiB"), "{notes}");
        assert!(!notes.contains("d.json"), "{notes}");
    }

    #[test]
    fn the_name_the_beta_and_the_ratios_are_one_water() {
        // three writable fits whose ratios, each taken apart, have the medians
        // of Jerlov I while their median beta is a coastal water
        let d = std::env::temp_dir().join(format!("uwhl-dive-c-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let fits = [[3.38297, 0.82833, 0.37822], [0.16084, 0.20893, 0.33307], [0.13030, 0.031906, 0.014568]];
        for (k, b) in fits.iter().enumerate() {
            let side = json!({"distance": {"used": true, "water": {"beta": b}}}).to_string();
            std::fs::write(d.join(format!("c{k}.json")), side).unwrap();
        }
        let w = read_water_from(&d).unwrap();
        assert_eq!(w.photos, 3);
        // the median beta by hand: 0.16084, 0.20893, 0.33307
        assert!((w.beta[0] - 0.16084).abs() < 1e-12 && (w.beta[1] - 0.20893).abs() < 1e-12);
        assert!((w.water_type.beta_br - 0.33307 / 0.16084).abs() < 1e-9);
        assert!((w.water_type.beta_bg - 0.33307 / 0.20893).abs() < 1e-9);
        let beta = [w.beta[0] as f32, w.beta[1] as f32, w.beta[2] as f32];
        assert_eq!(w.water_type.name, nearest_type(beta).0);
        assert_ne!(w.water_type.name, "I");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn only_numbers_a_fit_could_write_are_read() {
        use crate::method::distance::writable;
        // the Jerlov types at beta_B 0.05: on the curve
        for &(_, br, bg) in &crate::method::water::JERLOV {
            assert!(writable([0.05 / br, 0.05 / bg, 0.05]));
        }
        // a ratio of 1e-302, a blue below the grid or above it, ratios past the curve's ends by far
        for b in [[99.0, 99.0, 1e-300], [1e-300, 1e-300, 1e-300], [0.5, 0.1, 6.0], [0.05, 0.1, 0.05 * 4.5], [50.0, 0.1, 0.05], [0.5, 0.1, f64::NAN]] {
            assert!(!writable(b), "{b:?}");
        }
        let d = std::env::temp_dir().join(format!("uwhl-dive-b-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("x.json"), json!({"distance": {"used": true, "water": {"beta": [99, 99, 1e-300]}}}).to_string()).unwrap();
        let e = read_water_from(&d).unwrap_err().message;
        assert!(e.contains("no sidecar there records") && e.contains("1 of its *.json files could not be used"), "{e}");
        // many bad ones: ten named, then a count
        for k in 0..14 {
            std::fs::write(d.join(format!("y{k:02}.json")), "[").unwrap();
        }
        std::fs::write(d.join("z.json"), json!({"distance": {"used": true, "water": {"beta": [0.5, 0.1, 0.05]}}}).to_string()).unwrap();
        let w = read_water_from(&d).unwrap();
        assert_eq!((w.photos, w.skipped.0, w.skipped.1.len()), (1, 15, 10));
        assert!(w.notes().last().unwrap().contains("5 more sidecars"), "{:?}", w.notes());
    }

    #[test]
    fn fits_that_pin_their_water_down_count_more() {
        let d = std::env::temp_dir().join(format!("uwhl-dive-w-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let side = |b: [f64; 3], blue: [f64; 2]| {
            json!({"distance": {"used": true, "water": {"beta": b, "beta_range": [[0.1, 1.0], [0.1, 1.0], blue]}}}).to_string()
        };
        // one narrow fit (blue 0.05 within x1.2: weight 1 / ln 1.2 = 5.48) against two
        // wide ones (x20: weight 0.334 each): the narrow one is the weighted median
        std::fs::write(d.join("a.json"), side([0.5, 0.1, 0.05], [0.045, 0.054])).unwrap();
        std::fs::write(d.join("b.json"), side([0.4, 0.1, 0.08], [0.01, 0.2])).unwrap();
        std::fs::write(d.join("c.json"), side([0.3, 0.1, 0.09], [0.01, 0.2])).unwrap();
        let w = read_water_from(&d).unwrap();
        assert!(w.weighted);
        assert_eq!(w.photos, 3);
        assert!((w.water_type.beta_br - 0.1).abs() < 1e-12, "{}", w.water_type.beta_br);
        assert!((w.beta[2] - 0.05).abs() < 1e-12 && (w.beta[0] - 0.5).abs() < 1e-12);
        // without the narrow one's range, every fit counts the same: plain medians
        std::fs::write(d.join("a.json"), json!({"distance": {"used": true, "water": {"beta": [0.5, 0.1, 0.05], "beta_range": "x"}}}).to_string()).unwrap();
        let w = read_water_from(&d).unwrap();
        assert!(!w.weighted);
        assert!((w.water_type.beta_br - 0.2).abs() < 1e-12, "{}", w.water_type.beta_br);
        // a range that does not hold its own fit, or whose span overflows, is none
        for blue in [json!([0.06, 0.07]), json!([1e-320, 1.0])] {
            std::fs::write(
                d.join("a.json"),
                json!({"distance": {"used": true, "water": {"beta": [0.5, 0.1, 0.05], "beta_range": [[0.1, 1.0], [0.1, 1.0], blue]}}})
                    .to_string(),
            )
            .unwrap();
            assert!(!read_water_from(&d).unwrap().weighted);
        }
        // a fit whose range is one value (weight 1 / ln 1.01 = 100.5) counts at most ten
        // times the median weight (0.334 x 10): twelve wide fits (4.0 together) outweigh it
        let e = std::env::temp_dir().join(format!("uwhl-dive-cap-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&e);
        std::fs::create_dir_all(&e).unwrap();
        std::fs::write(e.join("one.json"), side([2.0, 0.6, 0.9], [0.9, 0.9])).unwrap();
        for k in 0..12 {
            std::fs::write(e.join(format!("w{k:02}.json")), side([0.4, 0.1, 0.08], [0.01, 0.2])).unwrap();
        }
        let w = read_water_from(&e).unwrap();
        assert!(w.weighted && (w.beta[2] - 0.08).abs() < 1e-12, "{:?}", w.beta);
        // with eight of them (2.7 together) the narrow fit is still the median
        for k in 8..12 {
            std::fs::remove_file(e.join(format!("w{k:02}.json"))).unwrap();
        }
        assert!((read_water_from(&e).unwrap().beta[2] - 0.9).abs() < 1e-12);
        std::fs::remove_dir_all(&e).unwrap();
        // a folder named *.json is named, not read; with no fit at all, the error names it too
        let f = std::env::temp_dir().join(format!("uwhl-dive-odd-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&f);
        std::fs::create_dir_all(f.join("x.json")).unwrap();
        let e = read_water_from(&f).unwrap_err().message;
        assert!(e.contains("1 of its *.json files could not be used") && e.contains("x.json: not a regular file"), "{e}");
        std::fs::write(f.join("z.json"), side([0.4, 0.1, 0.08], [0.01, 0.2])).unwrap();
        let w = read_water_from(&f).unwrap();
        assert_eq!((w.photos, w.skipped.0), (1, 1));
        assert!(w.notes().iter().any(|n| n.contains("x.json: not a regular file")), "{:?}", w.notes());
        std::fs::remove_dir_all(&f).unwrap();
        // a link to a sidecar of the folder is not followed: the fit counts once
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(d.join("b.json"), d.join("link.json")).unwrap();
            assert_eq!(read_water_from(&d).unwrap().photos, 3);
        }
        // by hand: values 1, 2, 3 weighted 1, 1, 3 reach half of 5 at 3; equal weights at 2
        assert_eq!(weighted_median(&[2.0, 3.0, 1.0], &[1.0, 3.0, 1.0], &mut Vec::new()), 3.0);
        assert_eq!(weighted_median(&[2.0, 3.0, 1.0], &[1.0, 1.0, 1.0], &mut Vec::new()), 2.0);
    }
}
