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

from . import _core

#: exit statuses, shared with uwhl-rs (docs/CLI.md): {name: code}
EXIT = {name: code for code, name, _ in _core.EXIT_CODES}
EXIT_OK, EXIT_USAGE, EXIT_INTERRUPTED = EXIT["ok"], EXIT["bad_arguments"], EXIT["interrupted"]

_EPILOG_RESTORE = _core.EXIT_CODES_HELP + """

outputs (per input NAME, in OUTDIR, mirroring sub-folders of folder inputs):
  NAME.jpg|.tif|.png   the corrected photo (sRGB)
  NAME_t.png           transmission t_B, 16-bit gray (-ln t_B is a distance proxy)
  NAME_t_color.png     transmission, colour-mapped (dark = far, yellow = near)
  NAME_sheet.png       with --contact-sheet: every water type side by side
  NAME.json            sidecar: water type, scores, A, VL size, flags, parameters,
                       version, timings; written last, it marks the input as done
Inputs whose sidecar exists are skipped unless --overwrite, so an interrupted
run resumes where it stopped. Every file is written atomically.

examples:
  uwhl restore dive_042/ -o corrected/ --jobs 2
  uwhl restore 'dive_*/**/*.NEF' -o out --format tiff --max-side 3000
  uwhl restore IMG_1620.CR2 -o out --water-type 3C --contact-sheet
"""


def _option_type(key: str):
    """An argparse type: the core's parser of option ``key`` (the one uwhl-rs uses)."""

    def parse(text: str):
        try:
            return _core.parse_option(key, text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e).split(": ", 1)[-1]) from None

    return parse


