"""The ``uwhl`` command (also ``python -m uwhl_rs``).

``uwhl restore INPUT... -o OUTDIR`` restores files, folders (recursively)
and globs, writing per input the corrected photo, the transmission maps
and a JSON sidecar (docs/OUTPUTS.md), with a progress bar, a summary and a
non-zero exit status when any input failed. ``uwhl demo`` restores the
built-in synthetic scene.
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass

#: exit statuses
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

_EPILOG_RESTORE = """\
outputs (per input NAME, in OUTDIR, mirroring sub-folders of folder inputs):
  NAME.jpg|.tif|.png   the corrected photo (sRGB)
  NAME_t.png           transmission t_B, 16-bit gray (-ln t_B is a distance proxy)
  NAME_t_color.png     transmission, colour-mapped (dark = far, yellow = near)
  NAME_sheet.png       with --contact-sheet: every water type side by side
  NAME.json            sidecar: water type, scores, A, VL size, flags, parameters,
                       version, timings; written last, it marks the input as done
Inputs whose sidecar exists are skipped unless --overwrite, so an interrupted
run resumes where it stopped. Every file is written atomically.

exit status: 0 all inputs done or skipped; 1 at least one input failed (the
others are still processed); 2 bad arguments; 130 interrupted.

examples:
  uwhl restore dive_042/ -o corrected/ --jobs 2
  uwhl restore 'dive_*/**/*.NEF' -o out --format tiff --max-side 3000
  uwhl restore IMG_1620.CR2 -o out --water-type 3C --contact-sheet
"""


def _parse_size(text: str) -> int:
    """'8G', '512M', '1000000' -> bytes."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)i?[bB]?\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"not a size: {text!r} (examples: 8G, 512M, 1000000)")
    mult = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}[m.group(2).lower()]
    return int(float(m.group(1)) * mult)


