//! The JSON sidecar `NAME.json` of docs/OUTPUTS.md, made here for both
//! commands (`implementation` says which one wrote it). Single-precision
//! results (A) are written as the f64 of the same value, as Python's
//! `float(np.float32(x))` does.

use crate::files::settings::{Preprocess, Settings};
use crate::method::params::Restoration;
use crate::method::water::WaterType;
use serde_json::{json, Value};
use std::path::Path;

/// Where the input came from (the `source` object).
#[derive(Debug, Clone)]
pub struct Source {
    /// "srgb", "linear" or "raw"
    pub kind: String,
    /// "PNG", "JPEG", "TIFF", or a raw file's extension in capitals ("DNG")
    pub format: String,
    /// bits per sample of the file
    pub bits: u8,
    /// rows after orientation
    pub height: usize,
    /// columns after orientation
    pub width: usize,
    /// EXIF orientation code applied
    pub orientation: u8,
    /// the restored data is linear light (false only with the reference preprocessing)
    pub linear: bool,
    /// the preprocessing applied
    pub preprocess: Preprocess,
    /// rows restored (after `--max-side`)
    pub processed_height: usize,
    /// columns restored
    pub processed_width: usize,
    /// the embedded ICC profile (`decode::Decoded::icc_profile`)
    pub icc_profile: Option<(String, bool, Option<String>)>,
    /// raw files: camera RGB -> linear sRGB (rows), as LibRaw gives it
    pub camera_matrix: Option<Vec<Vec<f64>>>,
    /// raw files: the as-shot white balance multipliers
    pub white_balance: Option<Vec<f64>>,
    /// what the reader noticed (raw: `white_level_below_data`, ...); the
    /// ICC profile's note is added from `icc_profile`
    pub notes: Vec<String>,
}

/// Paths of the image outputs (the sidecar names them by file name,
/// relative to itself).
#[derive(Debug, Clone)]
pub struct OutputPaths<'a> {
    /// `NAME.jpg|png|tif`
    pub image: &'a Path,
    /// `NAME_t.png`
    pub transmission: &'a Path,
    /// `NAME_t_color.png`
    pub transmission_color: &'a Path,
    /// `NAME_confidence.png`, when the method made a confidence map
    pub confidence: Option<&'a Path>,
    /// `NAME_sheet.png` (the Python command's `--contact-sheet`)
    pub contact_sheet: Option<&'a Path>,
}

/// What the sidecar records of a restoration: the estimates, without the
/// images (a `Restoration` of the core, or the fields the Python
/// `Restoration` keeps).
#[derive(Debug, Clone)]
pub struct Estimates<'a> {
    /// the chosen water type
    pub water_type: &'a WaterType,
    /// every evaluated type's score, in evaluation order
    pub scores: &'a [(String, f64)],
    /// the types excluded from the choice
    pub excluded: &'a [String],
    /// A
    pub veiling_light: [f32; 3],
    /// pixels of the water region
    pub vl_pixels: usize,
    /// pixels restored
    pub pixels: usize,
    /// the flags' names
    pub flags: Vec<&'a str>,
    /// the guided filter's radius used
    pub guided_radius: usize,
    /// its subsampling factor used
    pub guided_subsample: usize,
    /// the share of object pixels whose estimated veil exceeds the light (METHOD §12.5)
    pub veil_excess: Option<f64>,
    /// the share of the shown colour that is the input's balance (METHOD §12.5)
    pub fallback_share: Option<f64>,
    /// what became of a given distance map (METHOD §13; [`distance_record`])
    pub distance: Option<Value>,
}