def _add_options(parser: argparse.ArgumentParser, method_only: bool = False) -> None:
    """The options of the core's table that the Python command takes,
    grouped (``method_only``: those of the method, for ``uwhl evaluate``)."""
    groups: dict[str, argparse._ArgumentGroup] = {}
    for o in _core.OPTIONS:
        if o["faces"] == "rust" or (method_only and not o["method"]):
            continue
        g = groups.get(o["group"]) or groups.setdefault(o["group"], parser.add_argument_group(o["group"]))
        names = [o["flag"]] + ([o["short"]] if o["short"] else [])
        kw = dict(dest=o["key"], help=o["help"].replace("%", "%%"))
        if o["kind"] == "flag":
            kw["action"] = "store_true"
        elif o["kind"] == "water_types":
            kw.update(action="append", metavar=o["metavar"])
        elif o["kind"] == "key_value":
            kw.update(action="append", metavar=o["metavar"], type=_option_type(o["key"]))
        else:
            kw.update(type=_option_type(o["key"]), metavar=o["metavar"], default=o["default"])
        g.add_argument(*names, **kw)


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
    r.add_argument("-o", "--out", "--output", dest="out", required=True, metavar="OUTDIR",
                   help="output folder (created if needed)")
    _add_options(r)

    d = sub.add_parser(
        "demo",
        help="restore the built-in synthetic scene and print the true vs estimated water type",
        description="Render the package's synthetic underwater scene (nothing is downloaded), restore it, "
        "write input/restored/transmission/clean_truth PNGs and report true vs estimated water type and A.",
    )
    d.add_argument("-o", "--out", "--output", dest="out", default="uwhl_demo", help="output folder (default: ./uwhl_demo)")
    d.add_argument("--water-type", default="III", choices=list(uwhl_rs.WATER_TYPES), help="water type to render (default III)")
    d.add_argument("--size", default="480x640", help="HxW of the scene (default 480x640)")
    d.add_argument("--seed", type=int, default=7, help="scene seed (default 7)")

    rp = sub.add_parser(
        "report",
        help="one page for a batch: thumbnails, water types, the sequence, flagged photos first",
        description="Write OUTDIR/report/index.html from the sidecars under OUTDIR (docs/REPORT.md): the "
        "flagged photos first, a histogram of the water types, water type, A and score over the sequence, and a "
        "paginated grid of before/after thumbnails (written once into OUTDIR/report/thumbs) that open the "
        "full-size photo and its transmission map.",
    )
    rp.add_argument("out", metavar="OUTDIR", help="an output folder (or URL) of uwhl restore or uwhl-rs restore")
    rp.add_argument("--storage-option", action="append", default=[], metavar="KEY=VALUE",
                    help="an fsspec option for a URL OUTDIR, as for restore")
    rp.add_argument("--json-errors", action="store_true", help="each error as one JSON object on stderr")
    rp.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")

    fd = sub.add_parser(
        "ifdo",
        help="the iFDO file of a batch (image FAIR Digital Objects) for marine imaging platforms",
        description="Write OUTDIR/ifdo.yaml from the sidecars under OUTDIR (docs/OUTPUTS.md \"iFDO\"): the set's "
        "header (the fields of --header, the rest derived), one item per corrected photo (its image UUID, "
        "SHA-256, handle, UTC time and GPS position) and the restoration as the set's provenance.",
    )
    fd.add_argument("out", metavar="OUTDIR", help="an output folder (or URL) of uwhl restore or uwhl-rs restore")
    fd.add_argument("--header", required=True, metavar="HEADER",
                    help="YAML or JSON file of the set's iFDO fields: image-project, image-event, image-platform, "
                    "image-sensor, image-pi, image-creators, image-license, image-copyright, image-abstract, "
                    "image-context, image-coordinate-uncertainty-meters (and any other header field)")
    fd.add_argument("--handle-base", metavar="URL",
                    help="the URL the folder is published under: each photo's image-handle is it joined with "
                    "the photo's path (default: the photos' own file:// or object-storage URLs)")
    fd.add_argument("--format", choices=("yaml", "json"), default=None,
                    help="ifdo.yaml or ifdo.json (default: the kind of the header file)")
    fd.add_argument("--storage-option", action="append", default=[], metavar="KEY=VALUE",
                    help="an fsspec option for a URL OUTDIR, as for restore")
    fd.add_argument("--json-errors", action="store_true", help="each error as one JSON object on stderr")
    fd.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")

    e = sub.add_parser(
        "evaluate",
        help="the paper's colour and distance metrics on annotated photos, beside baselines",
        description="Evaluate the method on the photos of a manifest (docs/EVALUATE.md): the mean angle of "
        "chart gray patches from gray (psi-bar), rho of -ln t against distance maps, the water type against "
        "a known one; beside every other profile (--method), the input, a contrast stretch, gray world and "
        "every candidate type. Writes "
        "results.json, results.csv and report.html.",
    )
    e.add_argument("manifest", metavar="MANIFEST", help="the manifest (JSON; paths relative to it)")
    e.add_argument("-o", "--out", "--output", dest="out", required=True, metavar="OUTDIR",
                   help="output folder (created if needed)")
    e.add_argument("--mask-charts", action="store_true",
                   help="exclude the charts' regions from estimation (the mask of restore), as the paper does")
    e.add_argument("--json-errors", action="store_true", help="each error as one JSON object on stderr")
    e.add_argument("-q", "--quiet", action="store_true", help="no progress lines and no summary")
    _add_options(e, method_only=True)
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