def _int_at_least(lo: int):
    """An argparse type: an integer >= lo."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"must be at least {lo}, not {v}")
        return v

    return parse


_positive_int = _int_at_least(1)
_nonneg_int = _int_at_least(0)


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, not {text}")
    return v


def _subsample(text: str) -> int:
    """--guided-subsample: an integer >= 0 or "auto" (= 0)."""
    if text.strip() == "auto":
        return 0
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer >= 0 or auto: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0 or auto, not {v}")
    return v


def _veiling_light(text: str) -> tuple[float, float, float]:
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        v = tuple(float(p) for p in parts)
    except ValueError:
        v = ()
    if len(v) != 3 or not all(0 < x <= 1 for x in v):
        raise argparse.ArgumentTypeError(f"expected R,G,B with each value in (0, 1], not {text!r}")
    return v  # type: ignore[return-value]


def _water_types(values: list[str] | None):
    """--water-type values: names (comma lists allowed) or NAME:BETA_BR:BETA_BG."""
    import uwhl_rs

    if not values:
        return None
    out = []
    for v in values:
        for item in (x.strip() for x in v.split(",")):
            if not item:
                continue
            if ":" in item:
                parts = item.split(":")
                try:
                    out.append((parts[0], float(parts[1]), float(parts[2])))
                except (IndexError, ValueError):
                    raise ValueError(f"--water-type {item!r}: a custom type is NAME:BETA_BR:BETA_BG") from None
            elif item in uwhl_rs.WATER_TYPES:
                out.append(item)
            else:
                raise ValueError(
                    f"--water-type {item!r}: unknown; known types are {', '.join(uwhl_rs.WATER_TYPES)}"
                    " (or give NAME:BETA_BR:BETA_BG)"
                )
    return out


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``uwhl`` (all subcommands)."""
    import uwhl_rs

    p = argparse.ArgumentParser(
        prog="uwhl",
        description="Underwater single-image color restoration with haze-lines "
        "(Berman, Levy, Avidan & Treibitz, TPAMI 2020): corrected colors, a transmission "
        "(distance proxy) map and the Jerlov water type from a raw or JPEG photograph.",
        epilog="Run 'uwhl COMMAND --help' for a command's options.",
    )
    p.add_argument("--version", action="version", version=f"uwhl_rs {uwhl_rs.__version__}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")

    r = sub.add_parser(
        "restore",
        help="restore photographs (files, folders, globs) into an output folder",
        description="Restore underwater photographs: raw (NEF, CR2, ARW, DNG, ... anything LibRaw reads), "
        "JPEG, PNG or TIFF. Folders are searched recursively; quote globs to let uwhl expand them.",
        epilog=_EPILOG_RESTORE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    r.add_argument("inputs", nargs="+", metavar="INPUT", help="image files, folders or glob patterns")
    r.add_argument("-o", "--out", required=True, metavar="OUTDIR", help="output folder (created if needed)")
    g = r.add_argument_group("output")
    g.add_argument("--format", choices=["jpg", "tiff", "png"], default="jpg",
                   help="corrected photo as JPEG (default, 8-bit, quality 95), 16-bit TIFF, or PNG")
    g.add_argument("--bits", type=int, choices=[8, 16], default=None,
                   help="bits per sample for png/tiff (default: png 8, tiff 16)")
    g.add_argument("--quality", type=int, default=95, metavar="Q", help="JPEG quality 1-100 (default 95)")
    g.add_argument("--contact-sheet", action="store_true",
                   help="also write NAME_sheet.png: every water type's restoration side by side, "
                   "labelled with its score, the chosen one framed, the water region overlaid on the input")
    g.add_argument("--overwrite", action="store_true", help="redo inputs that already have a sidecar (default: skip them)")
    g = r.add_argument_group("input")
    g.add_argument("--preprocess", choices=["none", "reference"], default="none",
                   help="none (default): linear data, sRGB decoded through the inverse sRGB curve; "
                   "reference: the reference code's preprocessing of SPEC 2 (sRGB not linearised)")
    g.add_argument("--half-size", action="store_true", help="raw files: demosaic at half size (4x faster)")
    g.add_argument("--max-side", type=_positive_int, metavar="N",
                   help="shrink (block average) so the longer side is at most N before processing")
    g.add_argument("--max-pixels", type=_positive_int, default=300_000_000, metavar="N",
                   help="refuse images with more pixels (default 300000000)")
    g.add_argument("--mask", metavar="PATH",
                   help="image of the input's size: nonzero = use the pixel for estimation, "
                   "zero = ignore it (e.g. a color chart)")
    g.add_argument("--water-mask", metavar="PATH",
                   help="image of the input's size: nonzero = water region VL (replaces detection)")
    g = r.add_argument_group("method (defaults from SPEC.md)")
    g.add_argument("--water-type", action="append", metavar="TYPE",
                   help="candidate water type(s): names (I IA IB II III 1C 3C 5C 7C 9C), comma lists, "
                   "repeatable, or NAME:BETA_BR:BETA_BG; default all ten Jerlov types")
    g.add_argument("--veiling-light", type=_veiling_light, metavar="R,G,B",
                   help="a known veiling light A (linear, each in (0, 1]); default: estimated")
    g.add_argument("--selection", choices=["exhaustive", "fast"], default="exhaustive",
                   help="exhaustive (default): every water type restored and scored at full resolution; "
                   "fast: types scored on a ~1024 px copy, uncertain ones re-scored at full size")
    g.add_argument("--guided-radius", type=_nonneg_int, metavar="N", help="guided-filter radius (default min(H, W)/4)")
    g.add_argument("--guided-eps", type=_positive_float, default=1e-3, metavar="X", help="guided-filter eps (default 1e-3)")
    g.add_argument("--guided-subsample", type=_subsample, default=1, metavar="S|auto",
                   help="guided-filter subsampling: 1 (default) exact filter; S >= 2 fast guided filter "
                   "on S x S blocks (for video/sequences; t_B within ~4e-4 on average); "
                   "auto (= 0): max(1, radius / 32)")
    g.add_argument("--sphere-points", type=_positive_int, default=500, metavar="N", help="haze-line clusters (default 500)")
    g.add_argument("--reuse-estimates", type=_positive_int, metavar="N",
                   help="sequence mode for the frames of one video or dive (inputs in the order listed, "
                   "folders by name): choose the water type and estimate the veiling light on every N-th "
                   "restored input and reuse them for the ones in between (one type instead of ten); "
                   "needs --jobs 1")
    g.add_argument("--reuse-water-mask", action="store_true",
                   help="with --reuse-estimates: reuse the estimating input's water region too (a camera "
                   "that holds its attitude; skips the water detection)")
    g = r.add_argument_group("resources")
    g.add_argument("--jobs", "-j", type=_positive_int, default=1, metavar="N",
                   help="inputs processed at once (default 1): overlaps decoding and writing of one "
                   "input with the restoration of another")
    g.add_argument("--threads", type=_positive_int, metavar="N",
                   help="threads per restore (default: all cores, one pool shared by the jobs)")
    g.add_argument("--max-memory", type=_parse_size, metavar="BYTES",
                   help="working-memory limit per restore, e.g. 8G (default 16G)")
    g.add_argument("--quiet", "-q", action="store_true", help="no progress and no summary table; errors still shown")

    d = sub.add_parser(
        "demo",
        help="restore the built-in synthetic scene and print the true vs estimated water type",
        description="Render the package's synthetic underwater scene (nothing is downloaded), restore it, "
        "write input/restored/transmission/clean_truth PNGs and report true vs estimated water type and A.",
    )
    d.add_argument("-o", "--out", default="uwhl_demo", help="output folder (default: ./uwhl_demo)")
    d.add_argument("--water-type", default="III", choices=list(uwhl_rs.WATER_TYPES), help="water type to render (default III)")
    d.add_argument("--size", default="480x640", help="HxW of the scene (default 480x640)")
    d.add_argument("--seed", type=int, default=7, help="scene seed (default 7)")
    return p


# ------------------------------------------------------------------ inputs


@dataclass
class Job:
    """One input and where its outputs go."""

    path: str
    out_dir: str
    name: str


_GLOB_CHARS = re.compile(r"[*?\[]")


def _supported(path: str) -> bool:
    from .io import IMAGE_EXTENSIONS, RAW_EXTENSIONS

    ext = os.path.splitext(path)[1].lower()
    return ext in IMAGE_EXTENSIONS or ext in RAW_EXTENSIONS


def collect_inputs(inputs: list[str], out_dir: str) -> tuple[list[Job], list[tuple[str, str]]]:
    """Expand files, folders (recursive) and globs into jobs.

    Returns (jobs, problems): problems are (input, reason) for inputs that
    match nothing. Files under ``out_dir`` are never taken as inputs; the
    same file named twice is processed once; two inputs that would share
    an output name get ``NAME_ext`` (then ``NAME_ext_2``, ... if still shared).
    """
    out_real = os.path.realpath(out_dir)
    found: list[tuple[str, str]] = []  # (file, output sub-folder)
    problems = []
    for item in inputs:
        if os.path.isdir(item):
            n0 = len(found)
            for root, dirs, files in os.walk(item):
                dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                                 and os.path.realpath(os.path.join(root, d)) != out_real)
                for f in sorted(files):
                    if f.startswith(".") or not _supported(f):
                        continue
                    rel = os.path.relpath(root, item)
                    found.append((os.path.join(root, f), "" if rel == "." else rel))
            if len(found) == n0:
                problems.append((item, "folder holds no JPEG, PNG, TIFF or raw file"))
        elif os.path.exists(item):
            found.append((item, ""))
        elif _GLOB_CHARS.search(item):
            hits = sorted(h for h in glob.glob(item, recursive=True) if os.path.isfile(h) and _supported(h))
            if not hits:
                problems.append((item, "pattern matches no image file"))
            found.extend((h, "") for h in hits)
        else:
            problems.append((item, "no such file or folder"))
    seen = set()
    unique = []
    for path, sub in found:
        real = os.path.realpath(path)
        if real in seen or real.startswith(out_real + os.sep):
            continue
        seen.add(real)
        unique.append((path, sub))
    stems: dict[tuple[str, str], int] = {}
    for path, sub in unique:
        key = (sub, os.path.splitext(os.path.basename(path))[0])
        stems[key] = stems.get(key, 0) + 1
    jobs = []
    taken: set[tuple[str, str]] = set()
    for path, sub in unique:
        stem, ext = os.path.splitext(os.path.basename(path))
        name = stem if stems[(sub, stem)] == 1 else f"{stem}_{ext.lstrip('.').lower()}"
        base, k = name, 1
        while (sub, name) in taken:  # same stem and extension from two folders
            k += 1
            name = f"{base}_{k}"
        taken.add((sub, name))
        jobs.append(Job(path, os.path.join(out_dir, sub), name))
    return jobs, problems


