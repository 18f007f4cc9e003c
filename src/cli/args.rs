//! Command-line options of `uwhl-rs` and their parser. The options mirror
//! the Python command `uwhl restore` (docs/OUTPUTS.md); the values are
//! checked here so that a bad option is a usage error before any input is read.

use super::{CliError, Kind};
use crate::options::{exit_code_text, help_text, Faces, Kind as OptKind, Value as Val, OPTIONS};
use crate::params::Selection;
use crate::water::WaterType;
use std::ffi::OsString;
use std::path::PathBuf;

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
    /// The name used on the command line and in the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Format::Jpg => "jpg",
            Format::Png => "png",
            Format::Tiff => "tiff",
        }
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

/// Every option of the command, checked.
#[derive(Debug, Clone)]
pub struct Options {
    /// input files and folders (batch mode)
    pub inputs: Vec<PathBuf>,
    /// `-o DIR`
    pub outdir: PathBuf,
    /// `--water-type` entries in order (None = all ten)
    pub water_types: Option<Vec<WaterChoice>>,
    /// `--veiling-light R,G,B`
    pub veiling_light: Option<[f64; 3]>,
    /// `--mask PATH`
    pub mask: Option<PathBuf>,
    /// `--water-mask PATH`: a given water region (nonzero = water)
    pub water_mask: Option<PathBuf>,
    /// `--guided-radius`
    pub guided_radius: Option<usize>,
    /// `--guided-eps`
    pub guided_eps: f64,
    /// `--guided-subsample S|auto`: 1 exact filter, S >= 2 fast guided
    /// filter, 0 (`auto`) max(1, radius / 32)
    pub guided_subsample: usize,
    /// `--sphere-points`
    pub sphere_points: usize,
    /// `--max-side`
    pub max_side: Option<usize>,
    /// `--preprocess`
    pub preprocess: Preprocess,
    /// `--selection`: how the water type is chosen
    pub selection: Option<crate::params::Selection>,
    /// `--t-scale` (METHOD §4.6)
    pub t_scale: f64,
    /// `--method`: the profile (METHOD §12)
    pub method: crate::profile::Method,
    /// `--white-balance` (None: the profile's)
    pub white_balance: Option<crate::profile::WhiteBalance>,
    /// `--type-choice` (None: the profile's)
    pub type_choice: Option<crate::profile::TypeChoice>,
    /// `--haze-floor` (None: the profile's)
    pub haze_floor: Option<Option<&'static str>>,
    /// `--linear`: the input is already linear (no sRGB decoding)
    pub linear: bool,
    /// `--format`
    pub format: Format,
    /// `--bits` as given (None: the format's default, see [`Options::bits`])
    pub bits: Option<u8>,
    /// `--quality` of JPEG outputs, 1..=100
    pub quality: u8,
    /// `--overwrite`: process inputs whose sidecar exists
    pub overwrite: bool,
    /// `--threads` (None = all cores)
    pub threads: Option<usize>,
    /// `--max-memory` in bytes
    pub max_memory: u64,
    /// `--max-pixels`
    pub max_pixels: u64,
    /// `--json-errors`
    pub json_errors: bool,
    /// `--stream`: paths on stdin, one JSON line per frame on stdout
    pub stream: bool,
    /// `--reuse-estimates N` (stream mode): re-estimate every N frames
    pub reuse_estimates: Option<usize>,
    /// `--reuse-water-mask` (with `--reuse-estimates`): reuse the water region too
    pub reuse_water_mask: bool,
    /// `-q`: no progress lines on stdout (batch mode)
    pub quiet: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            inputs: Vec::new(),
            outdir: PathBuf::new(),
            water_types: None,
            veiling_light: None,
            mask: None,
            water_mask: None,
            guided_radius: None,
            guided_eps: crate::options::DEFAULT_EPS,
            guided_subsample: 1,
            sphere_points: crate::options::DEFAULT_SPHERE_POINTS,
            max_side: None,
            preprocess: Preprocess::None,
            selection: None,
            t_scale: crate::options::DEFAULT_T_SCALE,
            method: crate::profile::Method::default(),
            white_balance: None,
            type_choice: None,
            haze_floor: None,
            linear: false,
            format: Format::Jpg,
            bits: None,
            quality: crate::options::DEFAULT_QUALITY as u8,
            overwrite: false,
            threads: None,
            max_memory: crate::budget::default_max_memory(),
            max_pixels: crate::options::DEFAULT_MAX_PIXELS,
            json_errors: false,
            stream: false,
            reuse_estimates: None,
            reuse_water_mask: false,
            quiet: false,
        }
    }
}

