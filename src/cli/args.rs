//! Command-line options of `uwhl-rs` and their parser. The options mirror
//! the Python command `uwhl restore` (docs/OUTPUTS.md); the values are
//! checked here so that a bad option is a usage error before any input is read.

use super::CliError;
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

/// Input preprocessing (`--preprocess`, SPEC 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preprocess {
    /// decode sRGB to linear (the default; physically right)
    None,
    /// SPEC 2 reference: keep sRGB values as they are, mild pulled stretch
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

/// Default `--max-pixels`: 300 megapixels (as the Python command).
pub const DEFAULT_MAX_PIXELS: u64 = 300_000_000;

/// The smallest `--max-side` (the method needs 4x4 pixels).
pub const MIN_MAX_SIDE: usize = 4;

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
    pub selection: crate::pipeline::Selection,
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
            guided_eps: crate::pipeline::DEFAULT_EPS,
            guided_subsample: 1,
            sphere_points: crate::pipeline::DEFAULT_SPHERE_POINTS,
            max_side: None,
            preprocess: Preprocess::None,
            selection: crate::pipeline::Selection::Exhaustive,
            linear: false,
            format: Format::Jpg,
            bits: None,
            quality: 95,
            overwrite: false,
            threads: None,
            max_memory: crate::pipeline::DEFAULT_MAX_MEMORY,
            max_pixels: DEFAULT_MAX_PIXELS,
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
    /// `--help`
    Help,
    /// `--version`
    Version,
}

/// The `--help` text, with the exit codes.
pub const HELP: &str = "\
uwhl-rs: underwater colour restoration with haze-lines (Berman et al., TPAMI 2020)

Usage:
  uwhl-rs [OPTIONS] INPUT... -o OUTDIR     restore files and folders (PNG, JPEG, TIFF)
  uwhl-rs --stream [OPTIONS] -o OUTDIR     read image paths from stdin, one per line

For INPUT NAME.EXT writes OUTDIR/NAME.jpg (or .png/.tif), NAME_t.png (16-bit t_B),
NAME_t_color.png (colour-mapped t_B) and NAME.json (sidecar, written last).
Inputs are sRGB (decoded to linear) unless --linear.

Options:
  -o, --output DIR         output folder (created if missing)
      --water-type TYPES   candidate water types: Jerlov names (I IA IB II III 1C 3C 5C 7C 9C)
                           or NAME:BETA_BR:BETA_BG; repeatable or comma list (default: all ten)
      --veiling-light R,G,B  given veiling light A (linear), each in (0, 1]
      --mask PATH          image of the input's size: nonzero = use the pixel for estimation
      --water-mask PATH    image of the input's size: nonzero = water region (replaces detection)
      --guided-radius N    guided-filter radius (default round(min(H, W) / 4))
      --guided-eps X       guided-filter eps (default 0.001)
      --guided-subsample S|auto  guided-filter subsampling: 1 (default) the exact filter;
                           S >= 2 He and Sun's fast guided filter on S x S blocks (for video
                           and sequences: t_B within ~4e-4 on average); auto = max(1, radius/32)
      --sphere-points N    haze-line clusters (default 500)
      --max-side N         block-average the input so its longer side is at most N (N >= 4);
                           a mask block is used if all its pixels are, a water-mask block is
                           water if at least half its pixels are
      --preprocess MODE    none (default) | reference (SPEC 2: sRGB kept, pulled stretch)
      --selection MODE     exhaustive (default: every type at full resolution) | fast (types
                           scored on a ~1024 px copy, uncertain ones re-scored at full size)
      --linear             the input values are already linear (float TIFFs always are)
      --format FMT         jpg (default) | png | tiff
      --bits 8|16          png/tiff bits per sample (default: png 8, tiff 16; jpg is 8)
      --quality Q          JPEG quality 1-100 (default 95)
      --overwrite          process inputs whose sidecar exists (default: skip them)
      --threads N          worker threads (default: all cores); results do not depend on N
      --max-memory BYTES   memory budget, checked before decoding (suffixes K, M, G; default 16G)
      --max-pixels N       largest accepted input in pixels (default 300000000)
      --json-errors        report each error as one JSON object on stderr
      --stream             stream mode: one JSON line per frame on stdout, never stops on a bad frame
      --reuse-estimates N  stream mode: estimate water type and veiling light every N frames,
                           reuse them in between
      --reuse-water-mask   with --reuse-estimates: reuse the estimating frame's water region too
                           (a camera that holds its attitude; skips the water detection)
  -q, --quiet              no progress lines on stdout
  -h, --help               this text
  -V, --version            the version

