"""``uwhl restore INPUT... -o OUTDIR``: every input restored into OUTDIR by
the one batch loop (``uwhl_rs.batch.run_batch``: in this process, or on
a Dask cluster with ``--dask``, with inputs and outputs on local paths or
storage URLs), then the report and the iFDO when asked for."""

from __future__ import annotations

import argparse
import os
import time

import uwhl_rs

from .. import _core, batch, files, tasks
from ..errors import CommandError, UwhlError
from ..ifdo import load_header
from ..images import DEFAULT_MAX_PIXELS
from ..storage import is_url, parse_storage_options
from . import ifdo as ifdo_command
from . import report as report_command
from ..console import Console
from .parser import file_kwargs, water_types

__all__ = ["run"]


def _bad(message: str) -> CommandError:
    return CommandError(message, "bad_arguments")


def _check(a: argparse.Namespace, options: dict) -> None:
    """What is refused before any input is read."""
    try:
        _core.check_combination(a.format, a.bits, a.reuse_estimates, a.reuse_water_mask, False, a.preprocess)
    except ValueError as e:
        raise _bad(str(e)) from None
    if options.get("water_types") is not None:
        # the core's check of the list (a type listed twice, a custom type's betas), once, as the binary's parser
        # does: not a failure of every input
        try:
            _core.Params(water_types=options["water_types"])
        except UwhlError as e:
            raise _bad(f"--water-type: {e}") from None
    # this run reads its --water-from folder and navigation log once, from here (a process may serve many)
    _core.new_run()
    try:
        _core.check_water(a.water_from is not None, bool(a.water_types))
    except ValueError as e:
        raise _bad(str(e)) from None
    if a.water_from is not None:
        try:
            _core.FileSettings(water_from=a.water_from)
        except UwhlError as e:
            raise _bad(str(e)) from None
    try:
        _core.check_distance(a.distance is not None, a.altitude is not None, a.fov is not None,
                             a.reuse_estimates is not None, getattr(a, "distance_kind", "range") == "depth",
                             a.port is not None)
    except ValueError as e:
        raise _bad(str(e)) from None
    if a.altitude is not None:
        # a navigation log read and checked once, before any input (its line and column named)
        try:
            _core.FileSettings(altitude=a.altitude)
        except UwhlError as e:
            raise _bad(str(e)) from None
    for flag, path in (("--mask", a.mask), ("--water-mask", a.water_mask)):
        if path is not None and not os.path.isfile(path):
            # a FIFO or a device would block or never end: it is not opened
            why = "not a regular file (not opened)" if os.path.exists(path) else "no such file"
            raise _bad(f"{flag} {path}: {why}")
        if path is not None:
            # decoded once before any input, as the binary reads its masks: a mask that cannot be
            # read is the command's error, not one line per input with a folder of failed rows
            try:
                _core.decode_mask_file(os.fspath(path), flag, int(options.get("max_pixels") or DEFAULT_MAX_PIXELS),
                                       int(options.get("max_memory") or _core.default_max_memory()))
            except MemoryError as e:
                raise CommandError(str(e), "over_budget") from None
            except UwhlError as e:
                raise _bad(str(e)) from None
    if a.reuse_estimates is not None:
        # the sequence's keywords checked once here, not by every input
        method = {k: options[k] for k in files.METHOD_KEYS if k in options}
        try:
            uwhl_rs.Sequence(refresh_every=a.reuse_estimates, reuse_water_mask=a.reuse_water_mask, **method)
        except UwhlError as e:
            raise _bad(str(e)) from None


def run(a: argparse.Namespace, console: Console) -> int:
    """``uwhl restore``: the exit status, the largest of its inputs' codes."""
    options = file_kwargs(a, water_types(a.water_types))
    _check(a, options)
    header = load_header(a.ifdo) if a.ifdo is not None else None
    if a.water_from is not None:
        # the sidecars of the dive's folder that gave no fit, once, before any input (as uwhl-rs)
        for n in _core.FileSettings(water_from=a.water_from).dive_water_notes:
            console.note(f"note: {n}")
    # a given water meets a distance: which photos it is for (as uwhl-rs)
    note = _core.water_with_distance_note(a.water_from is not None, a.water_types is not None,
                                          a.distance is not None, a.altitude is not None)
    if note:
        console.note(f"note: {note}")
    # a run of photos only (every input a file that is no video) ignores --transfer: said once
    videos = any(not os.path.isfile(p) or os.path.splitext(p)[1].lower().lstrip(".") in _core.VIDEO_EXTENSIONS
                 for p in a.inputs)
    if (note := _core.transfer_note(a.transfer is not None, videos)) is not None:
        console.note(f"note: {note}")
    so: dict = {}
    if a.dask is not None or any(is_url(p) for p in [*a.inputs, a.out]):
        if a.jobs != 1:
            raise _bad("--jobs is for runs in this process; on a cluster (--dask) every worker takes one input at "
                       "a time per thread")
        so = parse_storage_options(a.storage_option)
    elif a.storage_option:
        raise _bad("--storage-option is for URL inputs or outputs (s3://, gs://, ...) and --dask")
    elif a.reuse_estimates is not None and a.jobs != 1:
        raise _bad("--reuse-estimates restores the inputs in order; it needs --jobs 1")
    # the options a sidecar records, for the line of an input skipped because an earlier run restored it
    console.options = {k: v for k, v in options.items() if k not in tasks.VIDEO_KEYS}
    from ..videofiles import given_video_options

    console.video_options = given_video_options(options)
    if not is_url(a.out):
        # a file at the output's name would fail every input, and summary.csv, one by one (as uwhl-rs)
        why = _core.outdir_problem(a.out)
        if why:
            raise CommandError(why, "write_failed", a.out)
        try:
            # made now (held by the run from its start: docs/OUTPUTS.md); one that cannot be made is one error
            os.makedirs(a.out, exist_ok=True)
        except OSError as e:
            raise CommandError(f"cannot make the output folder: {e.strerror or e}", "write_failed", a.out) from None
    t0 = time.perf_counter()
    # "_flags": each input's errors name the options as this command's flags (--max-memory), as uwhl-rs does
    result = batch.run_batch(a.inputs, a.out, dask=a.dask, storage_options=so, overwrite=a.overwrite,
                             reuse_estimates=a.reuse_estimates, reuse_water_mask=a.reuse_water_mask,
                             options={**options, "_flags": True}, jobs=a.jobs, listener=console)
    if not result.rows and not result.interrupted:
        console.note("nothing to do", always=True)
        return 0
    code = max((int(r["exit_code"] or 0) for r in result.rows), default=0)
    if result.summary_error:
        code = max(code, console.error("write_failed", result.summary_error))
    console.summary(result.rows, time.perf_counter() - t0)
    if result.interrupted:
        raise CommandError(f"interrupted after {len(result.rows) - result.problems} of {result.total} inputs; "
                           "run the same command again to resume", "interrupted")
    console.failed_count(sum(r["status"] == "failed" for r in result.rows))
    # the report and the iFDO of what is there, each failing alone
    if a.report:
        try:
            report_command.write(a.out, console, so or None)
        except (Exception, MemoryError) as e:
            code = max(code, console.failure(e))
    if header is not None:
        try:
            ifdo_command.write(a.out, header, console, file_format=ifdo_command.file_format(a.ifdo),
                               storage_options=so or None, refused="write_failed")
        except (Exception, MemoryError) as e:
            code = max(code, console.failure(e))
    return code
