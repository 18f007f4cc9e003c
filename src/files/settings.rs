//! What one input's processing is asked to do, the same for both commands:
//! the method's [`Params`] and the file options (format, bits, quality,
//! preprocessing, `--max-side`, masks, reuse of estimates), each set from a
//! row of the option table (`crate::files::options`) by [`Settings::set`].

use crate::error::{Failure, Kind};
use crate::files::options::Value as Val;
use crate::method::params::Params;
use crate::method::water::{jerlov_types, WaterType};
use std::path::{Path, PathBuf};

/// The encoded format of the restored image (`--format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `NAME.jpg`, 8-bit, quality 95
    Jpg,
    /// `NAME.png`, 8 or 16 bits (`--bits`)
    Png,
    /// `NAME.tif`, 16-bit RGB
    Tiff,
}

impl Format {
    /// Every format, in the order of `--format`'s values.
    pub const ALL: [Format; 3] = [Format::Jpg, Format::Png, Format::Tiff];

    /// The name used on the command line and in the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Format::Jpg => "jpg",
            Format::Png => "png",
            Format::Tiff => "tiff",
        }
    }

    /// The format called `name` on the command line (`jpg`, `png`, `tiff`).
    pub fn from_name(name: &str) -> Option<Format> {
        [Format::Jpg, Format::Png, Format::Tiff].into_iter().find(|f| f.name() == name)
    }

    /// The file extension of the restored image.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Jpg => "jpg",
            Format::Png => "png",
            Format::Tiff => "tif",
        }
    }
}

/// What follows `NAME` in the names of an input's outputs, in writing
/// order: the photo, t_B as 16-bit PNG, t_B colour-mapped, the confidence
/// map (written when the method makes one, METHOD §12.5; the name is
/// claimed in any case so that a rerun without it removes an old one), and
/// the contact sheet when asked for (the Python command's `--contact-sheet`). The
/// sidecar's `.json` comes last, added by `crate::files::commit`
/// (docs/OUTPUTS.md).
pub fn output_suffixes(format: Format, contact: bool) -> Vec<String> {
    let mut s = vec![format!(".{}", format.extension()), "_t.png".into(), "_t_color.png".into(), "_confidence.png".into()];
    if contact {
        s.push("_sheet.png".into());
    }
    s
}

/// Input preprocessing (`--preprocess`, METHOD §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preprocess {
    /// decode sRGB to linear (the default; physically right)
    None,
    /// METHOD §2 reference: keep sRGB values as they are, mild pulled stretch
    Reference,
}

impl Preprocess {
    /// The name used on the command line and in the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Preprocess::None => "none",
            Preprocess::Reference => "reference",
        }
    }
}

/// One `--water-type` entry: a Jerlov name or a custom `NAME:BETA_BR:BETA_BG`.
#[derive(Debug, Clone, PartialEq)]
pub struct WaterChoice {
    /// the type
    pub water_type: WaterType,
    /// given as `NAME:BETA_BR:BETA_BG` (echoed as `[name, br, bg]` in the sidecar)
    pub custom: bool,
}