impl Options {
    /// Bits per sample of the restored image: `--bits`, else 8 for JPEG and
    /// PNG, 16 for TIFF.
    pub fn bits(&self) -> u8 {
        self.bits.unwrap_or(match self.format {
            Format::Tiff => 16,
            Format::Jpg | Format::Png => 8,
        })
    }
}

/// What the command line asks for.
#[derive(Debug, Clone)]
pub enum Command {
    /// restore (batch or stream)
    Run(Box<Options>),
    /// `demo`: the built-in rendered scene
    Demo(Demo),
    /// `--help`
    Help,
    /// `--version`
    Version,
}

/// The `--help` text: usage, the options of the table (`crate::options`)
/// that this command takes, and the exit codes.
pub fn help() -> String {
    format!(
        "uwhl-rs: underwater colour restoration with haze-lines (Berman et al., TPAMI 2020)

usage:
  uwhl-rs restore [OPTIONS] INPUT... -o OUTDIR   restore files and folders (PNG, JPEG, TIFF)
  uwhl-rs restore --stream [OPTIONS] -o OUTDIR   read image paths from stdin, one per line
  uwhl-rs [OPTIONS] INPUT... -o OUTDIR           the same as 'uwhl-rs restore'
  uwhl-rs demo [-o DIR] [--water-type T] [--size HxW] [--seed N]
                                                 restore the built-in rendered scene

For INPUT NAME.EXT writes OUTDIR/NAME.jpg (or .png/.tif), NAME_t.png (16-bit t_B),
NAME_t_color.png (colour-mapped t_B) and NAME.json (sidecar, written last).
Inputs are sRGB (decoded to linear) unless --linear. The options, outputs and exit
codes are those of the Python command 'uwhl restore' (docs/CLI.md).

  -o, --out DIR              output folder (created if missing; --output is the same)
{}  -h, --help                 this text
  -V, --version              the version

{}In stream mode the exit code is 0 at the end of stdin unless the arguments were bad (2)
or the run was interrupted (130).
",
        help_text(Faces::Rust, 100),
        exit_code_text()
    )
}

/// The options of `demo` (as `uwhl demo`'s).
#[derive(Debug, Clone, PartialEq)]
pub struct Demo {
    /// `-o DIR` (default `uwhl_demo`)
    pub out: PathBuf,
    /// `--water-type`: the Jerlov type to render (default III)
    pub water_type: WaterType,
    /// `--size HxW` (default 480x640)
    pub size: (usize, usize),
    /// `--seed` (default 7)
    pub seed: u64,
}

/// Parses `demo`'s options (after the subcommand).
fn parse_demo(p: &mut lexopt::Parser) -> Result<Command, CliError> {
    use lexopt::prelude::*;
    let lex = |e: lexopt::Error| CliError::usage(e.to_string());
    let text = |v: OsString, flag: &str| v.into_string().map_err(|v| CliError::usage(format!("{flag}: {v:?} is not valid UTF-8")));
    let mut d = Demo {
        out: PathBuf::from("uwhl_demo"),
        water_type: WaterType::by_name("III").map_err(|e| CliError::new(Kind::Internal, e.to_string()))?,
        size: (480, 640),
        seed: 7,
    };
    while let Some(arg) = p.next().map_err(lex)? {
        match arg {
            Short('h') | Long("help") => return Ok(Command::Help),
            Short('o') | Long("out") | Long("output") => d.out = p.value().map_err(lex)?.into(),
            Long("water-type") => {
                let v = text(p.value().map_err(lex)?, "--water-type")?;
                d.water_type = WaterType::by_name(v.trim()).map_err(|e| CliError::usage(format!("--water-type: {e}")))?;
            }
            Long("size") => {
                let v = text(p.value().map_err(lex)?, "--size")?;
                let hw: Vec<usize> = v.to_ascii_lowercase().split('x').filter_map(|t| t.trim().parse().ok()).collect();
                d.size = match hw.as_slice() {
                    [h, w] if *h >= 4 && *w >= 4 && h.saturating_mul(*w) <= 50_000_000 => (*h, *w),
                    _ => return Err(CliError::usage(format!("--size: {v:?} is not HxW with sides >= 4 (e.g. 480x640)"))),
                };
            }
            Long("seed") => {
                let v = text(p.value().map_err(lex)?, "--seed")?;
                d.seed = v.trim().parse().map_err(|_| CliError::usage(format!("--seed: {v:?} is not an integer >= 0")))?;
            }
            _ => return Err(CliError::usage(arg.unexpected().to_string())),
        }
    }
    Ok(Command::Demo(d))
}

