//! `uwhl-rs restore --raw-frames WxH`: frames piped in on stdin (FFmpeg's
//! `-f rawvideo -pix_fmt rgb24` or `rgb48le`) restored as one sequence
//! (METHOD §10: estimates reused, re-estimated on a schedule, at cuts and
//! drifts, A smoothed), written to stdout in the same format (`-o -`) or
//! as each frame's outputs in a folder with one JSON line a frame
//! (`-o DIR`, as `--stream`). docs/CLI.md "Raw frames".
//!
//! Memory is planned once, from the frame size, and checked against
//! `--max-memory` before the first frame is read. The frame buffers (bytes
//! in, linear light, bytes out) are made once, and each restoration's
//! planes go back to the [`Sequence`] for the next frame
//! ([`Sequence::recycle`]), so frames of a steady stream allocate no
//! frame-sized buffer.

use super::args::Options;
use super::run::report;
use super::{Failure, Kind};
use crate::files::commit::{claim, Request, Resolution};
use crate::files::pipeline::{fit_mask, sequence_of, write_outputs, Outputs, Timing};
use crate::files::settings::Preprocess;
use crate::files::sidecar::{Estimates, Source};
use crate::files::transfer::{Codec, Transfer};
use crate::method::image::ImageRef;
use crate::method::params::{memory_estimate, Flag, Input};
use crate::method::sequence::{Decision, Sequence, VIDEO_SCENE_CUT, VIDEO_SMOOTHING};
use std::io::{ErrorKind, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Frames between scheduled estimates when `--reuse-estimates` is not
/// given: a second at 30 frames a second.
pub const DEFAULT_REFRESH: usize = 30;

/// How a frame read ended.
enum Got {
    /// a whole frame is in the buffer
    Frame,
    /// the input ended cleanly, between frames
    End,
    /// the input ended `got` bytes into a frame
    Partial(usize),
}

/// Reads one frame of `buf.len()` bytes: the whole frame, the end of the
/// input between frames, or where it ended inside one.
fn read_frame(input: &mut dyn Read, buf: &mut [u8]) -> std::io::Result<Got> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(buf.get_mut(got..).unwrap_or_default()) {
            Ok(0) => return Ok(if got == 0 { Got::End } else { Got::Partial(got) }),
            Ok(n) => got += n,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Got::Frame)
}

/// The bytes one frame of `w` x `h` needs while it is restored and
/// written: the bytes in and out, linear light, the method's estimate,
/// the restoration, and with `-o DIR` the outputs being encoded.
pub fn frame_plan(w: usize, h: usize, bytes_per_sample: u64, masks: bool, to_folder: bool) -> u64 {
    let n = (w as u64).saturating_mul(h as u64);
    let io = n.saturating_mul(6 * bytes_per_sample);
    let write = if to_folder { crate::files::budget::HELD_WHILE_WRITING } else { 0 };
    io.saturating_add(n.saturating_mul(12 + 33 + write))
        .saturating_add(memory_estimate(h, w, masks))
}

/// The sequence of a raw-frame run: `--reuse-estimates N` (default 30),
/// `--scene-cut`, `--smoothing` (defaults: a video's).
pub fn frame_sequence(opts: &Options) -> Sequence {
    sequence_of(opts, opts.reuse_estimates.unwrap_or(DEFAULT_REFRESH), VIDEO_SCENE_CUT, VIDEO_SMOOTHING)
}

/// Where the restored frames go.
enum Sink<'a> {
    /// `-o -`: the frames, in the input's format
    Stdout(&'a mut dyn Write),
    /// `-o DIR`: each frame's outputs, a JSON line each on `lines`
    Folder(&'a Path, &'a mut dyn Write),
}