impl<'a> Estimates<'a> {
    /// The estimates of a core restoration.
    pub fn of(res: &'a Restoration) -> Self {
        Self {
            water_type: &res.water_type,
            scores: &res.scores,
            excluded: &res.excluded,
            veiling_light: res.veiling_light,
            vl_pixels: res.veiling_mask.iter().filter(|&&b| b).count(),
            pixels: res.height.saturating_mul(res.width),
            flags: res.flags.iter().map(|f| f.name()).collect(),
            guided_radius: res.guided_radius,
            guided_subsample: res.guided_subsample,
            veil_excess: res.veil_excess,
            fallback_share: res.fallback_share,
            distance: res.distance.as_ref().map(|d| distance_record(d, None)),
        }
    }
}

/// The sidecar's `distance` of a file input: the restoration's record
/// with its `source` (the map's path), or, when `--distance` named no
/// readable map (`missing`: why), a record saying so (both commands).
pub fn distance_entry(record: Option<Value>, source: &str, missing: Option<&str>) -> Option<Value> {
    match (record, missing) {
        (_, Some(why)) => Some(json!({
            "source": source, "coverage": 0.0, "used": false, "rejected": why, "water": null, "light_path": null,
            "haze_order": null,
        })),
        (Some(mut r), None) => {
            if let Some(o) = r.as_object_mut() {
                o.insert("source".into(), json!(source));
            }
            Some(r)
        }
        (None, None) => None,
    }
}

/// The sidecar's `distance` (docs/OUTPUTS.md "Distance"): where the map
/// came from (`source`: a path, or "array"), the share of pixels with a
/// known distance, whether it was used and why not, the fitted water
/// (attenuation per channel in 1/m, the veiling light, the nearest Jerlov
/// type and how far from it, the fit's residual and pixels, and how far the
/// photo pins the water down: the range of each attenuation and the types
/// among the plausible waters, METHOD §13.2 step 6) and the
/// light path whose tint the display removed (metres of the same water).
pub fn distance_record(d: &crate::DistanceUse, source: Option<&str>) -> Value {
    let water = d.fit.as_ref().map(|f| {
        json!({
            "beta": f.beta.map(f64::from),
            "veiling_light": f.veiling_light.map(f64::from),
            "nearest_type": d.nearest.as_ref().map(|n| n.0.clone()),
            "type_distance": d.nearest.as_ref().map(|n| f64::from(n.1)),
            "residual": f64::from(f.residual),
            "optical_depth": f64::from(f.optical_depth),
            "pixels": f.pixels,
            "beta_range": f.beta_range.map(|r| r.map(f64::from)),
            "plausible_types": f.plausible_types,
        })
    });
    json!({
        "source": source,
        "coverage": f64::from(d.coverage),
        "used": d.rejected.is_none(),
        "rejected": d.rejected,
        "water": water,
        "light_path": d.light_path.map(f64::from),
        "haze_order": d.haze_order.map(f64::from),
    })
}

/// Seconds spent per phase.
#[derive(Debug, Clone, Copy, Default)]
pub struct Seconds {
    /// decoding and preprocessing
    pub read: f64,
    /// `restore`
    pub restore: f64,
    /// encoding and writing the image outputs
    pub write: f64,
    /// the contact sheet (when made)
    pub contact_sheet: Option<f64>,
    /// everything
    pub total: f64,
}

