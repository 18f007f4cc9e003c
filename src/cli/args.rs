//! Command-line options of `uwhl-rs` and their parser. The options mirror
//! the Python command `uwhl restore` (docs/OUTPUTS.md); the values are
//! checked here so that a bad option is a usage error before any input is read.

use super::{Failure, Kind};
pub use crate::files::settings::{Format, Preprocess, Settings, WaterChoice};
use crate::files::options::{exit_code_text, help_text, Faces, Kind as OptKind, Value as Val, OPTIONS};
use crate::method::water::WaterType;
use std::ffi::OsString;
use std::path::PathBuf;

/// Every option of the command, checked: one input's [`Settings`] (read
/// through `Deref`) and what the command itself does with its inputs.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// what each input's processing does (method and files)
    pub settings: Settings,
    /// input files and folders (batch mode)
    pub inputs: Vec<PathBuf>,
    /// `-o DIR`
    pub outdir: PathBuf,
    /// `--json-errors`
    pub json_errors: bool,
    /// `--stream`: paths on stdin, one JSON line per frame on stdout
    pub stream: bool,
    /// `-q`: no progress lines on stdout (batch mode)
    pub quiet: bool,
    /// `--raw-frames WxH`: frames of this width and height on stdin
    pub raw_frames: Option<(usize, usize)>,
    /// `--pix-fmt`: bits a sample of the raw frames (8: rgb24, 16: rgb48le)
    pub pix_fmt_bits: u32,
    /// `--pix-fmt` was given
    pub pix_fmt_given: bool,
    /// `--port` was given (it has a default: only a given one can be one too many)
    pub port_given: bool,
}

impl std::ops::Deref for Options {
    type Target = Settings;
    fn deref(&self) -> &Settings {
        &self.settings
    }
}