# ---------------------------------------------------------------- progress


class Progress:
    """A one-line progress bar on a terminal, plain log lines otherwise."""

    def __init__(self, total: int, stream=None, quiet: bool = False):
        self.total, self.done, self.t0 = total, 0, time.perf_counter()
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.quiet = quiet
        self.lock = threading.Lock()
        self.current = ""

    def _eta(self) -> str:
        el = time.perf_counter() - self.t0
        if self.done == 0:
            return "--:--"
        rest = el / self.done * (self.total - self.done)
        return f"{int(rest // 60):d}:{int(rest % 60):02d}"

    def _rate(self) -> float:
        el = time.perf_counter() - self.t0
        return self.done / el if el > 0 else 0.0

    def start(self, name: str) -> None:
        with self.lock:
            self.current = name
            if self.tty and not self.quiet:
                self._draw()

    def _draw(self) -> None:
        width = 28
        fill = int(width * self.done / max(1, self.total))
        line = (f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} "
                f"{self._rate():.2f} files/s ETA {self._eta()}  {self.current[:40]}")
        self.stream.write(line.ljust(110)[:110])
        self.stream.flush()

    def finish(self, message: str, error: bool = False) -> None:
        """One input finished; ``message`` is logged (errors always)."""
        with self.lock:
            self.done += 1
            if self.tty:
                if error or not self.quiet:
                    self.stream.write("\r" + " " * 110 + "\r")
                if error:
                    self.stream.write(message + "\n")
                if not self.quiet:
                    self._draw()
            elif error or not self.quiet:
                self.stream.write(f"[{self.done}/{self.total}] {message}\n")
            self.stream.flush()

    def close(self) -> None:
        if self.tty and not self.quiet:
            self.stream.write("\n")
            self.stream.flush()