/// The options of one input's processing, checked: the method's
/// parameters and what the files layer does around `restore`.
#[derive(Debug, Clone)]
pub struct Settings {
    /// the method's parameters (every row with `method: true` but
    /// `water_types`, set through `Params::set`)
    pub params: Params,
    /// `--water-type` entries in order (None = all ten), as given
    pub water_types: Option<Vec<WaterChoice>>,
    /// `--veiling-light R,G,B` as given (the sidecar echoes it)
    pub veiling_light: Option<[f64; 3]>,
    /// `--mask PATH`
    pub mask: Option<PathBuf>,
    /// `--water-mask PATH`: a given water region (nonzero = water)
    pub water_mask: Option<PathBuf>,
    /// `--distance TEMPLATE`: each input's distance map (METHOD §13;
    /// `crate::files::depth::expand`)
    pub distance: Option<String>,
    /// `--altitude SOURCE`: distance from the altitude over a flat seabed
    /// (METHOD §13.7; `crate::files::nav`)
    pub altitude: Option<crate::files::nav::AltitudeSource>,
    /// `--distance-kind depth`: the maps of `--distance` hold depth along
    /// the camera's axis, turned into ranges (METHOD §13.7)
    pub depth_along_axis: bool,
    /// `--fov DEG`: the lens's horizontal field of view in air
    pub fov: Option<f64>,
    /// `--port`: the housing's window
    pub port: crate::method::floor::Port,
    /// `--water-from DIR`: the water fitted on a folder's calibrated photos
    pub water_from: Option<crate::files::dive::DiveWater>,
    /// `--max-side`
    pub max_side: Option<usize>,
    /// `--preprocess`
    pub preprocess: Preprocess,
    /// `--linear`: the input is already linear (no sRGB decoding)
    pub linear: bool,
    /// `--half-size`: raw files demosaiced at half size (the Python command)
    pub half_size: bool,
    /// `--format`
    pub format: Format,
    /// `--bits` as given (None: the format's default, see [`Settings::bits`])
    pub bits: Option<u8>,
    /// `--quality` of JPEG outputs, 1..=100
    pub quality: u8,
    /// `--overwrite`: process inputs whose sidecar exists
    pub overwrite: bool,
    /// `--max-pixels`
    pub max_pixels: u64,
    /// `--reuse-estimates N`: re-estimate every N inputs
    pub reuse_estimates: Option<usize>,
    /// `--reuse-water-mask` (with `--reuse-estimates`): reuse the water region too
    pub reuse_water_mask: bool,
    /// `--max-memory` was given (else the budget follows the machine: "auto")
    pub max_memory_given: bool,
    /// `--scene-cut X`: a sequence's cut and drift threshold (METHOD §10)
    pub scene_cut: Option<f32>,
    /// `--smoothing W`: a sequence's weight of a scheduled estimate of A
    pub smoothing: Option<f32>,
    /// `--transfer`: the transfer curve of video and raw-frame samples
    pub transfer: Option<crate::files::transfer::Transfer>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            params: Params::default(),
            water_types: None,
            veiling_light: None,
            mask: None,
            water_mask: None,
            distance: None,
            altitude: None,
            fov: None,
            depth_along_axis: false,
            port: crate::method::floor::Port::Flat,
            water_from: None,
            max_side: None,
            preprocess: Preprocess::None,
            linear: false,
            half_size: false,
            format: Format::Jpg,
            bits: None,
            quality: crate::files::options::DEFAULT_QUALITY as u8,
            overwrite: false,
            max_pixels: crate::files::options::DEFAULT_MAX_PIXELS,
            reuse_estimates: None,
            reuse_water_mask: false,
            max_memory_given: false,
            scene_cut: None,
            smoothing: None,
            transfer: None,
        }
    }
}

impl Settings {
    /// Bits per sample of the restored image: `--bits`, else 8 for JPEG and
    /// PNG, 16 for TIFF.
    pub fn bits(&self) -> u8 {
        self.bits.unwrap_or(match self.format {
            Format::Tiff => 16,
            Format::Jpg | Format::Png => 8,
        })
    }

    /// The parameters `restore` is called with: the candidate types of
    /// `--water-type`, and no pool of its own (a command sizes rayon's
    /// global pool once, `cli::init_threads`).
    pub fn method_params(&self) -> Params {
        Params {
            water_types: match (&self.water_from, &self.water_types) {
                (Some(d), _) => vec![d.water_type.clone()],
                (None, None) => jerlov_types(),
                (None, Some(list)) => list.iter().map(|c| c.water_type.clone()).collect(),
            },
            threads: None,
            ..self.params.clone()
        }
    }