fn path(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// The options, in the `parameters` object: every method parameter of
/// the option table (`Params::recorded`; the water types and A as given;
/// `max_memory` as asked, "auto" when not given, so that a sidecar does not
/// follow the machine's free memory, with the budget used beside it as
/// `max_memory_used`), then the file options.
pub fn parameters(o: &Settings) -> Value {
    let types = o.water_types.as_ref().map(|list| {
        list.iter()
            .map(|c| {
                let t = &c.water_type;
                if c.custom {
                    json!([t.name, t.beta_br, t.beta_bg])
                } else {
                    json!(t.name)
                }
            })
            .collect::<Vec<_>>()
    });
    let mut p = serde_json::Map::new();
    for spec in crate::files::options::OPTIONS.iter().filter(|s| s.method) {
        let v = match spec.key {
            "water_types" => json!(types),
            "veiling_light" => json!(o.veiling_light),
            "max_memory" if !o.max_memory_given => json!("auto"),
            key => o.params.recorded(key).unwrap_or(Value::Null),
        };
        p.insert(spec.key.to_string(), v);
    }
    let files = json!({
        "max_memory_used": o.params.max_memory,
        "mask": o.mask.as_deref().map(path),
        "water_mask": o.water_mask.as_deref().map(path),
        "max_side": o.max_side,
        "max_pixels": o.max_pixels,
        "preprocess": o.preprocess.name(),
        "half_size": o.half_size,
        "format": o.format.name(),
        "bits": o.bits(),
        "quality": o.quality,
        "linear": o.linear,
    });
    if let Value::Object(f) = files {
        p.extend(f);
    }
    if let Some(d) = &o.distance {
        p.insert("distance".into(), json!(d));
        if o.depth_along_axis {
            p.insert("distance_kind".into(), json!("depth"));
        }
    }
    // the floor's pose and lens: a rerun with another altitude, field of
    // view or window is said to have been restored with another one
    if let Some(a) = &o.altitude {
        use crate::files::nav::AltitudeSource;
        let v = match a {
            AltitudeSource::Constant(h) => json!(h),
            AltitudeSource::Xmp => json!("xmp"),
            AltitudeSource::Log(l) => json!(path(&l.path)),
        };
        p.insert("altitude".into(), v);
    }
    if o.altitude.is_some() || (o.distance.is_some() && o.depth_along_axis) {
        p.insert("fov".into(), json!(o.fov));
        p.insert("port".into(), json!(o.port.name()));
    }
    if let Some(d) = &o.water_from {
        p.insert("water_from".into(), d.record());
    }
    Value::Object(p)
}

/// What an input's progress line says after its water type when its
/// colours are the input's balance throughout (METHOD §12.5: the type named
/// did not colour it), in both commands.
pub fn balance_said(fallback_share: Option<f64>) -> &'static str {
    match fallback_share {
        Some(s) if s >= crate::method::fallback::BALANCED => ", colours from the input's balance",
        _ => "",
    }
}

/// What an input's progress line says after its water type, in both
/// commands: that a distance was asked for and not used (no map found for
/// it, or a map the fit refused: the sidecar's `distance.rejected` says
/// why), and [`balance_said`]. `flags` are the sidecar's.
pub fn progress_said(fallback_share: Option<f64>, flags: &[&str]) -> String {
    let distance = if flags.contains(&"distance_missing") {
        ", no distance (see distance.rejected)"
    } else if flags.contains(&"distance_rejected") {
        ", distance not used (see distance.rejected)"
    } else {
        ""
    };
    format!("{distance}{}", balance_said(fallback_share))
}

/// The note both commands print once before the inputs when a water type
/// (`--water-type`) or a dive's water (`--water-from`) is given with a
/// source of distance (`--distance`, `--altitude`): a photo whose distance
/// is used is restored with the water fitted to it (METHOD §13), the given
/// water only where it is not. Each argument says whether that option was given.
pub fn water_with_distance_note(water_from: bool, water_type: bool, distance: bool, altitude: bool) -> Option<String> {
    let water = if water_from {
        "--water-from"
    } else if water_type {
        "--water-type"
    } else {
        return None;
    };
    let distance = if distance {
        "--distance"
    } else if altitude {
        "--altitude"
    } else {
        return None;
    };
    Some(format!(
        "{water} is used for the photos whose {distance} gives no usable distance; a photo with one is restored with \
         the water fitted to it (its sidecar's distance.water)"
    ))
}

/// The note both commands print once before the inputs when `--transfer`
/// is given to a run that may hold no video (`videos`: whether it may; the
/// binary's batches never do): photos are decoded by their own colour
/// profile, and the curve does nothing for them.
pub fn transfer_note(transfer: bool, videos: bool) -> Option<String> {
    (transfer && !videos).then(|| {
        "--transfer is the curve of video and raw-frame samples: photos are decoded through their own colour profile, \
         and it does nothing for them"
            .to_string()
    })
}