/// Runs `--raw-frames`: returns the exit code (0 at a clean end of stdin;
/// 3 when it ends inside a frame, cannot be read, or none of its frames
/// could be restored; 4 when one frame does not fit `--max-memory`; 5 when
/// the frames or lines cannot be written).
pub fn run_frames(opts: &Options, input: &mut dyn Read, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    crate::kernels::memory::process_base();
    let Some((w, h)) = opts.raw_frames else {
        return Kind::Internal.exit_code();
    };
    let bytes_per_sample: usize = if opts.pix_fmt_bits == 16 { 2 } else { 1 };
    let frame_bytes = w * h * 3 * bytes_per_sample;
    // the frames' stated size is their header: held to --max-pixels as a photo's is
    let pixels = (w as u64).saturating_mul(h as u64);
    if pixels > opts.max_pixels {
        let e = Failure::new(
            Kind::Budget,
            format!("frames of {w}x{h} = {pixels} pixels are over the limit of {} pixels (--max-pixels)", opts.max_pixels),
        );
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    let to_stdout = opts.outdir.as_os_str() == "-";
    if !to_stdout {
        if let Err(code) = super::run::outdir_usable(opts, err) {
            return code;
        }
    }
    let masks = match crate::files::pipeline::load_masks(opts) {
        Ok(m) => m,
        Err(e) => {
            report(err, opts.json_errors, None, &e);
            return e.kind.exit_code();
        }
    };
    // checked against the frames' size once (the photo path's check)
    let fitted = fit_mask(masks.mask.as_ref(), "--mask", (h, w, 1), 1, 1.0)
        .and_then(|m| Ok((m, fit_mask(masks.water.as_ref(), "--water-mask", (h, w, 1), 1, 0.5)?)));
    let (mask, water) = match fitted {
        Ok(m) => m,
        Err(e) => {
            report(err, opts.json_errors, None, &e);
            return e.kind.exit_code();
        }
    };
    let need = frame_plan(w, h, bytes_per_sample as u64, masks.mask.is_some() || masks.water.is_some(), !to_stdout)
        .saturating_add(crate::kernels::memory::process_base());
    // which limit it is: the one the user set, or the machine's
    let over = if need > opts.params.max_memory {
        Some(format!("over --max-memory {}", opts.params.max_memory))
    } else if !crate::kernels::memory::can_allocate(need) {
        Some("more than the system gives now (free memory, a container limit or ulimit -v)".to_string())
    } else {
        None
    };
    if let Some(over) = over {
        let e = Failure::new(Kind::Budget, format!("frames of {w}x{h} need about {need} bytes, {over}"));
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    let transfer = opts.transfer.unwrap_or(Transfer::Bt709);
    let codec = Codec::new(transfer, if bytes_per_sample == 2 { 16 } else { 8 });
    let mut seq = frame_sequence(opts);
    let _presence = if to_stdout {
        None
    } else {
        match super::run::enter_outdir(opts, err) {
            Ok(p) => p,
            Err(code) => return code,
        }
    };
    // one pipe at a time in a folder: two would write frame_000000 on, each
    // reporting the other's frames as its own
    let _pipe = if to_stdout {
        None
    } else {
        match hold_pipe(&opts.outdir) {
            Ok(f) => Some(f),
            Err(e) => {
                report(err, opts.json_errors, Some(&opts.outdir), &e);
                return e.kind.exit_code();
            }
        }
    };
    let mut sink = if to_stdout { Sink::Stdout(out) } else { Sink::Folder(&opts.outdir, out) };
    // the buffers of every frame, made once
    let mut bytes_in = vec![0u8; frame_bytes];
    let mut samples16 = vec![0u16; if bytes_per_sample == 2 { w * h * 3 } else { 0 }];
    let mut linear = vec![0f32; w * h * 3];
    let mut bytes_out = vec![0u8; if to_stdout { frame_bytes } else { 0 }];
    let t0 = Instant::now();
    let mut k = 0usize;
    // a run of frames that cannot be restored (a camera's black start, a
    // lens cap): its first frame said on stderr, the rest in one line when
    // the run ends (/dev/zero would otherwise be thousands of lines a second)
    let mut run = Unrestored::default();
    let mut restored = 0usize;
    // why the first frame that could not be restored was not: said again
    // when none could be (-q keeps the per-frame lines quiet)
    let mut why_not: Option<String> = None;
    let code = loop {
        match read_frame(input, &mut bytes_in) {
            Ok(Got::Frame) => {}
            Ok(Got::End) => break 0,
            Ok(Got::Partial(got)) => {
                run.end(err, opts.quiet);
                let e = Failure::new(
                    Kind::Input,
                    format!("stdin ended inside frame {k} ({got} of its {frame_bytes} bytes): that frame is dropped"),
                );
                report(err, opts.json_errors, None, &e);
                break e.kind.exit_code();
            }
            Err(e) => {
                let e = Failure::new(Kind::Input, format!("cannot read frame {k} from stdin: {e}"));
                report(err, opts.json_errors, None, &e);
                break e.kind.exit_code();
            }
        }
        let t_frame = Instant::now();
        if bytes_per_sample == 2 {
            for (s, &b) in samples16.iter_mut().zip(bytes_in.as_chunks::<2>().0) {
                *s = u16::from_le_bytes(b);
            }
            codec.decode_u16(&samples16, &mut linear);
        } else {
            codec.decode_u8(&bytes_in, &mut linear);
        }
        let t_read = t_frame.elapsed().as_secs_f64();
        let image = match ImageRef::new(&linear, h, w) {
            Ok(i) => i,
            Err(e) => {
                let e = Failure::from(e);
                report(err, opts.json_errors, None, &e);
                break e.kind.exit_code();
            }
        };
        let frame = Input {
            image,
            mask: mask.as_deref(),
            water_mask: water.as_deref(),
        };
        let t1 = Instant::now();
        let res = match seq.restore(&frame) {
            Ok(r) => r,
            Err(e) => {
                // one frame that cannot be restored (black or flat: no haze-line
                // to read) never stops the stream, and the frames out stay in
                // step with the frames in: it goes out as it came in (stdout),
                // or its line is the error (a folder)
                let e = Failure::from(e);
                let first = run.add(k);
                if why_not.is_none() {
                    why_not = Some(format!("frame {k}: {}", e.message));
                }
                let written = match &mut sink {
                    Sink::Stdout(o) => {
                        if first && opts.json_errors {
                            let said = Failure::new(e.kind, format!("frame {k}: {}; written as it came in", e.message));
                            report(err, true, None, &said);
                        } else if !opts.quiet && first {
                            let _ = writeln!(err, "uwhl-rs: frame {k}: {}; written as it came in", e.message);
                        }
                        o.write_all(&bytes_in).and_then(|()| o.flush()).map_err(|why| {
                            Failure::new(Kind::Write, format!("cannot write frame {k} to stdout ({why}): stopped"))
                        })
                    }
                    Sink::Folder(dir, lines) => {
                        let e = Failure::new(e.kind, format!("frame {k}: {}", e.message));
                        if first {
                            report(err, opts.json_errors, None, &e);
                        }
                        // an earlier run's outputs of frame k are not this run's frame k
                        if let Err(why) = clear_frame(opts, dir, k) {
                            report(err, opts.json_errors, None, &why);
                        }
                        // compact, as every other line on stdout (the sidecars, the write errors)
                        writeln!(lines, "{}", crate::cli::run::json_line(&e.to_json(Some(&format!("stdin#{k}"))).to_string()))
                            .and_then(|()| lines.flush())
                            .map_err(
                            |why| Failure::new(Kind::Write, format!("cannot write the line of frame {k} to stdout ({why}): stopped")),
                        )
                    }
                };
                if let Err(e) = written {
                    report(err, opts.json_errors, None, &e);
                    break e.kind.exit_code();
                }
                k += 1;
                continue;
            }
        };
        let t_restore = t1.elapsed().as_secs_f64();
        restored += 1;
        run.end(err, opts.quiet);
        let (decision, change) = seq.last_decision();
        if decision != Decision::Reused && !opts.quiet {
            let a = res.veiling_light;
            let _ = writeln!(
                err,
                "uwhl-rs: frame {k}: {} estimate (colour change {change:.2}): water type {}, A ({:.4}, {:.4}, {:.4})",
                decision.name(),
                res.water_type.name,
                a[0],
                a[1],
                a[2]
            );
        }
        let written = match &mut sink {
            Sink::Stdout(o) => {
                if bytes_per_sample == 2 {
                    codec.encode_u16(&res.image, &mut samples16);
                    for (b, s) in bytes_out.chunks_exact_mut(2).zip(&samples16) {
                        b.copy_from_slice(&s.to_le_bytes());
                    }
                } else {
                    codec.encode_u8(&res.image, &mut bytes_out);
                }
                o.write_all(&bytes_out).and_then(|()| o.flush()).map_err(|e| {
                    Failure::new(Kind::Write, format!("cannot write frame {k} to stdout ({e}): stopped"))
                })
            }
            Sink::Folder(dir, lines) => {
                let t = Timing { read: t_read, restore: t_restore, contact_sheet: None, start: t_frame };
                // a frame whose files cannot be written (a folder planted at
                // its name) is that frame's error line, as in --stream; the run
                // stops only when the lines themselves cannot be written
                let line = match write_frame(opts, dir, k, (w, h), transfer, bytes_per_sample, &res, decision, t) {
                    Ok(side) => side,
                    Err(e) => {
                        report(err, opts.json_errors, None, &e);
                        e.to_json(Some(&format!("stdin#{k}"))).to_string()
                    }
                };
                writeln!(lines, "{}", crate::cli::run::json_line(&line)).and_then(|()| lines.flush()).map_err(|e| {
                    Failure::new(Kind::Write, format!("cannot write the line of frame {k} to stdout ({e}): stopped"))
                })
            }
        };
        seq.recycle(res);
        if let Err(e) = written {
            report(err, opts.json_errors, None, &e);
            break e.kind.exit_code();
        }
        k += 1;
    };
    run.end(err, opts.quiet);
    if !opts.quiet {
        let s = t0.elapsed().as_secs_f64();
        let _ = writeln!(err, "uwhl-rs: {k} frames in {s:.1} s ({:.2} frames a second)", k as f64 / s.max(1e-9));
    }
    // a stream of which no frame could be restored failed, as a video
    // whose frames all fail does: its frames still went out in step
    if code == 0 && k > 0 && restored == 0 {
        let why = why_not.map(|w| format!("; {w}")).unwrap_or_default();
        let e = Failure::new(Kind::Input, format!("no frame could be restored (all {k} read from stdin){why}"));
        report(err, opts.json_errors, None, &e);
        return e.kind.exit_code();
    }
    code
}

/// A run of consecutive frames that could not be restored: its first
/// frame and how many.
#[derive(Default)]
struct Unrestored {
    first: usize,
    count: usize,
}

impl Unrestored {
    /// Counts frame `k`; whether it begins a run (its own line is said).
    fn add(&mut self, k: usize) -> bool {
        if self.count == 0 {
            self.first = k;
        }
        self.count += 1;
        self.count == 1
    }

    /// Ends the run: one line for the frames after its first, when any.
    fn end(&mut self, err: &mut dyn Write, quiet: bool) {
        if self.count > 1 && !quiet {
            let (a, b) = (self.first + 1, self.first + self.count - 1);
            let _ = writeln!(err, "uwhl-rs: frames {a}-{b}: the same ({} frames, not restored as frame {} was not)", b - a + 1, self.first);
        }
        self.count = 0;
    }
}

/// The lock of the one pipe of frames writing to `dir` (an exclusive
/// `flock` on `dir/.uwhl-frames.lock`, held while the returned file is):
/// a second pipe into the folder is refused before it reads a frame.
fn hold_pipe(dir: &Path) -> Result<std::fs::File, Failure> {
    let path = dir.join(".uwhl-frames.lock");
    let cannot = |e: std::io::Error| Failure::new(Kind::Write, format!("cannot make {}: {e}", path.display()));
    let f = std::fs::OpenOptions::new().create(true).truncate(false).write(true).open(&path).map_err(cannot)?;
    match f.try_lock() {
        Ok(()) => Ok(f),
        Err(std::fs::TryLockError::WouldBlock) => Err(Failure::new(
            Kind::Write,
            format!(
                "another --raw-frames run is writing to {}: the frames of both would take the same names; give each pipe a folder of its own",
                dir.display()
            ),
        )),
        Err(std::fs::TryLockError::Error(e)) => Err(cannot(e)),
    }
}

/// Why frame `k`'s name in `dir` is not this pipe's to replace: its
/// sidecar is another input's (a photo named `frame_000000.png` restored
/// into the folder). The frames of a pipe replace an earlier pipe's
/// (`stdin#k`), never another input's outputs.
fn others_at(dir: &Path, name: &str, k: usize) -> Result<(), Failure> {
    let sidecar = dir.join(format!("{name}.json"));
    let Some(side) = crate::files::commit::read_sidecar(&sidecar) else { return Ok(()) };
    match side.get("input").and_then(serde_json::Value::as_str) {
        Some(input) if input == format!("stdin#{k}") => Ok(()),
        other => Err(Failure::new(
            Kind::Write,
            format!(
                "{} holds the outputs of {}: not replaced (write the frames to a folder of their own)",
                sidecar.display(),
                other.map_or_else(|| "another input".to_string(), crate::files::nav::shown)
            ),
        )),
    }
}

/// Removes what an earlier run wrote as frame `k` in `dir` (a frame this
/// run cannot restore has no outputs, only its line).
fn clear_frame(opts: &Options, dir: &Path, k: usize) -> Result<(), Failure> {
    let name = format!("frame_{k:06}");
    others_at(dir, &name, k)?;
    let input = PathBuf::from(format!("stdin#{k}"));
    let suffixes = crate::files::pipeline::output_suffixes(opts);
    // nothing there (the usual case): no claim, no sync of the folder
    let there = |s: &str| std::fs::symlink_metadata(dir.join(format!("{name}{s}"))).is_ok();
    if !there(".json") && !suffixes.iter().any(|s| there(s)) {
        return Ok(());
    }
    let request = Request { dir, base: &name, input: &input, suffixes: &suffixes, overwrite: true, rename: false };
    match claim(&request) {
        Ok(Resolution::Claimed(c)) => {
            c.clear().map_err(|e| Failure::new(Kind::Write, format!("cannot remove the earlier {name} in {}: {e}", dir.display())))
        }
        Ok(Resolution::Skipped(why, s)) => Err(Failure::new(Kind::Write, format!("{}: {}", s.display(), why.reason()))),
        Err(e) => Err(Failure::new(Kind::Write, format!("cannot claim output names in {}: {e}", dir.display()))),
    }
}

/// Frame `k`'s outputs in `dir` (`frame_000042.jpg`, its maps and sidecar,
/// the sidecar last), through the one writing half of both commands.
#[allow(clippy::too_many_arguments)]
fn write_frame(
    opts: &Options,
    dir: &Path,
    k: usize,
    (w, h): (usize, usize),
    transfer: Transfer,
    bytes_per_sample: usize,
    res: &crate::method::params::Restoration,
    decision: Decision,
    timing: Timing,
) -> Result<String, Failure> {
    let name = format!("frame_{k:06}");
    others_at(dir, &name, k)?;
    let label = format!("stdin#{k}");
    let suffixes = crate::files::pipeline::output_suffixes(opts);
    let input = PathBuf::from(&label);
    let request = Request { dir, base: &name, input: &input, suffixes: &suffixes, overwrite: true, rename: false };
    let claimed = match claim(&request) {
        Ok(Resolution::Claimed(c)) => c,
        Ok(Resolution::Skipped(why, s)) => {
            return Err(Failure::new(Kind::Write, format!("{}: {}", s.display(), why.reason())))
        }
        Err(e) => return Err(Failure::new(Kind::Write, format!("cannot claim output names in {}: {e}", dir.display()))),
    };
    let source = Source {
        kind: "linear".into(),
        format: format!("raw {} {}", if bytes_per_sample == 2 { "rgb48le" } else { "rgb24" }, transfer.name()),
        bits: if bytes_per_sample == 2 { 16 } else { 8 },
        height: h,
        width: w,
        orientation: 1,
        linear: true,
        preprocess: Preprocess::None,
        processed_height: h,
        processed_width: w,
        icc_profile: None,
        camera_matrix: None,
        white_balance: None,
        notes: vec![format!("frame {k} of stdin; {} estimate", decision.name())],
    };
    let parameters = crate::files::sidecar::parameters(opts);
    let side = write_outputs(
        claimed,
        Outputs {
            label: &label,
            input: None,
            implementation: "rust",
            source: &source,
            estimates: Estimates::of(res),
            image: &res.image,
            transmission: &res.transmission,
            confidence: res.confidence.as_deref(),
            contact_sheet: None,
            reused: Some(res.flags.contains(&Flag::EstimatesReused)),
            parameters: &parameters,
        },
        opts,
        timing,
    )?;
    Ok(side.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that gives its bytes a few at a time.
    struct Trickle<'a>(&'a [u8]);

    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.0.len().min(buf.len()).min(5);
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn frames_are_read_whole_across_short_reads() {
        let data: Vec<u8> = (0..30).collect();
        let mut r = Trickle(&data);
        let mut buf = [0u8; 12];
        assert!(matches!(read_frame(&mut r, &mut buf), Ok(Got::Frame)));
        assert_eq!(buf.to_vec(), (0..12).collect::<Vec<u8>>());
        assert!(matches!(read_frame(&mut r, &mut buf), Ok(Got::Frame)));
        // 6 bytes left of a 12-byte frame: where it ended is said
        assert!(matches!(read_frame(&mut r, &mut buf), Ok(Got::Partial(6))));
        assert!(matches!(read_frame(&mut r, &mut buf), Ok(Got::End)));
    }
}