Exit codes (with several inputs, every input is processed and the largest code is returned):
  0  every input restored (or skipped because its sidecar exists)
  2  bad arguments or option values
  3  an input could not be read, decoded or restored (corrupt, unsupported, constant...)
  4  an input is over --max-pixels or --max-memory
  5  an output could not be written
  6  internal error (a bug; please report)
In stream mode the exit code is 0 at the end of stdin unless the arguments were bad (2).
";

fn text(v: OsString, opt: &str) -> Result<String, CliError> {
    v.into_string()
        .map_err(|v| CliError::usage(format!("{opt}: {v:?} is not valid UTF-8")))
}

fn number<T>(v: OsString, opt: &str, min: T) -> Result<T, CliError>
where
    T: std::str::FromStr + PartialOrd + std::fmt::Display,
{
    let s = text(v, opt)?;
    match s.trim().parse::<T>() {
        Ok(n) if n >= min => Ok(n),
        _ => Err(CliError::usage(format!(
            "{opt}: {s:?} is not an integer >= {min}"
        ))),
    }
}

/// Parses a byte count with an optional suffix K, M, G, T (powers of 1024;
/// `KiB`, `MB` and the like are read the same way).
pub fn parse_bytes(s: &str) -> Option<u64> {
    let s = s.trim();
    let split = s
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(s.len());
    let (digits, suffix) = s.split_at(split);
    let n: u64 = digits.parse().ok()?;
    let shift = match suffix.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 0,
        "K" | "KB" | "KIB" => 10,
        "M" | "MB" | "MIB" => 20,
        "G" | "GB" | "GIB" => 30,
        "T" | "TB" | "TIB" => 40,
        _ => return None,
    };
    n.checked_mul(1u64 << shift)
}

fn triple(s: &str, opt: &str) -> Result<[f64; 3], CliError> {
    let parts: Vec<&str> = s
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|p| !p.is_empty())
        .collect();
    let bad = || CliError::usage(format!("{opt}: {s:?} is not three numbers R,G,B"));
    match parts.as_slice() {
        [r, g, b] => {
            let mut out = [0.0f64; 3];
            for (o, p) in out.iter_mut().zip([r, g, b]) {
                *o = p.parse().map_err(|_| bad())?;
            }
            if out.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 1.0)) {
                return Err(CliError::usage(format!(
                    "{opt}: every component of {s:?} must be in (0, 1]"
                )));
            }
            Ok(out)
        }
        _ => Err(bad()),
    }
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