def collect_inputs(inputs: list[str], out_dir: str, fmt: str = "jpg",
                   contact: bool = False) -> tuple[list[Job], list[tuple[str, str]]]:
    """Expand files, folders (recursive) and globs into jobs.

    Glob patterns are expanded here; the rest is the core's one discovery
    and naming, which uwhl-rs uses too (``_core.collect_jobs``): files under
    ``out_dir`` are never taken as inputs, the same file named twice is
    processed once, and two inputs that would share an output name get
    ``NAME_ext`` (then ``NAME_ext_2``, ... if still shared), and no output
    file of one input (``fmt``, ``contact``) is another's. Returns (jobs,
    problems): problems are (input, reason) for inputs that match nothing.
    """
    items: list[str] = []
    problems: list[tuple[str, str]] = []
    for item in inputs:
        if not os.path.exists(item) and _GLOB_CHARS.search(item):
            hits = sorted(h for h in glob.glob(item, recursive=True) if os.path.isfile(h) and _supported(h))
            if not hits:
                problems.append((item, "pattern matches no image file"))
            items.extend(hits)
        else:
            items.append(item)
    from .files import output_suffixes

    found, missing = _core.collect_jobs(items, out_dir, output_suffixes(fmt, contact))
    problems += [(str(p), why) for p, why in missing]
    return [Job(str(p), str(d), name) for p, d, name in found], problems


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

    def finish(self, message: str, error: bool = False, report=None) -> None:
        """One input finished: ``message`` is its progress line; an error
        is reported by ``report()`` (always, also with --quiet)."""
        with self.lock:
            self.done += 1
            if self.tty and (error or not self.quiet):
                self.stream.write("\r" + " " * 110 + "\r")
            if error:
                self.stream.flush()
                report()
            elif not self.quiet and not self.tty:
                self.stream.write(f"[{self.done}/{self.total}] {message}\n")
            if self.tty and not self.quiet:
                self._draw()
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
    code: int = 0  # the exit code of this input (docs/CLI.md)


def _describe(e: BaseException, path: str | None = None) -> str:
    """The message of a failure; the input's path is said once, by the
    line that reports it, so a leading ``path: `` is left out."""
    if isinstance(e, MemoryError):
        return f"over the memory budget: {e}"
    if isinstance(e, OSError) and e.strerror:
        return f"{e.strerror}" + (f": {e.filename}" if e.filename else "")
    text = str(e) or type(e).__name__
    if path is not None and text.startswith(f"{path}: "):
        text = text[len(path) + 2:]
    return text


def _error_kind(e: BaseException, writing: bool) -> str:
    """The kind of a failure, as uwhl-rs classifies it (docs/CLI.md)."""
    import uwhl_rs
    from .io import ImageReadError, ImageTooLargeError

    if isinstance(e, (MemoryError, ImageTooLargeError)):
        return "over_budget"
    if isinstance(e, (ImageReadError, uwhl_rs.ImageError)):
        return "unreadable_input"
    if isinstance(e, uwhl_rs.ParameterError):
        return "bad_arguments"
    if isinstance(e, OSError):
        return "write_failed" if writing else "unreadable_input"
    return "internal"


def _report(err, json_errors: bool, item: str | None, kind: str, message: str) -> None:
    """One error line on stderr: ``uwhl: INPUT: MESSAGE`` or, with
    --json-errors, the JSON object uwhl-rs writes."""
    if json_errors:
        import json

        err.write(json.dumps({"error": kind, "input": item, "message": message, "exit_code": EXIT[kind]}) + "\n")
    else:
        err.write(f"uwhl: {item}: {message}\n" if item is not None else f"uwhl: {message}\n")
    err.flush()


_BAD = object()


def _water_types_or_report(a: argparse.Namespace, err):
    """The parsed --water-type values, or ``_BAD`` after reporting why not."""
    try:
        return _water_types(a.water_types)
    except ValueError as e:
        _report(err, a.json_errors, None, "bad_arguments", str(e))
        return _BAD


