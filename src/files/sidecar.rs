//! The JSON sidecar `NAME.json` of docs/OUTPUTS.md (`implementation: "rust"`).
//! Single-precision results (A) are written as the f64 of the same value,
//! as Python's `float(np.float32(x))` does, so both commands write equal numbers.

use crate::files::settings::{Preprocess, Settings};
use crate::method::params::Restoration;
use serde_json::{json, Value};
use std::path::Path;

/// Where the input came from (the `source` object).
#[derive(Debug, Clone)]
pub struct Source {
    /// "srgb" or "linear"
    pub kind: &'static str,
    /// "PNG", "JPEG", "TIFF"
    pub format: &'static str,
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
}

/// Paths of the three image outputs (the sidecar names them by file name,
/// relative to itself).
#[derive(Debug, Clone)]
pub struct OutputPaths<'a> {
    /// `NAME.jpg|png|tif`
    pub image: &'a Path,
    /// `NAME_t.png`
    pub transmission: &'a Path,
    /// `NAME_t_color.png`
    pub transmission_color: &'a Path,
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
    /// everything
    pub total: f64,
}

fn path(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// The options, in the `parameters` object (keys as the Python command's;
/// `half_size` is always false here: it concerns raw files).
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
    let steps = o.method_params().steps();
    let step = |k: &str| steps.iter().find(|s| s.0 == k).map(|s| s.1);
    json!({
        "method": step("method"),
        "white_balance": step("white_balance"),
        "type_choice": step("type_choice"),
        "haze_floor": step("haze_floor"),
        "water_types": types,
        "veiling_light": o.veiling_light,
        "mask": o.mask.as_deref().map(path),
        "water_mask": o.water_mask.as_deref().map(path),
        "guided_radius": o.params.guided_radius,
        "guided_eps": o.params.guided_eps,
        "t_scale": o.params.t_scale,
        "guided_subsample": o.params.guided_subsample,
        "sphere_points": o.params.sphere_points,
        "threads": o.params.threads,
        "max_side": o.max_side,
        "max_pixels": o.max_pixels,
        "preprocess": o.preprocess.name(),
        "selection": step("selection"),
        "half_size": false,
        "format": o.format.name(),
        "bits": o.bits(),
        "quality": o.quality,
        "max_memory": o.params.max_memory,
        "linear": o.linear,
    })
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

fn icc_notes(source: &Source) -> Vec<String> {
    match &source.icc_profile {
        Some((_, _, Some(why))) => vec![format!("the ICC profile cannot be read ({why}); read as sRGB")],
        _ => vec![],
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The whole sidecar object.
pub fn sidecar(
    input: &Path,
    outputs: &OutputPaths,
    source: &Source,
    res: &Restoration,
    opts: &Settings,
    seconds: Seconds,
) -> Value {
    let vl_pixels = res.veiling_mask.iter().filter(|&&b| b).count();
    let n = res.height.saturating_mul(res.width).max(1);
    let scores: serde_json::Map<String, Value> = res
        .scores
        .iter()
        .map(|(name, s)| (name.clone(), json!(s)))
        .collect();
    let a: Vec<f64> = res.veiling_light.iter().map(|&v| f64::from(v)).collect();
    json!({
        "input": path(input),
        "outputs": {
            "image": file_name(outputs.image),
            "transmission": file_name(outputs.transmission),
            "transmission_color": file_name(outputs.transmission_color),
        },
        "uwhl_version": env!("CARGO_PKG_VERSION"),
        "implementation": "rust",
        "source": {
            "path": path(input),
            "kind": source.kind,
            "format": source.format,
            "bits": source.bits,
            "height": source.height,
            "width": source.width,
            "orientation": source.orientation,
            "linear": source.linear,
            "preprocess": source.preprocess.name(),
            "camera_matrix": null,
            "white_balance": null,
            "notes": icc_notes(source),
            "icc_profile": icc_json(source),
            "processed_height": source.processed_height,
            "processed_width": source.processed_width,
        },
        "water_type": res.water_type.name,
        "scores": scores,
        "excluded": res.excluded,
        "veiling_light": a,
        "vl_pixels": vl_pixels,
        "vl_fraction": vl_pixels as f64 / n as f64,
        "flags": res.flags.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "guided_radius": res.guided_radius,
        "guided_subsample": res.guided_subsample,
        "beta_ratios": [res.water_type.beta_br, res.water_type.beta_bg],
        "parameters": parameters(opts),
        "seconds": {
            "read": seconds.read,
            "restore": seconds.restore,
            "write": seconds.write,
            "total": seconds.total,
        },
    })
}