# ------------------------------------------------------------------ restore


@dataclass
class Outcome:
    """The result line of one input."""

    job: Job
    status: str  # "ok" | "skipped" | "failed"
    water_type: str = ""
    seconds: float = 0.0
    note: str = ""


def _describe(e: BaseException) -> str:
    if isinstance(e, MemoryError):
        return f"over the memory budget: {e}"
    if isinstance(e, OSError) and e.strerror:
        return f"{e.strerror}" + (f": {e.filename}" if e.filename else "")
    return str(e) or type(e).__name__


def run_restore(a: argparse.Namespace, out=None, err=None) -> int:
    """``uwhl restore``: returns the exit status."""
    import uwhl_rs

    from . import files

    out = out or sys.stdout
    err = err or sys.stderr
    try:
        water_types = _water_types(a.water_type)
    except ValueError as e:
        err.write(f"uwhl restore: error: {e}\n")
        return EXIT_USAGE
    if a.format == "jpg" and a.bits == 16:
        err.write("uwhl restore: error: --bits 16 needs --format png or tiff (JPEG holds 8 bits)\n")
        return EXIT_USAGE
    for flag, path in (("--mask", a.mask), ("--water-mask", a.water_mask)):
        if path is not None and not os.path.isfile(path):
            err.write(f"uwhl restore: error: {flag} {path}: no such file\n")
            return EXIT_USAGE
    if a.reuse_water_mask and a.reuse_estimates is None:
        err.write("uwhl restore: error: --reuse-water-mask needs --reuse-estimates N\n")
        return EXIT_USAGE
    if a.reuse_estimates is not None and a.jobs != 1:
        err.write("uwhl restore: error: --reuse-estimates restores the inputs in order; it needs --jobs 1\n")
        return EXIT_USAGE
    jobs, problems = collect_inputs(a.inputs, a.out)
    for item, why in problems:
        err.write(f"uwhl: {item}: {why}\n")
    if not jobs:
        err.write("uwhl restore: nothing to do\n")
        return EXIT_FAILED
    # threads=None: every job works in the one global pool; a fixed count
    # per job would make concurrent jobs queue on one cached pool
    threads = a.threads
    kwargs = dict(
        format=a.format,
        bits=a.bits,
        quality=a.quality,
        preprocess=a.preprocess,
        half_size=a.half_size,
        max_side=a.max_side,
        max_pixels=a.max_pixels,
        mask=a.mask,
        water_mask=a.water_mask,
        contact=a.contact_sheet,
        water_types=water_types,
        veiling_light=a.veiling_light,
        guided_radius=a.guided_radius,
        guided_eps=a.guided_eps,
        guided_subsample=a.guided_subsample,
        sphere_points=a.sphere_points,
        selection=a.selection,
        threads=threads,
    )
    if a.max_memory is not None:
        kwargs["max_memory"] = a.max_memory
    if a.reuse_estimates is not None:
        method = {k: kwargs[k] for k in files.METHOD_KEYS if k in kwargs}
        try:
            kwargs["sequence"] = uwhl_rs.Sequence(
                refresh_every=a.reuse_estimates, reuse_water_mask=a.reuse_water_mask, **method
            )
        except uwhl_rs.UwhlError as e:
            err.write(f"uwhl restore: error: {e}\n")
            return EXIT_USAGE
    progress = Progress(len(jobs), err, a.quiet)
    outcomes: list[Outcome] = []

    def begin(job: Job):
        """Reads and restores ``job``. Returns the function that settles it
        (prints its progress line, returns its Outcome) given the result of
        the function that writes it, and that writer (None when there is
        nothing to write: skipped or failed)."""
        sidecar = files.output_paths(job.out_dir, job.name, a.format)["sidecar"]
        if not a.overwrite and os.path.exists(sidecar):
            def skipped(_=None) -> Outcome:
                progress.finish(f"{job.path}: skipped, already done")
                return Outcome(job, "skipped", note="already done (sidecar exists; --overwrite redoes it)")
            return skipped, None
        progress.start(os.path.basename(job.path))
        t0 = time.perf_counter()

        def settle(result) -> Outcome:
            if isinstance(result, BaseException):
                o = Outcome(job, "failed", seconds=time.perf_counter() - t0, note=_describe(result))
                progress.finish(f"uwhl: {job.path}: FAILED: {o.note}", error=True)
                return o
            dt = time.perf_counter() - t0
            flags = ", ".join(result.restoration.flags)
            o = Outcome(job, "ok", result.restoration.water_type, dt, flags)
            progress.finish(f"{job.path}: {o.water_type} in {dt:.2f} s" + (f" ({flags})" if flags else ""))
            return o

        try:
            write = files._restore_staged(job.path, job.out_dir, name=job.name, **kwargs)
        except (Exception, MemoryError) as e:  # one bad file never stops the batch
            return settle, (lambda failure=e: failure)

        def finish():
            try:
                return write()
            except (Exception, MemoryError) as e:
                return e

        return settle, finish

    def one(job: Job) -> Outcome:
        settle, finish = begin(job)
        return settle(finish() if finish else None)

    interrupted = False
    try:
        if a.jobs == 1:
            # one input is written (encoders release the GIL) while the next
            # is read and restored (the core releases it); lines stay in order
            with ThreadPoolExecutor(max_workers=1, thread_name_prefix="uwhl-write") as writer:
                pending = []  # (settle, future of the write) of the previous input

                def settle_pending() -> None:
                    while pending:
                        settle, written = pending[0]
                        result = written.result()  # an interrupt here leaves it pending
                        pending.pop()
                        outcomes.append(settle(result))

                try:
                    for job in jobs:
                        settle, finish = begin(job)
                        settle_pending()
                        if finish is None:
                            outcomes.append(settle())
                        else:
                            pending.append((settle, writer.submit(finish)))
                finally:
                    # also on an interrupt: the write in flight finishes (its
                    # files appear whole or not at all) and counts
                    settle_pending()
        else:
            with ThreadPoolExecutor(max_workers=a.jobs) as pool:
                futures = {pool.submit(one, j): j for j in jobs}
                try:
                    for f in as_completed(futures):
                        outcomes.append(f.result())
                except KeyboardInterrupt:
                    for f in futures:
                        f.cancel()
                    raise
    except KeyboardInterrupt:
        interrupted = True
    progress.close()
    order = {id(j): k for k, j in enumerate(jobs)}
    outcomes.sort(key=lambda o: order[id(o.job)])
    # inputs that matched nothing count as failed in the summary too
    outcomes = [Outcome(Job(item, "", ""), "failed", note=why) for item, why in problems] + outcomes
    failed = [o for o in outcomes if o.status == "failed"]
    if not a.quiet:
        _summary(outcomes, out, time.perf_counter() - progress.t0)
    if interrupted:
        err.write(f"uwhl: interrupted after {len(outcomes)} of {len(jobs)} inputs; "
                  "run the same command again to resume\n")
        return EXIT_INTERRUPTED
    if failed:
        err.write(f"uwhl: {len(failed)} input(s) failed\n")
        return EXIT_FAILED
    return EXIT_OK