/// The options of `current` (what [`parameters`] gives for this run) that
/// differ from those the sidecar at `path` recorded, by name and sorted:
/// what a skipped input (its sidecar exists) says it was restored with.
/// The machine's knobs (`threads`, `max_memory`, `max_memory_used`) do not
/// change a result and are left out; an unreadable sidecar, or one without
/// `parameters`, gives none.
pub fn changed_options(path: &Path, current: &Value) -> Vec<String> {
    const MACHINE: [&str; 3] = ["threads", "max_memory", "max_memory_used"];
    let Some(side) = crate::files::commit::read_sidecar(path) else { return Vec::new() };
    let (Some(Value::Object(was)), Value::Object(now)) = (side.get("parameters"), current) else {
        return Vec::new();
    };
    let mut keys: Vec<String> = was
        .keys()
        .chain(now.keys())
        .filter(|k| !MACHINE.contains(&k.as_str()) && was.get(*k) != now.get(*k))
        .cloned()
        .collect();
    keys.sort();
    keys.dedup();
    keys
}

/// What a skipped input's line says after "NAME.json exists": the options
/// it was restored with that differ from this run's, by their flags, if any.
pub fn changed_said(changed: &[String]) -> String {
    if changed.is_empty() {
        return String::new();
    }
    format!("; restored with another {}: --overwrite redoes it", flags_of(changed).join(", "))
}

/// The command-line flags of the sidecar's parameter names `keys` (a name
/// without a flag as it is).
pub fn flags_of(keys: &[String]) -> Vec<String> {
    keys.iter()
        .map(|k| {
            crate::files::options::OPTIONS
                .iter()
                .find(|s| s.key == k.as_str())
                .map_or_else(|| k.clone(), |s| s.flag.to_string())
        })
        .collect()
}

/// The sidecar's `source.icc_profile`: the profile's description and
/// whether the codes were converted through it (null without a profile),
/// as the Python reader writes it.
fn icc_json(source: &Source) -> Value {
    match &source.icc_profile {
        None => Value::Null,
        Some((name, converted, _)) => json!({"description": name, "converted": converted}),
    }
}

