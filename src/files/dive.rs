//! `--water-from DIR`: a dive restored with the water fitted on its
//! photos that had a distance (METHOD §13, "A dive learns once"). The
//! sidecars in DIR whose `distance` was used give their fitted attenuation;
//! the median of their ratios beta_B/beta_R and beta_B/beta_G, each photo
//! weighted by how far it pins its water down (METHOD §13.6), is the water
//! type of every photo of the run (the veiling light stays each photo's
//! own: it follows the exposure and the light at that depth).

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Failure, Kind};
use crate::method::distance::{nearest_type, weighted_median};
use crate::method::water::WaterType;

/// Most sidecars read from one folder.
const MAX_SIDECARS: usize = 100_000;

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
}

impl DiveWater {
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
/// pairs, a blue pair that is not 0 < lo <= hi < 100 with a finite span,
/// or one that does not hold the sidecar's own blue attenuation `blue`
/// (the fit always lies in its range; a range that does not is none the
/// program wrote).
fn range_weight(side: &Value, blue: f64) -> Option<f64> {
    let pairs = side.pointer("/distance/water/beta_range")?.as_array()?;
    let [_, _, b] = pairs.as_slice() else { return None };
    let [lo, hi] = b.as_array()?.as_slice() else { return None };
    let (lo, hi) = (lo.as_f64()?, hi.as_f64()?);
    let span = hi / lo;
    let usable = lo > 0.0 && lo <= hi && hi < 100.0 && span.is_finite() && lo <= blue && blue <= hi;
    usable.then(|| 1.0 / span.max(1.01).ln())
}

/// The fitted attenuation a sidecar records, when its distance was used:
/// exactly three numbers, each in (0, 100).
fn fitted_beta(side: &Value) -> Option<[f64; 3]> {
    if side.pointer("/distance/used") != Some(&Value::Bool(true)) {
        return None;
    }
    let [r, g, b] = side.pointer("/distance/water/beta")?.as_array()?.as_slice() else { return None };
    let v = [r.as_f64()?, g.as_f64()?, b.as_f64()?];
    v.iter().all(|x| x.is_finite() && *x > 0.0 && *x < 100.0).then_some(v)
}

/// [`read_water_from`] once per folder and process: every photo of a run
/// gets the same water even when the run writes new sidecars into that
/// folder (the Python command makes its settings per photo).
pub fn water_from(dir: &Path) -> Result<DiveWater, Failure> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static SEEN: OnceLock<Mutex<HashMap<PathBuf, DiveWater>>> = OnceLock::new();
    let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let cache = SEEN.get_or_init(|| Mutex::new(HashMap::new()));
    if let Some(w) = cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner).get(&key) {
        return Ok(w.clone());
    }
    let w = read_water_from(dir)?;
    cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner).insert(key, w.clone());
    Ok(w)
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
    for e in entries.flatten() {
        let p = e.path();
        if p.extension().and_then(|x| x.to_str()) != Some("json") || !e.file_type().is_ok_and(|t| t.is_file()) {
            continue;
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
    for p in &paths {
        let Some(side) = crate::files::commit::read_sidecar(p) else { continue };
        if let Some(b) = fitted_beta(&side) {
            betas.push(b);
            weights.push(range_weight(&side, b[2]));
        }
    }
    if betas.is_empty() {
        return Err(Failure::new(
            Kind::Usage,
            format!(
                "--water-from {}: no sidecar there records a water fitted from a distance (restore the calibrated photos with --distance first)",
                dir.display()
            ),
        ));
    }
    let br: Vec<f64> = betas.iter().map(|b| b[2] / b[0]).collect();
    let bg: Vec<f64> = betas.iter().map(|b| b[2] / b[1]).collect();
    let range = |v: &[f64]| [v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max)];
    let spread = [range(&br), range(&bg)];
    // weighted only when every fit has its range: a folder of sidecars
    // written before the range existed keeps its plain medians
    let weights: Option<Vec<f64>> = weights.into_iter().collect();
    let med = |v: &[f64]| match &weights {
        Some(w) => weighted_median(v, w, &mut Vec::new()),
        None => median(&mut v.to_vec()),
    };
    let beta: [f64; 3] = std::array::from_fn(|c| med(&betas.iter().map(|b| b[c]).collect::<Vec<_>>()));
    let (rbr, rbg) = (med(&br), med(&bg));
    let (name, _) = nearest_type([beta[0] as f32, beta[1] as f32, beta[2] as f32]);
    let water_type = WaterType::new(&name, rbr, rbg)
        .map_err(|e| Failure::usage(format!("--water-from {}: the fitted water is not usable: {e}", dir.display())))?;
    Ok(DiveWater { folder: dir.to_path_buf(), water_type, beta, spread, photos: betas.len(), weighted: weights.is_some() })
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