def _summary(outcomes: list[Outcome], out, total: float) -> None:
    if not outcomes:
        return
    w = min(48, max(len(os.path.basename(o.job.path)) for o in outcomes))
    out.write(f"\n{'input':<{w}}  {'status':<7}  {'type':<5}  {'seconds':>7}  note\n")
    for o in outcomes:
        secs = f"{o.seconds:7.2f}" if o.status != "skipped" else "      -"
        out.write(f"{os.path.basename(o.job.path)[:w]:<{w}}  {o.status:<7}  {o.water_type:<5}  {secs}  {o.note}\n")
    n = {s: sum(o.status == s for o in outcomes) for s in ("ok", "skipped", "failed")}
    out.write(f"{n['ok']} done, {n['skipped']} skipped, {n['failed']} failed in {total:.1f} s\n")
    out.flush()


# --------------------------------------------------------------------- demo


def run_demo(out_dir: str, water_type: str, size: tuple[int, int], seed: int) -> int:
    """``uwhl demo``: render, restore and report the built-in scene."""
    import numpy as np

    import uwhl_rs
    from uwhl_rs import synth
    from uwhl_rs.io import colorize_transmission, write_image

    h, w = size
    image, truth = synth.demo_input(h, w, water_type=water_type, seed=seed)
    t0 = time.perf_counter()
    res = uwhl_rs.restore(image)
    dt = time.perf_counter() - t0
    os.makedirs(out_dir, exist_ok=True)
    write_image(os.path.join(out_dir, "input.png"), image, encoding="linear")
    write_image(os.path.join(out_dir, "restored.png"), res.image, encoding="linear")
    write_image(os.path.join(out_dir, "transmission.png"), colorize_transmission(res.transmission))
    write_image(os.path.join(out_dir, "clean_truth.png"), truth["clean"], encoding="linear")
    z = truth["distance"]
    ok = np.isfinite(z)
    rho = float(np.corrcoef(z[ok], -np.log(res.transmission[ok]))[0, 1])
    ranking = sorted(res.scores, key=res.scores.get)
    print(f"uwhl_rs {uwhl_rs.__version__}: built-in synthetic scene {w}x{h}, seed {seed}")
    print(f"true water type:      {truth['water_type']}")
    print(f"estimated water type: {res.water_type}   (types by gray-world score: {' '.join(ranking)};"
          f" excluded by the t_R rule: {', '.join(res.excluded) or 'none'})")
    print(f"veiling light A: true {tuple(round(v, 4) for v in truth['veiling_light'])},"
          f" estimated {tuple(round(v, 4) for v in res.veiling_light)}")
    print(f"water region: {res.veiling_mask.mean():.1%} of the image; flags: {res.flags or 'none'}")
    print(f"rho(true distance, -ln t_B) = {rho:.3f}")
    print(f"restore took {dt:.3f} s; wrote input.png, restored.png, transmission.png, clean_truth.png to {out_dir}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``uwhl`` command; returns the exit status."""
    p = build_parser()
    a = p.parse_args(argv)
    if a.cmd == "demo":
        try:
            h, w = (int(v) for v in a.size.lower().split("x"))
        except ValueError:
            p.error(f"--size must look like 480x640, not {a.size!r}")
        if h < 4 or w < 4:
            p.error(f"--size must be at least 4x4, not {a.size!r}")
        return run_demo(a.out, a.water_type, (h, w), a.seed)
    return run_restore(a)