impl std::ops::DerefMut for Options {
    fn deref_mut(&mut self) -> &mut Settings {
        &mut self.settings
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
    /// `demo --help`
    DemoHelp,
    /// `--version`
    Version,
}

/// The demo's default output folder.
const DEMO_OUT: &str = "uwhl_demo";
/// The demo's default water type.
const DEMO_TYPE: &str = "III";
/// The demo's default size (height, width).
const DEMO_SIZE: (usize, usize) = (480, 640);
/// The demo's default seed.
const DEMO_SEED: u64 = 7;

/// The `demo --help` text: the demo's own options (as `uwhl demo --help`).
pub fn demo_help() -> String {
    let types: Vec<String> = crate::method::water::jerlov_types().into_iter().map(|t| t.name).collect();
    format!(
        "usage: uwhl-rs demo [-o DIR] [--water-type T] [--size HxW] [--seed N]

Render the package's synthetic underwater scene (nothing is downloaded),
restore it, write input/restored/transmission/clean_truth PNGs and report
true vs estimated water type and A.

options:
  -h, --help          this help
  -o, --out DIR       output folder (default ./{DEMO_OUT})
  --water-type T      water type to render: {} (default {DEMO_TYPE})
  --size HxW          height x width of the scene (default {}x{})
  --seed N            scene seed (default {DEMO_SEED})
",
        types.join(", "),
        DEMO_SIZE.0,
        DEMO_SIZE.1
    )
}

/// The `--help` text: usage, the options of the table (`crate::files::options`)
/// that this command takes, and the exit codes.
pub fn help() -> String {
    format!(
        "uwhl-rs: underwater colour restoration with haze-lines (Berman et al., TPAMI 2020)

usage:
  uwhl-rs restore [OPTIONS] INPUT... -o OUTDIR   restore files and folders (PNG, JPEG, TIFF)
  uwhl-rs restore --stream [OPTIONS] -o OUTDIR   read image paths from stdin, one per line
  uwhl-rs restore --raw-frames WxH [OPTIONS] -o -|OUTDIR
                                                 restore raw frames from stdin (rgb24 or rgb48le) as one
                                                 sequence, to stdout or to OUTDIR
  uwhl-rs [OPTIONS] INPUT... -o OUTDIR           the same as 'uwhl-rs restore'
  uwhl-rs demo [-o DIR] [--water-type T] [--size HxW] [--seed N]
                                                 restore the built-in rendered scene

For INPUT NAME.EXT writes OUTDIR/NAME.jpg (or .png/.tif), NAME_t.png (16-bit t_B),
NAME_t_color.png (colour-mapped t_B), NAME_confidence.png (16-bit, 1 = the colours
can be trusted; not with --fallback none) and NAME.json (sidecar, written last).
Inputs are sRGB (decoded to linear) unless --linear. The options, outputs and exit
codes are those of the Python command 'uwhl restore' (docs/CLI.md).

  -o, --out DIR              output folder (created if missing; --output is the same)
{}  -h, --help                 this text
  -V, --version              the version

{}In stream mode the exit code is 0 at the end of stdin unless the arguments were bad (2)
or the output folder cannot be made (5). With --raw-frames it is 0 at a clean end of stdin,
3 when stdin ends inside a frame, 4 when a frame does not fit --max-memory, 5 when stdout
closes. In both, SIGINT or SIGTERM end the run at once by that signal (a shell shows 130
or 143).
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

/// The value of `-o`: an empty name would be taken as the current folder,
/// which is never what was meant (an unset shell variable), so it is refused.
fn outdir_value(v: OsString) -> Result<PathBuf, Failure> {
    if v.is_empty() {
        return Err(Failure::usage(
            "-o/--out: the output folder's name is empty (give a folder; '.' for the current one)",
        ));
    }
    // "--" ends the options: as a folder's name it is a slip (the Python command refuses it too)
    if v == "--" {
        return Err(Failure::usage("-o/--out: expected a folder, not '--' (write ./-- for a folder of that name)"));
    }
    Ok(v.into())
}

/// Parses `demo`'s options (after the subcommand).
fn parse_demo(p: &mut lexopt::Parser) -> Result<Command, Failure> {
    use lexopt::prelude::*;
    let lex = |e: lexopt::Error| Failure::usage(e.to_string());
    let text = |v: OsString, flag: &str| v.into_string().map_err(|v| Failure::usage(format!("{flag}: {v:?} is not valid UTF-8")));
    let mut d = Demo {
        out: PathBuf::from(DEMO_OUT),
        water_type: WaterType::by_name(DEMO_TYPE).map_err(|e| Failure::new(Kind::Internal, e.to_string()))?,
        size: DEMO_SIZE,
        seed: DEMO_SEED,
    };
    while let Some(arg) = p.next().map_err(lex)? {
        match arg {
            Short('h') | Long("help") => return Ok(Command::DemoHelp),
            Short('o') | Long("out") | Long("output") => d.out = outdir_value(p.value().map_err(lex)?)?,
            Long("water-type") => {
                let v = text(p.value().map_err(lex)?, "--water-type")?;
                d.water_type = WaterType::by_name(v.trim()).map_err(|e| Failure::usage(format!("--water-type: {e}")))?;
            }
            Long("size") => {
                let v = text(p.value().map_err(lex)?, "--size")?;
                let hw: Vec<usize> = v.to_ascii_lowercase().split('x').filter_map(|t| t.trim().parse().ok()).collect();
                d.size = match hw.as_slice() {
                    [h, w] if *h >= 4 && *w >= 4 && h.saturating_mul(*w) <= 50_000_000 => (*h, *w),
                    _ => return Err(Failure::usage(format!("--size: {v:?} is not HxW with sides >= 4 (e.g. 480x640)"))),
                };
            }
            Long("seed") => {
                let v = text(p.value().map_err(lex)?, "--seed")?;
                d.seed = v.trim().parse().map_err(|_| Failure::usage(format!("--seed: {v:?} is not an integer >= 0")))?;
            }
            _ => return Err(Failure::usage(arg.unexpected().to_string())),
        }
    }
    Ok(Command::Demo(d))
}

impl Options {
    /// Sets the option `key` of the table to its parsed value: the
    /// command's own options here, the rest through [`Settings::set`].
    fn set(&mut self, key: &str, v: Val) -> Result<(), Failure> {
        match key {
            "stream" => self.stream = true,
            "raw_frames" => {
                if let Val::Size(w, h) = v {
                    self.raw_frames = Some((w, h));
                }
            }
            "pix_fmt" => {
                self.pix_fmt_given = true;
                self.pix_fmt_bits = match v {
                    Val::Text(t) if t == "rgb48le" => 16,
                    _ => 8,
                }
            }
            "port" => {
                self.port_given = true;
                self.settings.set(key, v)?;
            }
            "json_errors" => self.json_errors = true,
            "quiet" => self.quiet = true,
            _ => {
                if !self.settings.set(key, v)? {
                    return Err(Failure::new(Kind::Internal, format!("option {key} has no field")));
                }
            }
        }
        Ok(())
    }
}

/// What an unknown short option `c` says: the whole word it came from
/// (`-dash.mp4`, not `-d`; `crate::files::options::unknown_short_said`).
fn unknown_short(args: &[OsString], c: char) -> String {
    let word = args
        .iter()
        .map(|a| a.to_string_lossy())
        .take_while(|a| a != "--")
        .find(|a| a.starts_with('-') && !a.starts_with("--") && a.chars().nth(1) == Some(c));
    crate::files::options::unknown_short_said(&word.map_or_else(|| format!("-{c}"), |w| w.into_owned()))
}

/// Parses the command line (without the program name): `restore` and its
/// options, or the same options without the subcommand.
pub fn parse<I>(args: I) -> Result<Command, Failure>
where
    I: IntoIterator,
    I::Item: Into<OsString>,
{
    use lexopt::prelude::*;
    let mut o = Options::default();
    let mut outdir: Option<PathBuf> = None;
    let args: Vec<OsString> = args.into_iter().map(Into::into).collect();
    let mut p = lexopt::Parser::from_args(args.clone());
    let lex = |e: lexopt::Error| Failure::usage(e.to_string());
    let mut first = true;
    // the folder is read once the command line is known to be whole, so
    // that a usage error is named before the folder's (as in Python)
    let mut water_from: Option<Val> = None;
    while let Some(arg) = p.next().map_err(lex)? {
        let is_first = std::mem::replace(&mut first, false);
        let spec = match &arg {
            Short('h') | Long("help") => return Ok(Command::Help),
            Short('V') | Long("version") => return Ok(Command::Version),
            Short('o') | Long("out") | Long("output") => {
                outdir = Some(outdir_value(p.value().map_err(lex)?)?);
                continue;
            }
            Value(v) if is_first && v == "restore" => continue,
            Value(v) if is_first && v == "demo" => return parse_demo(&mut p),
            Value(v) if is_first && (v == "evaluate" || v == "report" || v == "ifdo") => {
                return Err(Failure::usage(format!(
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
                return Err(Failure::usage(format!(
                    "{} is an option of the Python command only: run 'uwhl restore' (docs/CLI.md)",
                    s.flag
                )))
            }
            None => return Err(Failure::usage(match &arg {
                Short(c) => unknown_short(&args, *c),
                _ => arg.unexpected().to_string(),
            })),
        };
        let value = if spec.kind == OptKind::Flag {
            Val::On
        } else {
            let raw = p.value().map_err(lex)?;
            let t = raw
                .into_string()
                .map_err(|v| Failure::usage(format!("{}: {v:?} is not valid UTF-8", spec.flag)))?;
            spec.parse(&t).map_err(Failure::usage)?
        };
        if spec.key == "water_from" {
            water_from = Some(value);
            continue;
        }
        o.set(spec.key, value)?;
    }
    o.outdir = outdir.ok_or_else(|| Failure::usage("-o OUTDIR is required"))?;
    if o.pix_fmt_bits == 0 {
        o.pix_fmt_bits = 8;
    }
    if o.raw_frames.is_some() {
        if o.stream || !o.inputs.is_empty() {
            return Err(Failure::usage("--raw-frames reads the frames from stdin; give no INPUT arguments and no --stream"));
        }
        // frames are restored at their own size: a reduced size of the
        // frames out would no longer match the frames in (-o -), and the
        // folder's frames were written at full size whatever --max-side said
        if o.max_side.is_some() {
            return Err(Failure::usage(
                "--max-side with --raw-frames: frames are restored at the size they come in (scale them before the pipe, e.g. ffmpeg -vf scale)",
            ));
        }
        if o.distance.is_some() || o.altitude.is_some() || water_from.is_some() {
            return Err(Failure::usage("--raw-frames restores a sequence: --distance, --altitude and --water-from are for photos"));
        }
        // the samples' curve is --transfer's: these photo options would be silently ignored
        if o.linear {
            return Err(Failure::usage("--linear is for photos: the curve of --raw-frames samples is --transfer (--transfer linear)"));
        }
        if o.preprocess == crate::files::settings::Preprocess::Reference {
            return Err(Failure::usage("--preprocess is for photos: the curve of --raw-frames samples is --transfer"));
        }
    } else if o.outdir.as_os_str() == "-" {
        return Err(Failure::usage("-o - (stdout) is for --raw-frames; give an output folder"));
    } else if o.pix_fmt_given {
        return Err(Failure::usage("--pix-fmt is for --raw-frames"));
    }
    if o.stream && !o.inputs.is_empty() {
        return Err(Failure::usage(
            "--stream reads the input paths from stdin; give no INPUT arguments",
        ));
    }
    if !o.stream && o.raw_frames.is_none() && o.inputs.is_empty() {
        return Err(Failure::usage("no INPUT given (or use --stream or --raw-frames)"));
    }
    crate::files::options::check_combination(
        o.format.name(),
        o.bits.map(u64::from),
        o.reuse_estimates.map(|n| n as u64),
        o.reuse_water_mask,
        o.linear,
        o.preprocess.name(),
        crate::files::options::Names::Flags,
    )
    .map_err(Failure::usage)?;
    crate::files::options::check_water(water_from.is_some(), o.water_types.is_some(), crate::files::options::Names::Flags)
        .map_err(Failure::usage)?;
    crate::files::options::check_distance(
        o.distance.is_some(),
        o.altitude.is_some(),
        o.fov.is_some(),
        o.depth_along_axis,
        o.reuse_estimates.is_some(),
        o.port_given,
        crate::files::options::Names::Flags,
    )
    .map_err(Failure::usage)?;
    if let Some(v) = water_from {
        o.set("water_from", v)?;
    }
    Ok(Command::Run(Box::new(o)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(args: &[&str]) -> Result<Options, Failure> {
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
        assert_eq!(o.params.guided_radius, Some(7));
        assert_eq!(o.params.guided_subsample, 3);
        assert_eq!(o.max_side, Some(512));
        assert_eq!(o.format, Format::Tiff);
        assert_eq!(o.params.max_memory, 512 << 20);
        assert_eq!(o.params.threads, Some(2));
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
        assert_eq!(run(&["a", "-o", "o"]).map(|o| o.params.guided_subsample).ok(), Some(1));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample", "auto"]).map(|o| o.params.guided_subsample).ok(), Some(0));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample", "0"]).map(|o| o.params.guided_subsample).ok(), Some(0));
        assert_eq!(run(&["a", "-o", "o", "--guided-subsample=4"]).map(|o| o.params.guided_subsample).ok(), Some(4));
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
    fn an_empty_out_is_refused_not_the_current_folder() {
        for args in [&["a.png", "-o", ""][..], &["a.png", "--out="], &["--stream", "--output", ""]] {
            let e = run(args).err().unwrap();
            assert_eq!(e.kind, Kind::Usage, "{args:?}");
            assert!(e.message.contains("-o/--out") && e.message.contains("empty"), "{}", e.message);
        }
        let e = parse(["demo", "-o", ""].iter().copied()).err().unwrap();
        assert_eq!(e.kind, Kind::Usage);
    }

    #[test]
    fn help_has_every_option_and_exit_code() {
        let h = help();
        for s in OPTIONS.iter().filter(|s| s.faces != Faces::Python) {
            assert!(h.contains(s.flag), "{}", s.flag);
        }
        for (code, _, _) in crate::files::options::EXIT_CODES {
            assert!(h.contains(&format!("  {code} ")), "{code}");
        }
    }
}