/// One `--water-type` item: a Jerlov name, or `NAME:BETA_BR:BETA_BG`.
fn water_choice(item: &str) -> Result<WaterChoice, CliError> {
    let bad = |e: crate::Error| CliError::usage(format!("--water-type {item:?}: {e}"));
    if item.contains(':') {
        let parts: Vec<&str> = item.split(':').map(str::trim).collect();
        let ratios = match parts.as_slice() {
            [name, br, bg] => br.parse::<f64>().ok().zip(bg.parse::<f64>().ok()).map(|r| (*name, r)),
            _ => None,
        };
        let (name, (br, bg)) = ratios.ok_or_else(|| {
            CliError::usage(format!(
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
fn water_types(list: &mut Vec<WaterChoice>, v: &str) -> Result<(), CliError> {
    for item in v.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let choice = water_choice(item)?;
        if list.iter().any(|c| c.water_type.name == choice.water_type.name) {
            return Err(CliError::usage(format!(
                "--water-type: {:?} is listed twice",
                choice.water_type.name
            )));
        }
        list.push(choice);
    }
    if list.is_empty() {
        return Err(CliError::usage("--water-type: no type named"));
    }
    Ok(())
}

impl Options {
    /// Sets the option `key` of the table to its parsed value: the one
    /// place where a row of `crate::options::OPTIONS` meets this struct.
    fn set(&mut self, key: &str, v: Val) -> Result<(), CliError> {
        let int = |v: &Val| match v {
            Val::Int(n) => Ok(*n),
            other => Err(CliError::new(Kind::Internal, format!("{key}: {other:?} is not an integer"))),
        };
        let usize_of = |v: &Val| int(v).map(|n| usize::try_from(n).unwrap_or(usize::MAX));
        let text = |v: Val| match v {
            Val::Text(t) => Ok(t),
            other => Err(CliError::new(Kind::Internal, format!("{key}: {other:?} is not text"))),
        };
        match key {
            "format" => {
                self.format = match text(v)?.as_str() {
                    "png" => Format::Png,
                    "tiff" => Format::Tiff,
                    _ => Format::Jpg,
                }
            }
            "bits" => self.bits = Some(int(&v)?.min(16) as u8),
            "quality" => self.quality = int(&v)?.min(100) as u8,
            "overwrite" => self.overwrite = true,
            "preprocess" => {
                self.preprocess = if text(v)? == "reference" { Preprocess::Reference } else { Preprocess::None }
            }
            "linear" => self.linear = true,
            "max_side" => self.max_side = Some(usize_of(&v)?),
            "max_pixels" => self.max_pixels = int(&v)?,
            "mask" => self.mask = Some(text(v)?.into()),
            "water_mask" => self.water_mask = Some(text(v)?.into()),
            "water_types" => water_types(self.water_types.get_or_insert_with(Vec::new), &text(v)?)?,
            "veiling_light" => {
                if let Val::Rgb(rgb) = v {
                    self.veiling_light = Some(rgb);
                }
            }
            "selection" => {
                self.selection = Some(Selection::from_name(&text(v)?).map_err(CliError::from)?)
            }
            "method" => self.method = crate::profile::Method::from_name(&text(v)?).map_err(CliError::from)?,
            "white_balance" => {
                self.white_balance = Some(crate::profile::WhiteBalance::from_name(&text(v)?).map_err(CliError::from)?)
            }
            "haze_floor" => {
                self.haze_floor = Some(crate::params::haze_floor_from_name(&text(v)?).map_err(CliError::from)?)
            }
            "type_choice" => {
                self.type_choice = Some(crate::profile::TypeChoice::from_name(&text(v)?).map_err(CliError::from)?)
            }
            "guided_radius" => self.guided_radius = Some(usize_of(&v)?),
            "guided_eps" => {
                if let Val::Float(x) = v {
                    self.guided_eps = x;
                }
            }
            "t_scale" => {
                if let Val::Float(x) = v {
                    self.t_scale = x;
                }
            }
            "guided_subsample" => self.guided_subsample = usize_of(&v)?,
            "sphere_points" => self.sphere_points = usize_of(&v)?,
            "reuse_estimates" => self.reuse_estimates = Some(usize_of(&v)?),
            "reuse_water_mask" => self.reuse_water_mask = true,
            "threads" => self.threads = Some(usize_of(&v)?),
            "max_memory" => self.max_memory = int(&v)?,
            "stream" => self.stream = true,
            "json_errors" => self.json_errors = true,
            "quiet" => self.quiet = true,
            other => return Err(CliError::new(Kind::Internal, format!("option {other} has no field"))),
        }
        Ok(())
    }
}

/// Parses the command line (without the program name): `restore` and its
/// options, or the same options without the subcommand.
pub fn parse<I>(args: I) -> Result<Command, CliError>
where
    I: IntoIterator,
    I::Item: Into<OsString>,
{
    use lexopt::prelude::*;
    let mut o = Options::default();
    let mut outdir: Option<PathBuf> = None;
    let mut p = lexopt::Parser::from_args(args);
    let lex = |e: lexopt::Error| CliError::usage(e.to_string());
    let mut first = true;
    while let Some(arg) = p.next().map_err(lex)? {
        let is_first = std::mem::replace(&mut first, false);
        let spec = match &arg {
            Short('h') | Long("help") => return Ok(Command::Help),
            Short('V') | Long("version") => return Ok(Command::Version),
            Short('o') | Long("out") | Long("output") => {
                outdir = Some(p.value().map_err(lex)?.into());
                continue;
            }
            Value(v) if is_first && v == "restore" => continue,
            Value(v) if is_first && v == "demo" => return parse_demo(&mut p),
            Value(v) if is_first && (v == "evaluate" || v == "report" || v == "ifdo") => {
                return Err(CliError::usage(format!(
                    "'{}' is a subcommand of the Python command only: run 'uwhl {}' (docs/CLI.md)",
                    v.to_string_lossy(),
                    v.to_string_lossy()
                )))
            }
            Value(v) => {
                o.inputs.push(v.into());
                continue;
            }
            Long(name) => OPTIONS.iter().find(|s| s.flag.strip_prefix("--") == Some(*name)),
            Short(c) => OPTIONS.iter().find(|s| s.short == Some(*c)),
        };
        let spec = match spec {
            Some(s) if s.faces != Faces::Python => s,
            Some(s) => {
                return Err(CliError::usage(format!(
                    "{} is an option of the Python command only: run 'uwhl restore' (docs/CLI.md)",
                    s.flag
                )))
            }
            None => return Err(CliError::usage(arg.unexpected().to_string())),
        };
        let value = if spec.kind == OptKind::Flag {
            Val::On
        } else {
            let raw = p.value().map_err(lex)?;
            let t = raw
                .into_string()
                .map_err(|v| CliError::usage(format!("{}: {v:?} is not valid UTF-8", spec.flag)))?;
            spec.parse(&t).map_err(CliError::usage)?
        };
        o.set(spec.key, value)?;
    }
    o.outdir = outdir.ok_or_else(|| CliError::usage("-o OUTDIR is required"))?;
    if o.stream && !o.inputs.is_empty() {
        return Err(CliError::usage(
            "--stream reads the input paths from stdin; give no INPUT arguments",
        ));
    }
    if !o.stream && o.inputs.is_empty() {
        return Err(CliError::usage("no INPUT given (or use --stream)"));
    }
    crate::options::check_combination(
        o.format.name(),
        o.bits.map(u64::from),
        o.reuse_estimates.map(|n| n as u64),
        o.reuse_water_mask,
        o.linear,
        o.preprocess.name(),
    )
    .map_err(CliError::usage)?;
    Ok(Command::Run(Box::new(o)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(args: &[&str]) -> Result<Options, CliError> {
        match parse(args.iter().copied())? {
            Command::Run(o) => Ok(*o),
            c => panic!("{c:?}"),
        }
    }

    #[test]
    fn parses_every_option() {
        let o = run(&[
            "a.png", "-o", "out", "--water-type", "II,III", "--water-type", "5C",
            "--veiling-light", "0.1 0.2,0.3", "--mask", "m.png", "--guided-radius", "7",
            "--water-type", "mine:0.5:1.1", "--water-mask", "w.png", "--quality", "90",
            "--guided-eps", "0.01", "--guided-subsample", "3", "--sphere-points", "100", "--max-side", "512",
            "--preprocess", "reference", "--format", "tiff", "--bits", "16", "--overwrite",
            "--threads", "2", "--max-memory", "512M", "--max-pixels", "1000", "--json-errors",
            "b.jpg",
        ])
        .unwrap();
        assert_eq!(o.inputs, vec![PathBuf::from("a.png"), PathBuf::from("b.jpg")]);
        let names: Vec<String> = o.water_types.iter().flatten().map(|c| c.water_type.name.clone()).collect();
        assert_eq!(names, vec!["II", "III", "5C", "mine"]);
        assert_eq!(o.water_types.as_ref().map(|v| v[3].custom), Some(true));
        assert_eq!((o.bits(), o.quality), (16, 90));
        assert_eq!(o.veiling_light, Some([0.1, 0.2, 0.3]));
        assert_eq!(o.guided_radius, Some(7));
        assert_eq!(o.guided_subsample, 3);
        assert_eq!(o.max_side, Some(512));
        assert_eq!(o.format, Format::Tiff);
        assert_eq!(o.max_memory, 512 << 20);
        assert_eq!(o.threads, Some(2));
        assert!(o.overwrite && o.json_errors && !o.stream);
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for args in [
            &["a.png"][..],
            &["-o", "out"],
            &["a", "-o", "o", "--water-type", "XI"],
            &["a", "-o", "o", "--water-type", "II,II"],
            &["a", "-o", "o", "--veiling-light", "0.1,0.2"],
            &["a", "-o", "o", "--veiling-light", "0,0.2,0.3"],
            &["a", "-o", "o", "--guided-eps", "-1"],
            &["a", "-o", "o", "--guided-subsample", "-1"],
            &["a", "-o", "o", "--guided-subsample", "fast"],
            &["a", "-o", "o", "--guided-subsample", "1.5"],
            &["a", "-o", "o", "--guided-subsample", ""],
            &["a", "-o", "o", "--guided-subsample", "AUTO"],
            &["a", "-o", "o", "--guided-subsample"],
            &["a", "-o", "o", "--bits", "12"],
            &["a", "-o", "o", "--threads", "0"],
            &["a", "-o", "o", "--max-memory", "lots"],
            &["a", "-o", "o", "--max-side", "3"],
            &["a", "-o", "o", "--bits", "16"],
            &["a", "-o", "o", "--quality", "101"],
            &["a", "-o", "o", "--water-type", "x:1"],
            &["a", "-o", "o", "--water-type", "x:0:1"],
            &["a", "-o", "o", "--format", "gif"],
            &["a", "-o", "o", "--frobnicate"],
            &["a", "-o", "o", "--quality", "0"],
            &["a", "-o", "o", "--jobs", "2"],
            &["evaluate", "-o", "o"],
            &["ifdo", "out", "--header", "h.yaml"],
            &["demo", "--size", "3x9"],
            &["demo", "--water-type", "XI"],
            &["demo", "--frobnicate"],
            &["-o", "o", "--stream", "--reuse-water-mask"],
            &["a", "-o", "o", "--stream"],
            &["a", "-o", "o", "--linear", "--preprocess", "reference"],
        ] {
            let e = run(args).unwrap_err();
            assert_eq!(e.kind, super::super::Kind::Usage, "{args:?}");
        }
    }

    #[test]
    fn guided_subsample_values() {
        assert_eq!(run(&["a", "-o", "o"]).map(|o| o.guided_subsample).ok(), Some(1));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample", "auto"]).map(|o| o.guided_subsample).ok(), Some(0));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample", "0"]).map(|o| o.guided_subsample).ok(), Some(0));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample=4"]).map(|o| o.guided_subsample).ok(), Some(4));
        let e = run(&["a", "-o", "o", "--guided-subsample", "fast"]).unwrap_err();
        assert!(e.to_string().contains("--guided-subsample"), "{e}");
    }

    #[test]
    fn restore_subcommand_and_out_spellings() {
        for args in [
            &["restore", "a.png", "-o", "out"][..],
            &["a.png", "--out", "out"],
            &["restore", "a.png", "--output", "out"],
            &["restore", "a.png", "--out=out"],
        ] {
            let o = run(args).unwrap();
            assert_eq!((o.inputs, o.outdir), (vec![PathBuf::from("a.png")], PathBuf::from("out")), "{args:?}");
        }
        // a file named "restore" after the first position is an input
        assert_eq!(run(&["a.png", "restore", "-o", "o"]).unwrap().inputs.len(), 2);
        // --reuse-estimates is accepted in batch mode too
        assert_eq!(run(&["a", "b", "-o", "o", "--reuse-estimates", "3"]).unwrap().reuse_estimates, Some(3));
    }

    #[test]
    fn help_has_every_option_and_exit_code() {
        let h = help();
        for s in OPTIONS.iter().filter(|s| s.faces != Faces::Python) {
            assert!(h.contains(s.flag), "{}", s.flag);
        }
        for (code, _, _) in crate::options::EXIT_CODES {
            assert!(h.contains(&format!("  {code} ")), "{code}");
        }
    }
}