/// Parses the command line (without the program name).
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
    while let Some(arg) = p.next().map_err(lex)? {
        match arg {
            Short('h') | Long("help") => return Ok(Command::Help),
            Short('V') | Long("version") => return Ok(Command::Version),
            Short('o') | Long("output") => outdir = Some(p.value().map_err(lex)?.into()),
            Long("water-type") => {
                let v = text(p.value().map_err(lex)?, "--water-type")?;
                let list = o.water_types.get_or_insert_with(Vec::new);
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
            }
            Long("veiling-light") => {
                let v = text(p.value().map_err(lex)?, "--veiling-light")?;
                o.veiling_light = Some(triple(&v, "--veiling-light")?);
            }
            Long("mask") => o.mask = Some(p.value().map_err(lex)?.into()),
            Long("water-mask") => o.water_mask = Some(p.value().map_err(lex)?.into()),
            Long("guided-radius") => {
                o.guided_radius = Some(number(p.value().map_err(lex)?, "--guided-radius", 0)?)
            }
            Long("guided-eps") => {
                let v = text(p.value().map_err(lex)?, "--guided-eps")?;
                match v.trim().parse::<f64>() {
                    Ok(x) if x.is_finite() && x > 0.0 => o.guided_eps = x,
                    _ => {
                        return Err(CliError::usage(format!(
                            "--guided-eps: {v:?} is not a number > 0"
                        )))
                    }
                }
            }
            Long("guided-subsample") => {
                let v = text(p.value().map_err(lex)?, "--guided-subsample")?;
                o.guided_subsample = match v.trim() {
                    "auto" => 0,
                    t => t.parse::<usize>().map_err(|_| {
                        CliError::usage(format!(
                            "--guided-subsample: {v:?} is not an integer >= 0 or auto"
                        ))
                    })?,
                };
            }
            Long("sphere-points") => {
                o.sphere_points = number(p.value().map_err(lex)?, "--sphere-points", 1)?
            }
            Long("max-side") => {
                o.max_side = Some(number(p.value().map_err(lex)?, "--max-side", MIN_MAX_SIDE)?)
            }
            Long("preprocess") => {
                o.preprocess = match text(p.value().map_err(lex)?, "--preprocess")?.as_str() {
                    "none" => Preprocess::None,
                    "reference" => Preprocess::Reference,
                    v => {
                        return Err(CliError::usage(format!(
                            "--preprocess: {v:?} is not none or reference"
                        )))
                    }
                }
            }
            Long("selection") => {
                o.selection = match text(p.value().map_err(lex)?, "--selection")?.as_str() {
                    "exhaustive" => crate::pipeline::Selection::Exhaustive,
                    "fast" => crate::pipeline::Selection::Fast,
                    v => {
                        return Err(CliError::usage(format!(
                            "--selection: {v:?} is not exhaustive or fast"
                        )))
                    }
                }
            }
            Long("linear") => o.linear = true,
            Long("format") => {
                o.format = match text(p.value().map_err(lex)?, "--format")?
                    .to_ascii_lowercase()
                    .as_str()
                {
                    "jpg" | "jpeg" => Format::Jpg,
                    "png" => Format::Png,
                    "tif" | "tiff" => Format::Tiff,
                    v => {
                        return Err(CliError::usage(format!(
                            "--format: {v:?} is not jpg, png or tiff"
                        )))
                    }
                }
            }
            Long("bits") => {
                o.bits = match number::<u8>(p.value().map_err(lex)?, "--bits", 0)? {
                    b @ (8 | 16) => Some(b),
                    b => return Err(CliError::usage(format!("--bits: {b} is not 8 or 16"))),
                }
            }
            Long("quality") => {
                let q = number::<u8>(p.value().map_err(lex)?, "--quality", 1)?;
                if q > 100 {
                    return Err(CliError::usage(format!("--quality: {q} is not in 1..100")));
                }
                o.quality = q;
            }
            Long("overwrite") => o.overwrite = true,
            Long("threads") => {
                let n = number(p.value().map_err(lex)?, "--threads", 1)?;
                if n > 1024 {
                    return Err(CliError::usage(format!("--threads: {n} is more than 1024")));
                }
                o.threads = Some(n);
            }
            Long("max-memory") => {
                let v = text(p.value().map_err(lex)?, "--max-memory")?;
                o.max_memory = parse_bytes(&v).filter(|&b| b > 0).ok_or_else(|| {
                    CliError::usage(format!(
                        "--max-memory: {v:?} is not a byte count > 0 (e.g. 2000000000, 512M, 4G)"
                    ))
                })?;
            }
            Long("max-pixels") => o.max_pixels = number(p.value().map_err(lex)?, "--max-pixels", 1)?,
            Long("json-errors") => o.json_errors = true,
            Long("stream") => o.stream = true,
            Long("reuse-estimates") => {
                o.reuse_estimates = Some(number(p.value().map_err(lex)?, "--reuse-estimates", 1)?)
            }
            Long("reuse-water-mask") => o.reuse_water_mask = true,
            Short('q') | Long("quiet") => o.quiet = true,
            Value(v) => o.inputs.push(v.into()),
            _ => return Err(CliError::usage(arg.unexpected().to_string())),
        }
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
    if o.reuse_estimates.is_some() && !o.stream {
        return Err(CliError::usage("--reuse-estimates needs --stream"));
    }
    if o.reuse_water_mask && o.reuse_estimates.is_none() {
        return Err(CliError::usage("--reuse-water-mask needs --reuse-estimates N"));
    }
    if o.format == Format::Jpg && o.bits == Some(16) {
        return Err(CliError::usage(
            "--bits 16 needs --format png or tiff (JPEG holds 8 bits)",
        ));
    }
    if o.linear && o.preprocess == Preprocess::Reference {
        return Err(CliError::usage(
            "--preprocess reference is the SPEC 2 treatment of sRGB inputs; it cannot be used with --linear",
        ));
    }
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
            &["a", "-o", "o", "--reuse-estimates", "3"],
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
    fn byte_suffixes() {
        assert_eq!(parse_bytes("1024"), Some(1024));
        assert_eq!(parse_bytes("2K"), Some(2048));
        assert_eq!(parse_bytes("3GiB"), Some(3 << 30));
        assert_eq!(parse_bytes("1x"), None);
        assert_eq!(parse_bytes("99999999999T"), None);
    }
}