def run_restore(a: argparse.Namespace, out=None, err=None) -> int:
    """``uwhl restore``: returns the exit status."""
    import uwhl_rs

    from . import files

    out = out or sys.stdout
    err = err or sys.stderr
    water_types = _water_types_or_report(a, err)
    if water_types is _BAD:
        return EXIT_USAGE
    try:
        _core.check_combination(a.format, a.bits, a.reuse_estimates, a.reuse_water_mask, False, a.preprocess)
    except ValueError as e:
        _report(err, a.json_errors, None, "bad_arguments", str(e))
        return EXIT_USAGE
    for flag, path in (("--mask", a.mask), ("--water-mask", a.water_mask)):
        if path is not None and not os.path.isfile(path):
            _report(err, a.json_errors, None, "bad_arguments", f"{flag} {path}: no such file")
            return EXIT_USAGE
    a.ifdo_header = None
    if a.ifdo is not None:
        from . import ifdo

        try:
            a.ifdo_header = ifdo.load_header(a.ifdo)
        except ifdo.IfdoError as e:
            _report(err, a.json_errors, None, "bad_arguments", str(e))
            return EXIT_USAGE
    from . import batch

    if a.dask is not None or any(batch.is_url(p) for p in [*a.inputs, a.out]):
        return _run_batch(a, water_types, out, err)
    if a.storage_option:
        _report(err, a.json_errors, None, "bad_arguments",
                "--storage-option is for URL inputs or outputs (s3://, gs://, ...) and --dask")
        return EXIT_USAGE
    if a.reuse_estimates is not None and a.jobs != 1:
        _report(err, a.json_errors, None, "bad_arguments",
                "--reuse-estimates restores the inputs in order; it needs --jobs 1")
        return EXIT_USAGE
    jobs, problems = collect_inputs(a.inputs, a.out, a.format, a.contact_sheet)
    from .summary import SummaryWriter, row_fields_from_sidecar

    # OUTDIR/summary.csv, a row per input as it is settled (made with the first row)
    csv_rows = SummaryWriter(a.out)
    for item, why in problems:
        _report(err, a.json_errors, item, "unreadable_input", why)
        csv_rows.add({"input": item, "status": "failed", "error_kind": "unreadable_input", "error": why,
                      "exit_code": EXIT["unreadable_input"]})
    if not jobs:
        csv_rows.close()
        if csv_rows.error:
            _report(err, a.json_errors, None, "write_failed", csv_rows.error)
        if problems:
            return EXIT["unreadable_input"]
        err.write("uwhl: nothing to do\n")
        return EXIT_OK
    # what a killed run left in the output folders goes first
    for d in sorted({j.out_dir for j in jobs}):
        _core.remove_stale_temps(d)
    # threads=None (no --threads): every job works in the one global pool; a
    # fixed count per job would make concurrent jobs queue on one cached pool
    kwargs = _file_kwargs(a, water_types)
    # --max-memory bounds the process's peak: what it holds before the
    # first input (the interpreter, numpy, the codecs, imported now so that
    # they are counted here and not while the first input is written) counts
    import imageio.v3  # noqa: F401
    import tifffile  # noqa: F401
    from PIL import Image  # noqa: F401

    # (and 4 MiB for the three writer threads' stacks and allocator arenas)
    kwargs["_base"] = _core.process_base() + (4 << 20)
    if a.reuse_estimates is not None:
        method = {k: kwargs[k] for k in files.METHOD_KEYS if k in kwargs}
        try:
            kwargs["sequence"] = uwhl_rs.Sequence(
                refresh_every=a.reuse_estimates, reuse_water_mask=a.reuse_water_mask, **method
            )
        except uwhl_rs.UwhlError as e:
            _report(err, a.json_errors, None, "bad_arguments", str(e))
            return EXIT_USAGE
    progress = Progress(len(jobs), err, a.quiet)
    outcomes: list[Outcome] = []

    def begin(job: Job):
        """Reads and restores ``job``. Returns the function that settles it
        (prints its progress line, returns its Outcome) given the result of
        the function that writes it, and that writer (None when there is
        nothing to write: skipped or failed)."""
        try:
            status, sidecar, reason, claim = files.claim_outputs(job.out_dir, job.name, job.path, a.format,
                                                                 a.contact_sheet, overwrite=a.overwrite, rename=True)
        except OSError as e:
            failure = ("write_failed", OSError(e.errno, f"cannot claim output names in {job.out_dir}: {e}"))

            def settle_claim(result=failure) -> Outcome:
                kind, e = result
                o = Outcome(job, "failed", note=_describe(e, job.path), code=EXIT[kind])
                csv_rows.add({"input": job.path, "status": "failed", "error_kind": kind, "error": o.note,
                              "exit_code": o.code})
                progress.finish(f"{job.path}: {o.note}", error=True,
                                report=lambda: _report(err, a.json_errors, job.path, kind, o.note))
                return o
            return settle_claim, None
        if status != "claimed":
            # the core's reason, as uwhl-rs prints it; a done input names its sidecar
            why = f"{sidecar} exists" if status == "done" else reason
            note = "already done (sidecar exists; --overwrite redoes it)" if status == "done" else reason

            def skipped(_=None) -> Outcome:
                csv_rows.add({"input": job.path, "status": "skipped", "error": note, "exit_code": 0,
                              "sidecar": str(sidecar)})
                progress.finish(f"{job.path}: skipped ({why})")
                return Outcome(job, "skipped", note=note)
            return skipped, None
        progress.start(os.path.basename(job.path))
        t0 = time.perf_counter()

        def settle(result) -> Outcome:
            if isinstance(result, tuple):  # (kind, exception)
                kind, e = result
                o = Outcome(job, "failed", seconds=time.perf_counter() - t0, note=_describe(e, job.path), code=EXIT[kind])
                csv_rows.add({"input": job.path, "status": "failed", "error_kind": kind, "error": o.note,
                              "exit_code": o.code, "seconds": round(o.seconds, 4)})
                progress.finish(f"{job.path}: {o.note}", error=True,
                                report=lambda: _report(err, a.json_errors, job.path, kind, o.note))
                return o
            dt = time.perf_counter() - t0
            o = Outcome(job, "ok", result.restoration.water_type, dt, ", ".join(result.restoration.flags))
            csv_rows.add({"input": job.path, "status": "done", **row_fields_from_sidecar(result.sidecar),
                          "seconds": round(dt, 4), "exit_code": 0, **result.paths})
            progress.finish(f"{job.path} -> {result.paths['image']} (water type {o.water_type}, {dt:.2f} s)")
            return o

        try:
            write = files._restore_staged(job.path, job.out_dir, name=job.name, _claim=claim, **kwargs)
        except (Exception, MemoryError) as e:  # one bad file never stops the batch
            return settle, (lambda failure=(_error_kind(e, False), e): failure)

        def finish():
            try:
                return write()
            except (Exception, MemoryError) as e:
                return _error_kind(e, True), e

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
    finally:
        csv_rows.close()
    progress.close()
    order = {id(j): k for k, j in enumerate(jobs)}
    outcomes.sort(key=lambda o: order[id(o.job)])
    # inputs that matched nothing count as failed in the summary too
    outcomes = [Outcome(Job(item, "", ""), "failed", note=why, code=EXIT["unreadable_input"])
                for item, why in problems] + outcomes
    if not a.quiet:
        _summary(outcomes, out, time.perf_counter() - progress.t0)
    if interrupted:
        _report(err, a.json_errors, None, "interrupted",
                f"interrupted after {len(outcomes) - len(problems)} of {len(jobs)} inputs; "
                "run the same command again to resume")
        return EXIT_INTERRUPTED
    return _batch_end(a, outcomes, csv_rows.error, out, err)