    /// Sets the option `key` of the table to its parsed value: the one
    /// place where a row of `crate::files::options::OPTIONS` meets these
    /// settings; a method key goes to [`Params::set`]. Returns false for a
    /// key that is not one of them (a command's own option).
    pub fn set(&mut self, key: &str, v: Val) -> Result<bool, Failure> {
        let int = |v: &Val| match v {
            Val::Int(n) => Ok(*n),
            other => Err(Failure::new(Kind::Internal, format!("{key}: {other:?} is not an integer"))),
        };
        let usize_of = |v: &Val| int(v).map(|n| usize::try_from(n).unwrap_or(usize::MAX));
        let text = |v: Val| match v {
            Val::Text(t) => Ok(t),
            other => Err(Failure::new(Kind::Internal, format!("{key}: {other:?} is not text"))),
        };
        match key {
            // the table's choices are the formats' names
            "format" => self.format = Format::from_name(&text(v)?).unwrap_or(Format::Jpg),
            "bits" => self.bits = Some(int(&v)?.min(16) as u8),
            "quality" => self.quality = int(&v)?.min(100) as u8,
            "overwrite" => self.overwrite = true,
            "preprocess" => {
                self.preprocess = if text(v)? == "reference" { Preprocess::Reference } else { Preprocess::None }
            }
            "linear" => self.linear = true,
            "half_size" => self.half_size = true,
            "max_side" => self.max_side = Some(usize_of(&v)?),
            "max_pixels" => self.max_pixels = int(&v)?,
            "mask" => self.mask = Some(text(v)?.into()),
            "water_mask" => self.water_mask = Some(text(v)?.into()),
            "distance" => self.distance = Some(text(v)?),
            "altitude" => self.altitude = Some(crate::files::nav::altitude_source(&text(v)?)?),
            "distance_kind" => self.depth_along_axis = text(v)? == "depth",
            "fov" => {
                self.fov = Some(match v {
                    Val::Float(f) => f,
                    other => return Err(Failure::new(Kind::Internal, format!("{key}: {other:?} is not a number"))),
                })
            }
            "port" => self.port = crate::method::floor::Port::parse(&text(v)?).unwrap_or(crate::method::floor::Port::Flat),
            "water_from" => self.water_from = Some(crate::files::dive::water_from(Path::new(&text(v)?))?),
            "water_types" => water_types(self.water_types.get_or_insert_with(Vec::new), &text(v)?)?,
            "reuse_estimates" => self.reuse_estimates = Some(usize_of(&v)?),
            "reuse_water_mask" => self.reuse_water_mask = true,
            "scene_cut" | "smoothing" => {
                let x = match v {
                    Val::Float(f) => f as f32,
                    other => return Err(Failure::new(Kind::Internal, format!("{key}: {other:?} is not a number"))),
                };
                *(if key == "scene_cut" { &mut self.scene_cut } else { &mut self.smoothing }) = Some(x);
            }
            "transfer" => {
                let name = text(v)?;
                self.transfer = Some(crate::files::transfer::Transfer::parse(&name).ok_or_else(|| {
                    Failure::new(Kind::Internal, format!("{key}: {name:?} is not a transfer curve"))
                })?);
            }
            "max_memory" => {
                self.params.set(key, &v).map_err(Failure::from)?;
                self.max_memory_given = true;
            }
            "veiling_light" => {
                self.params.set(key, &v).map_err(Failure::from)?;
                if let Val::Rgb(rgb) = v {
                    self.veiling_light = Some(rgb);
                }
            }
            _ if crate::files::options::spec(key).is_some_and(|s| s.method) => {
                self.params.set(key, &v).map_err(Failure::from)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}

/// One `--water-type` item: a Jerlov name, or `NAME:BETA_BR:BETA_BG`.
fn water_choice(item: &str) -> Result<WaterChoice, Failure> {
    let bad = |e: crate::Error| Failure::usage(format!("--water-type {item:?}: {e}"));
    if item.contains(':') {
        let parts: Vec<&str> = item.split(':').map(str::trim).collect();
        let ratios = match parts.as_slice() {
            [name, br, bg] => br.parse::<f64>().ok().zip(bg.parse::<f64>().ok()).map(|r| (*name, r)),
            _ => None,
        };
        let (name, (br, bg)) = ratios.ok_or_else(|| {
            Failure::usage(format!(
                "--water-type {item:?}: a custom type is NAME:BETA_BR:BETA_BG"
            ))
        })?;
        return Ok(WaterChoice {
            water_type: WaterType::new(name, br, bg).map_err(bad)?,
            custom: true,
        });
    }
    Ok(WaterChoice {
        water_type: WaterType::by_name(item).map_err(bad)?,
        custom: false,
    })
}

/// One `--water-type` value: its comma-separated items appended to `list`.
pub(crate) fn water_types(list: &mut Vec<WaterChoice>, v: &str) -> Result<(), Failure> {
    for item in v.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let choice = water_choice(item)?;
        if list.iter().any(|c| c.water_type.name == choice.water_type.name) {
            return Err(Failure::usage(format!(
                "--water-type: {:?} is listed twice",
                choice.water_type.name
            )));
        }
        list.push(choice);
    }
    if list.is_empty() {
        return Err(Failure::usage("--water-type: no type named"));
    }
    Ok(())
}


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_names_follow_the_format_and_the_sheet() {
        assert_eq!(output_suffixes(Format::Tiff, false), [".tif", "_t.png", "_t_color.png", "_confidence.png"]);
        assert_eq!(
            output_suffixes(Format::Jpg, true),
            [".jpg", "_t.png", "_t_color.png", "_confidence.png", "_sheet.png"]
        );
        assert_eq!(Format::from_name("png"), Some(Format::Png));
        assert_eq!(Format::from_name("tif"), None);
    }

    #[test]
    fn method_keys_land_in_params_and_file_keys_in_the_settings() {
        let mut s = Settings::default();
        assert!(s.set("guided_eps", Val::Float(0.01)).unwrap());
        assert!(s.set("veiling_light", Val::Rgb([0.1, 0.2, 0.3])).unwrap());
        assert!(s.set("quality", Val::Int(80)).unwrap());
        assert!(!s.set("quiet", Val::On).unwrap());
        assert_eq!(s.params.guided_eps, 0.01);
        assert_eq!(s.params.veiling_light, Some([0.1f32, 0.2, 0.3]));
        assert_eq!(s.veiling_light, Some([0.1, 0.2, 0.3]));
        assert_eq!(s.quality, 80);
        // a value of the wrong kind for a method key is the core's parameter error
        assert_eq!(s.set("t_scale", Val::Text("x".into())).unwrap_err().kind, Kind::Usage);
    }
}
