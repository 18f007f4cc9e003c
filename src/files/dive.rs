//! `--water-from DIR`: a dive restored with the water fitted on its
//! photos that had a distance (METHOD §13, "A dive learns once"). The
//! sidecars in DIR whose `distance` was used give their fitted attenuation;
//! the median of their ratios beta_B/beta_R and beta_B/beta_G is the water
//! type of every photo of the run (the veiling light stays each photo's
//! own: it follows the exposure and the light at that depth).

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Failure, Kind};
use crate::method::distance::nearest_type;
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

/// The fitted attenuation a sidecar records, when its distance was used.
fn fitted_beta(side: &Value) -> Option<[f64; 3]> {
    if side.pointer("/distance/used") != Some(&Value::Bool(true)) {
        return None;
    }
    let b = side.pointer("/distance/water/beta")?.as_array()?;
    let v: Vec<f64> = b.iter().filter_map(Value::as_f64).collect();
    match v.as_slice() {
        [r, g, bb] if v.iter().all(|x| x.is_finite() && *x > 0.0 && *x < 100.0) => Some([*r, *g, *bb]),
        _ => None,
    }
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
    let mut betas = Vec::new();
    for e in entries.flatten().take(MAX_SIDECARS) {
        let p = e.path();
        if p.extension().and_then(|x| x.to_str()) != Some("json") {
            continue;
        }
        if let Some(b) = crate::files::commit::read_sidecar(&p).as_ref().and_then(fitted_beta) {
            betas.push(b);
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
    let mut br: Vec<f64> = betas.iter().map(|b| b[2] / b[0]).collect();
    let mut bg: Vec<f64> = betas.iter().map(|b| b[2] / b[1]).collect();
    let range = |v: &[f64]| [v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max)];
    let spread = [range(&br), range(&bg)];
    let beta: [f64; 3] = std::array::from_fn(|c| median(&mut betas.iter().map(|b| b[c]).collect::<Vec<_>>()));
    let (rbr, rbg) = (median(&mut br), median(&mut bg));
    let (name, _) = nearest_type([beta[0] as f32, beta[1] as f32, beta[2] as f32]);
    let water_type = WaterType::new(&name, rbr, rbg)
        .map_err(|e| Failure::usage(format!("--water-from {}: the fitted water is not usable: {e}", dir.display())))?;
    Ok(DiveWater { folder: dir.to_path_buf(), water_type, beta, spread, photos: betas.len() })
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
    }
}