def _batch_end(a: argparse.Namespace, outcomes: list, summary_error: str | None, out, err) -> int:
    """The end of a batch that was not interrupted, for both paths: the
    failures counted, summary.csv's trouble reported, the report written;
    the exit status."""
    failed = [o for o in outcomes if o.status == "failed"]
    if failed and not a.json_errors:
        err.write(f"uwhl: {len(failed)} input(s) failed\n")
    code = max((o.code for o in outcomes), default=EXIT_OK)
    if summary_error:
        _report(err, a.json_errors, None, "write_failed", summary_error)
        code = max(code, EXIT["write_failed"])
    if a.report:
        code = max(code, run_report(a.out, a.quiet, out, err, storage_options=getattr(a, "storage_options", None),
                                    json_errors=a.json_errors))
    if getattr(a, "ifdo_header", None) is not None:
        fmt = "json" if a.ifdo.lower().endswith(".json") else "yaml"
        code = max(code, run_ifdo(a.out, a.ifdo_header, file_format=fmt, storage_options=getattr(a, "storage_options", None),
                                  quiet=a.quiet, json_errors=a.json_errors, out=out, err=err))
    return code


def _run_batch(a: argparse.Namespace, water_types, out, err) -> int:
    """``uwhl restore`` on a Dask cluster (``--dask``) or with URL inputs or
    outputs: ``uwhl_rs.batch`` (docs/SCALE.md), with the local run's
    progress, summary and exit codes."""
    from . import batch

    if a.jobs != 1:
        _report(err, a.json_errors, None, "bad_arguments",
                "--jobs is for runs in this process; on a cluster (--dask) every worker takes one input at a time "
                "per thread")
        return EXIT_USAGE
    try:
        so = batch.parse_storage_options(a.storage_option)
    except ValueError as e:
        _report(err, a.json_errors, None, "bad_arguments", str(e))
        return EXIT_USAGE
    a.storage_options = so
    options = _file_kwargs(a, water_types)
    progress = Progress(0, err, a.quiet)
    t0 = time.perf_counter()

    def announce(text: str) -> None:
        if not a.quiet:
            err.write(f"uwhl: {text}\n")
            err.flush()

    try:
        result = batch.run_batch(a.inputs, a.out, dask=a.dask, storage_options=so, overwrite=a.overwrite,
                                 reuse_estimates=a.reuse_estimates, reuse_water_mask=a.reuse_water_mask,
                                 bar=batch._Bar(progress, err, a.json_errors), options=options, announce=announce)
    except batch.BatchError as e:
        _report(err, a.json_errors, None, e.kind, str(e))
        return EXIT[e.kind]
    except KeyboardInterrupt:
        _report(err, a.json_errors, None, "interrupted", "interrupted; run the same command again to resume")
        return EXIT_INTERRUPTED
    progress.close()
    if not result.rows and not result.interrupted:
        err.write("uwhl: nothing to do\n")
        return EXIT_OK
    status = {"done": "ok", "skipped": "skipped", "failed": "failed"}
    outcomes = [Outcome(Job(r["input"], "", ""), status[r["status"]], r["water_type"] or "", r["seconds"] or 0.0,
                        (r["flags"] or "") if r["status"] == "done" else (r["error"] or ""), int(r["exit_code"] or 0))
                for r in result.rows]
    if not a.quiet:
        _summary(outcomes, out, time.perf_counter() - t0)
    if result.interrupted:
        _report(err, a.json_errors, None, "interrupted",
                f"interrupted after {len(result.rows)} of {result.total} inputs; run the same command again to resume")
        return EXIT_INTERRUPTED
    return _batch_end(a, outcomes, result.summary_error, out, err)


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
    print(f"estimated water type: {res.water_type}   (types by score, best first: {' '.join(ranking)};"
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
    if a.cmd == "evaluate":
        return run_evaluate(a)
    if a.cmd == "report":
        return _run_report_command(a)
    if a.cmd == "ifdo":
        return _run_ifdo_command(a)
    return run_restore(a)


def run_ifdo(out_dir: str, header, *, handle_base: str | None = None, file_format: str | None = None,
             storage_options: dict | None = None, quiet: bool = False, json_errors: bool = False,
             out=None, err=None) -> int:
    """``uwhl ifdo OUTDIR`` (and ``restore --ifdo``): writes the folder's
    iFDO (``uwhl_rs.ifdo``); returns the exit status."""
    from . import batch, ifdo

    out = out or sys.stdout
    err = err or sys.stderr
    if not batch.is_url(out_dir) and not os.path.isdir(out_dir):
        _report(err, json_errors, out_dir, "unreadable_input", "no such folder")
        return EXIT["unreadable_input"]
    try:
        done = ifdo.write_ifdo(out_dir, header, handle_base=handle_base, file_format=file_format,
                               storage_options=storage_options)
    except ifdo.IfdoError as e:
        _report(err, json_errors, out_dir, "bad_arguments", f"no iFDO written: {e}")
        return EXIT_USAGE
    except batch.BatchError as e:
        _report(err, json_errors, out_dir, e.kind, f"cannot write the iFDO: {e}")
        return EXIT[e.kind]
    except OSError as e:
        _report(err, json_errors, out_dir, "write_failed", f"cannot write the iFDO: {_describe(e)}")
        return EXIT["write_failed"]
    if not quiet:
        out.write(f"ifdo: {done['path']} ({done['items']} photos)\n")
        for n in done["notes"][:20]:
            out.write(f"  note: {n}\n")
        if len(done["notes"]) > 20:
            out.write(f"  ... and {len(done['notes']) - 20} more notes\n")
        out.flush()
    return EXIT_OK


def run_report(out_dir: str, quiet: bool = False, out=None, err=None, *, storage_options: dict | None = None,
               json_errors: bool = False) -> int:
    """``uwhl report OUTDIR`` (and ``--report``; OUTDIR a folder or a
    storage URL): returns the exit status."""
    from . import batch, report

    out = out or sys.stdout
    err = err or sys.stderr
    if not batch.is_url(out_dir) and not os.path.isdir(out_dir):
        _report(err, json_errors, out_dir, "unreadable_input", "no such folder")
        return EXIT["unreadable_input"]
    try:
        done = report.write_report(out_dir, storage_options=storage_options)
    except batch.BatchError as e:
        _report(err, json_errors, out_dir, e.kind, f"cannot write the report: {e}")
        return EXIT[e.kind]
    except FileNotFoundError:
        _report(err, json_errors, out_dir, "unreadable_input", "no such folder")
        return EXIT["unreadable_input"]
    except OSError as e:
        _report(err, json_errors, out_dir, "write_failed", f"cannot write the report: {_describe(e)}")
        return EXIT["write_failed"]
    if not quiet:
        out.write(f"report: {done['path']} ({done['photos']} photos, {done['flagged']} flagged, {done['failed']} failed, "
                  f"{done['thumbnails_written']} thumbnails written, {done['seconds']:.1f} s)\n")
        for p in done["problems"][:20]:
            out.write(f"  note: {p}\n")
        out.flush()
    return EXIT_OK


def _run_report_command(a: argparse.Namespace) -> int:
    from . import batch

    try:
        so = batch.parse_storage_options(a.storage_option)
    except ValueError as e:
        _report(sys.stderr, a.json_errors, None, "bad_arguments", str(e))
        return EXIT_USAGE
    return run_report(a.out, a.quiet, storage_options=so or None, json_errors=a.json_errors)


def _run_ifdo_command(a: argparse.Namespace) -> int:
    from . import batch, ifdo

    err = sys.stderr
    try:
        so = batch.parse_storage_options(a.storage_option)
        header = ifdo.load_header(a.header)
    except ValueError as e:  # IfdoError is one
        _report(err, a.json_errors, None, "bad_arguments", str(e))
        return EXIT_USAGE
    fmt = a.format or ("json" if a.header.lower().endswith(".json") else "yaml")
    return run_ifdo(a.out, header, handle_base=a.handle_base, file_format=fmt, storage_options=so or None,
                    quiet=a.quiet, json_errors=a.json_errors)


def _file_kwargs(a: argparse.Namespace, water_types) -> dict:
    """The keywords of ``files.restore_file`` that ``uwhl restore``'s flags
    give (``max_memory`` only when given: the default follows the machine
    that restores)."""
    kw = dict(format=a.format, bits=a.bits, quality=a.quality, preprocess=a.preprocess, half_size=a.half_size,
              max_side=a.max_side, max_pixels=a.max_pixels, mask=a.mask, water_mask=a.water_mask,
              contact=a.contact_sheet, water_types=water_types, **_method_kwargs(a, skip=("max_memory",)))
    if a.max_memory is not None:
        kw["max_memory"] = a.max_memory
    return kw


def _method_kwargs(a: argparse.Namespace, skip=()) -> dict:
    """The method's keywords of ``restore`` as parsed from the option
    table's flags (``water_types`` is parsed apart), less those in ``skip``."""
    return {o["key"]: getattr(a, o["key"]) for o in _core.OPTIONS
            if o["method"] and o["faces"] != "rust" and o["key"] not in ("water_types", *skip)}


def run_evaluate(a: argparse.Namespace, out=None, err=None) -> int:
    """``uwhl evaluate``: returns the exit status (docs/CLI.md's codes)."""
    from . import evaluate as ev

    out = out or sys.stdout
    err = err or sys.stderr
    water_types = _water_types_or_report(a, err)
    if water_types is _BAD:
        return EXIT_USAGE
    kwargs = {k: v for k, v in _method_kwargs(a, skip=("method",)).items() if v is not None}
    if water_types is not None:
        kwargs["water_types"] = water_types
    try:
        entries, problems = ev.load_manifest(a.manifest)
    except ev.ManifestError as e:
        _report(err, a.json_errors, a.manifest, "unreadable_input", str(e))
        return EXIT["unreadable_input"]
    code = EXIT_OK
    for p in problems:
        _report(err, a.json_errors, a.manifest, "unreadable_input", p)
        code = max(code, EXIT["unreadable_input"])
    results = []
    t0 = time.perf_counter()
    for k, entry in enumerate(entries, 1):
        t = time.perf_counter()
        try:
            r = ev.evaluate_entry(entry, a.method, a.mask_charts, **kwargs)
        except (Exception, MemoryError) as e:
            kind = "unreadable_input" if isinstance(e, ev.ManifestError) else _error_kind(e, False)
            _report(err, a.json_errors, entry.label, kind, _describe(e, entry.path))
            problems.append(f"{entry.label}: {_describe(e, entry.path)}")
            code = max(code, EXIT[kind])
            continue
        results.append(r)
        if not a.quiet:
            psi = [row["psi_deg"] for row in r["charts"] if row["method"] == a.method]
            rho = r["rho"].get(a.method, {}).get("rho_B")
            out.write(f"[{k}/{len(entries)}] {entry.label}: water type {r['water_type']}"
                      + (f", psi-bar {', '.join(f'{v:.1f}' for v in psi if v is not None)} deg" if psi else "")
                      + (f", rho {rho:.3f}" if rho is not None else "") + f" ({time.perf_counter() - t:.1f} s)\n")
            out.flush()
    try:
        import uwhl_rs

        parameters = {"method": a.method, "mask_charts": a.mask_charts,
                      **{k: v if not isinstance(v, tuple) else list(v) for k, v in kwargs.items()},
                      "profiles": {m: uwhl_rs.method_steps(**({**kwargs, "method": m} if m == a.method else {"method": m}))
                                   for m in ev.METHODS}}
        doc = ev.write_results(a.out, a.manifest, results, problems, parameters)
        ev.write_report(a.out, doc, results, entries, a.method, ev.METHODS)
    except OSError as e:
        _report(err, a.json_errors, a.out, "write_failed", _describe(e))
        return EXIT["write_failed"]
    if not a.quiet:
        out.write(f"\n{'method':<12} {'psi-bar':>8} {'rho t_B':>8}\n")
        for m, v in doc["summary"].items():
            if m == "water_type":
                continue
            out.write(f"{m:<12} {ev._fmt(v['psi_deg']):>8} {ev._fmt(v['rho_B']):>8}\n")
        if "water_type" in doc["summary"]:
            for m, wt in doc["summary"]["water_type"].items():
                out.write(f"water type ({m}): {wt['exact']:.0%} exact, {wt['within_one']:.0%} within one step\n")
        out.write(f"{len(results)} of {len(entries)} images evaluated in {time.perf_counter() - t0:.1f} s; "
                  f"{os.path.join(a.out, 'report.html')}\n")
    return code