fn notes(source: &Source) -> Vec<String> {
    let mut notes = source.notes.clone();
    if let Some((_, _, Some(why))) = &source.icc_profile {
        notes.push(format!("the ICC profile cannot be read ({why}); read as sRGB"));
    }
    notes
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The whole sidecar object: `input` is the input as the batch names it
/// (a path, or a URL for object storage), `implementation` "rust" or
/// "python", `parameters` made by [`parameters`].
pub fn sidecar(
    input: &str,
    implementation: &str,
    outputs: &OutputPaths,
    source: &Source,
    est: &Estimates,
    parameters: &Value,
    seconds: Seconds,
) -> Value {
    let scores: serde_json::Map<String, Value> = est
        .scores
        .iter()
        .map(|(name, s)| (name.clone(), json!(s)))
        .collect();
    let a: Vec<f64> = est.veiling_light.iter().map(|&v| f64::from(v)).collect();
    let mut names = serde_json::Map::new();
    names.insert("image".into(), json!(file_name(outputs.image)));
    names.insert("transmission".into(), json!(file_name(outputs.transmission)));
    names.insert("transmission_color".into(), json!(file_name(outputs.transmission_color)));
    if let Some(c) = outputs.confidence {
        names.insert("confidence".into(), json!(file_name(c)));
    }
    if let Some(sheet) = outputs.contact_sheet {
        names.insert("contact_sheet".into(), json!(file_name(sheet)));
    }
    let mut secs = serde_json::Map::new();
    secs.insert("read".into(), json!(seconds.read));
    secs.insert("restore".into(), json!(seconds.restore));
    secs.insert("write".into(), json!(seconds.write));
    if let Some(sheet) = seconds.contact_sheet {
        secs.insert("contact_sheet".into(), json!(sheet));
    }
    secs.insert("total".into(), json!(seconds.total));
    let mut side = json!({
        "input": input,
        "outputs": names,
        "uwhl_version": env!("CARGO_PKG_VERSION"),
        "implementation": implementation,
        "source": {
            "path": input,
            "kind": source.kind,
            "format": source.format,
            "bits": source.bits,
            "height": source.height,
            "width": source.width,
            "orientation": source.orientation,
            "linear": source.linear,
            "preprocess": source.preprocess.name(),
            "camera_matrix": source.camera_matrix,
            "white_balance": source.white_balance,
            "notes": notes(source),
            "icc_profile": icc_json(source),
            "processed_height": source.processed_height,
            "processed_width": source.processed_width,
        },
        "water_type": est.water_type.name,
        "scores": scores,
        "excluded": est.excluded,
        "veiling_light": a,
        "vl_pixels": est.vl_pixels,
        "vl_fraction": est.vl_pixels as f64 / est.pixels.max(1) as f64,
        "flags": est.flags,
        "veil_excess": est.veil_excess,
        "fallback_share": est.fallback_share,
        "guided_radius": est.guided_radius,
        "guided_subsample": est.guided_subsample,
        "beta_ratios": [est.water_type.beta_br, est.water_type.beta_bg],
        "parameters": parameters,
        "seconds": secs,
    });
    if let (Some(d), Some(obj)) = (&est.distance, side.as_object_mut()) {
        obj.insert("distance".into(), d.clone());
    }
    side
}

#[cfg(test)]
mod tests {
    /// The Python command's distance record goes through a JSON parse on its
    /// way to the sidecar: the parse must give back the number the writer
    /// wrote (serde_json's `float_roundtrip`), checked against the compiler's
    /// own parse of 17-digit numbers that a faster parse gets wrong in the
    /// last bit (a fit's value from the hostile pass among them).
    #[test]
    fn a_float_written_to_json_is_read_back_exactly() {
        for x in [0.462_046_712_636_947_63_f64, 0.1 + 0.2, 2.225_073_858_507_201_4e-308, 0.987_654_321_098_765_4] {
            let text = serde_json::to_string(&x).unwrap();
            assert_eq!(serde_json::from_str::<f64>(&text).unwrap().to_bits(), x.to_bits(), "{text}");
        }
    }

    #[test]
    fn a_skipped_input_names_the_options_it_was_restored_with_otherwise() {
        use super::{changed_options, changed_said};
        let d = std::env::temp_dir().join(format!("uwhl-changed-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let side = d.join("a.json");
        std::fs::write(
            &side,
            r#"{"input": "a.png", "water_type": "II", "parameters": {"method": "revised", "threads": 2,
                "water_types": null, "guided_eps": 0.001, "gone": 1}}"#,
        )
        .unwrap();
        let now = serde_json::json!({"method": "revised", "threads": 1, "water_types": ["3C"], "guided_eps": 0.001,
                                     "max_memory": "auto"});
        // threads and max_memory do not change a result; a key only one side has does
        let changed = changed_options(&side, &now);
        assert_eq!(changed, ["gone", "water_types"]);
        assert_eq!(changed_said(&changed), "; restored with another gone, --water-type: --overwrite redoes it");
        assert_eq!(changed_said(&[]), "");
        // the same options, or a sidecar that cannot be read: nothing to say
        let same = serde_json::json!({"method": "revised", "threads": 8, "water_types": null, "guided_eps": 0.001,
                                      "gone": 1});
        assert!(changed_options(&side, &same).is_empty());
        assert!(changed_options(&d.join("missing.json"), &now).is_empty());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
