"""Batches at survey scale: :func:`restore_many` runs every input of a
batch on a Dask cluster or in this process, with inputs and outputs on
local paths or fsspec URLs (``s3://``, ``gs://``, ...); ``uwhl restore``
is :func:`run_batch` in this process.

The outputs, their names and the sidecars are those of a local
``uwhl restore`` run (docs/OUTPUTS.md), written by the same code
(``tasks.begin``); what is particular to clusters and object storage
(resume, retries, memory per task, the sidecar as commit marker) is in
docs/SCALE.md.

Dask, distributed, fsspec, s3fs and pandas are the optional extra
``uwhl_rs[dask]``; they are imported only when a batch needs them.
"""

from __future__ import annotations

import contextlib
import os
import posixpath
import shutil
import sys
import tempfile
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field, replace

from . import _core, cluster
from .console import Console
from .errors import EXIT, BatchError
from .files import output_suffixes
from .inputs import GLOB_CHARS, collect_inputs, supported
from .outdir import CSV_COLUMNS, FILE_NAME, SummaryWriter, folder_done, stored_names
from .storage import (EXTRA, check_output_bucket, filesystem, is_url, join, local_path, need, parse_storage_options,
                      scheme, storage_error)
from .tasks import COLUMNS, Item, begin, context, row, scratch_root, skipped_row

__all__ = ["restore_many", "run_batch", "BatchResult", "BatchError", "parse_storage_options", "plan_batch", "EXTRA",
           "COLUMNS"]


# ------------------------------------------------------------------ planning


@dataclass
class Plan:
    """What :func:`plan_batch` found."""

    items: list[Item] = field(default_factory=list)
    #: (input, reason) of inputs that match nothing
    problems: list[tuple[str, str]] = field(default_factory=list)
    #: the items whose sidecar exists at the destination (skipped unless overwrite)
    done: set = field(default_factory=set)
    #: what the discovery has to say (earlier runs' output folders not searched)
    notes: list[str] = field(default_factory=list)


def _earlier_outputs(fs, root: str, files: list[str]) -> list[str]:
    """The folders under ``root`` (not ``root`` itself) that are an earlier
    run's output folder: their ``summary.csv`` begins with the summary's
    first six columns, as ``jobs::is_output_folder`` reads a local one (its
    first 4 KiB only)."""
    first = (",".join(CSV_COLUMNS[:6]) + ",").encode()
    out = []
    for f in files:
        d, name = posixpath.split(f)
        if name == FILE_NAME and d.rstrip("/") != root:
            try:
                if fs.cat_file(f, start=0, end=4096).startswith(first):
                    out.append(d.rstrip("/") + "/")
            except (OSError, ValueError):
                pass  # unreadable: not known to be one, searched as before
    return out


def _list_remote(inputs: list[str], out: str, storage_options: dict) -> tuple[list[tuple[str, str]], list, list]:
    """URL inputs as (url, folder relative to the output folder), in the
    order a local folder walk gives (sorted by path components, hidden
    entries skipped, the output folder and earlier runs' output folders
    never searched), the problems and the notes on the folders not searched."""
    found: list[tuple[str, str]] = []
    problems: list[tuple[str, str]] = []
    notes: list[str] = []
    out_key = out.rstrip("/") + "/"
    for url in inputs:
        fs, path = filesystem(url, storage_options)
        proto = url.split("://", 1)[0]

        def full(p: str) -> str:
            return fs.unstrip_protocol(p) if hasattr(fs, "unstrip_protocol") else f"{proto}://{p}"

        try:
            if GLOB_CHARS.search(path):
                hits = sorted(h for h in fs.glob(path) if supported(h) and fs.isfile(h))
                if not hits:
                    problems.append((url, "pattern matches no image file"))
                found += [(full(h), "") for h in hits]
            elif fs.isdir(path):
                root = path.rstrip("/")
                rels = []
                listed = fs.find(root)
                # the run's own output folder (a rerun finds its summary.csv) is skipped below, without a note
                same = is_url(out) and scheme(out) == scheme(url)
                own = filesystem(out, storage_options)[1].rstrip("/") + "/" if same else None
                earlier = [d for d in _earlier_outputs(fs, root, listed) if not (own and d.startswith(own))]
                notes += [f"{full(d.rstrip('/'))}: an output folder of an earlier restore (its summary.csv): not "
                          "searched; name its files to restore them" for d in earlier]
                for f in listed:
                    if any(f.startswith(d) for d in earlier):
                        continue
                    rel = f[len(root):].lstrip("/")
                    parts = rel.split("/")
                    if any(p.startswith(".") for p in parts) or not supported(rel):
                        continue
                    if full(f).startswith(out_key) or (own and f.startswith(own)):
                        continue
                    rels.append((tuple(parts), f))
                rels.sort()
                if not rels:
                    problems.append((url, "folder holds no JPEG, PNG, TIFF, raw or video file"))
                found += [(full(f), "/".join(parts[:-1])) for parts, f in rels]
            elif fs.isfile(path):
                found.append((url, ""))
            else:
                problems.append((url, "no such file or folder"))
        except BatchError:
            raise
        except FileNotFoundError:
            problems.append((url, "no such file or folder"))
        except Exception as e:  # the storage itself: credentials, endpoint, permissions
            raise storage_error(e, url) from None
    seen = set()
    unique = []
    for u, rel in found:
        if u not in seen:
            seen.add(u)
            unique.append((u, rel))
    return unique, problems, notes


def plan_batch(inputs: list[str], out: str, *, format: str = "jpg", contact: bool = False,
               storage_options: dict | None = None) -> Plan:
    """The inputs of a batch, named as a local run names them (the core's
    ``collect_jobs`` for local inputs; fsspec listings named by the same
    rules, ``_core.name_jobs``, for URLs), and which are already done (their
    sidecar exists at the destination)."""
    so = storage_options or {}
    suffixes = output_suffixes(format, contact)
    plan = Plan()
    local = [local_path(i) for i in inputs if not is_url(i)]
    remote = [i for i in inputs if is_url(i)]
    out_local = not is_url(out)
    if local:
        # named against the real output folder when it is local (the output
        # folder is never searched), else against a folder that cannot exist
        anchor = local_path(out) if out_local else os.path.join(tempfile.gettempdir(), f".uwhl-none-{os.getpid()}")
        jobs, problems, notes = collect_inputs(local, anchor, format, contact)
        plan.problems += problems
        plan.notes += notes
        for j in jobs:
            rel = os.path.relpath(j.out_dir, anchor)
            rel = "" if rel == "." else rel.replace(os.sep, "/")
            plan.items.append(Item(j.path, join(out if not out_local else anchor, rel), j.name))
    if remote:
        found, problems, notes = _list_remote(remote, out, so)
        plan.problems += problems
        plan.notes += notes
        names = _core.name_jobs([(u, rel) for u, rel in found], suffixes)
        base = local_path(out)
        plan.items += [Item(u, join(base, rel), n) for (u, rel), n in zip(found, names)]
    # what is done already: the sidecars at the destination that record
    # their input (in a folder, each input's claim decides the rest)
    done = []
    if out_local:
        done = folder_done(plan.items)
    elif plan.items:
        fs, root = filesystem(out, so)
        try:
            listing = fs.find(root.rstrip("/"), detail=True) if fs.exists(root.rstrip("/")) else {}
            existing = {p: i.get("size") if isinstance(i, dict) else None for p, i in listing.items()}
            done, refused = stored_names(plan.items, existing, so)
        except FileNotFoundError:
            refused = []
        except Exception as e:
            raise storage_error(e, out) from None
        plan.problems += [(it.input, why) for it, why in refused]
        plan.items = [it for it in plan.items if all(it is not r for r, _ in refused)]
    for k, it in enumerate(plan.items):
        it.index = k
    plan.done = {it.index for it in done}
    return plan


# ------------------------------------------------------------------ running


@dataclass
class BatchResult:
    """What :func:`run_batch` did."""

    #: one dict per input (:data:`COLUMNS`), inputs that match nothing first
    rows: list
    #: the number of inputs found
    total: int
    #: stopped by an interrupt (the rows say what was done)
    interrupted: bool = False
    #: why summary.csv could not be written, or None
    summary_error: str | None = None
    #: how many of the rows (the first) are inputs that match nothing
    problems: int = 0


def _earlier_summary(output: str, so, scratch: str, listener) -> None:
    """The destination's summary.csv copied into the scratch folder, so that
    the batch lists its earlier failures again as a local run does (the
    core reads the copy). One that cannot be read, or is over the size
    the core reads, is not copied (said)."""
    try:
        fs, root = filesystem(output, so)
        src = join(root, FILE_NAME)
        if not fs.exists(src):
            return
        size = int(fs.info(src).get("size") or 0)
        if size > _core.EARLIER_SUMMARY_BYTES:
            raise ValueError(f"it is over {_core.EARLIER_SUMMARY_BYTES >> 20} MiB")
        fs.get_file(src, os.path.join(scratch, FILE_NAME))
    except Exception as e:  # the store's own errors: the batch goes on, the earlier failures are not listed
        if listener is not None:
            listener.note(f"note: the earlier {FILE_NAME} of {output} is not read ({type(e).__name__}: {e}): "
                          "its failures are not listed again")


def run_batch(inputs: list[str], output: str, *, client=None, dask: str | None = None,
              storage_options: dict | None = None, overwrite: bool = False, reuse_estimates: int | None = None,
              reuse_water_mask: bool = False, options: dict | None = None, jobs: int = 1,
              listener=None) -> BatchResult:
    """The body of :func:`restore_many` and of ``uwhl restore``: every input
    planned, restored (on ``client`` or the cluster ``dask`` names, else in
    this process: with ``jobs`` 1, one input written while the next is
    restored; else ``jobs`` inputs at a time) and settled, each row added to
    summary.csv as it comes. An interrupt lets the input being written
    finish and stops the batch (``interrupted``).

    ``listener`` (the command's console) is told ``row(row, k, total)`` for
    each input settled (``k``: its place in name order, None for an input
    that matches nothing) and ``note(text)`` (the Dask dashboard's address)."""
    so = dict(storage_options or {})
    if any(is_url(p) for p in [*inputs, output]):
        need("fsspec")
    opts = dict(options or {})
    fmt, contact = opts.get("format", "jpg"), opts.get("contact", False)
    if not is_url(output):
        try:
            os.makedirs(local_path(output), exist_ok=True)
        except OSError:
            pass  # each input's claim then says why its outputs cannot be written
    else:
        check_output_bucket(output, so)
    plan = plan_batch(inputs, output, format=fmt, contact=contact, storage_options=so)
    for n in plan.notes if listener is not None else ():
        listener.note(f"note: {n}")
    total = len(plan.items)
    if not is_url(output):
        # what a killed run left in the output folders goes first
        for d in sorted({local_path(it.out_dir) for it in plan.items}):
            if os.path.isdir(d):
                _core.remove_stale_temps(d, local_path(output))
    problems = [row(Item(i, "", ""), "failed", error_kind="unreadable_input", error=why,
                    exit_code=EXIT["unreadable_input"], worker=None) for i, why in plan.problems]
    # summary.csv as the batch goes: in OUTDIR, or (object storage) in a
    # local file uploaded when the batch ends
    scratch = None if not is_url(output) else tempfile.mkdtemp(prefix="uwhl-summary-")
    if scratch is not None:
        _earlier_summary(output, so, scratch, listener)
    csv_rows = SummaryWriter(scratch or local_path(output),
                             waiting=(lambda t: listener.note(f"note: {t}")) if listener is not None else None)
    csv_rows.given([it.input for it in plan.items] + [r["input"] for r in problems])
    for r in problems:
        csv_rows.add(r)
        if listener is not None:
            listener.row(r, None, total)
    rows: dict[int, dict] = {}

    def settle(k: int, r: dict) -> None:
        rows[k] = r
        csv_rows.add(r)
        if listener is not None:
            listener.row(r, k + 1, total)

    interrupted = False
    summary_error = None
    c, started = None, None
    try:
        if client is None and dask is None:
            _run_here(plan.items, opts, so, overwrite, reuse_estimates, reuse_water_mask, jobs, settle,
                      set() if overwrite else plan.done, getattr(listener, "note", None))
        else:
            groups = _groups(plan, overwrite, reuse_estimates, settle)
            if groups:
                c, started, threads = cluster.connect(client, dask, opts.get("threads"))
                if threads is not None:
                    opts["threads"] = threads
                cluster.check_workers(c)
                if cluster.runs_elsewhere(c):
                    groups = _on_any_worker(groups, opts)
                if listener is not None:
                    listener.note(f"Dask dashboard: {c.dashboard_link}")
                cluster.run_on_cluster(c, groups, opts, so, overwrite, reuse_estimates, reuse_water_mask, settle)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if started is not None:
            c.close()
            started.close()
        csv_rows.close()
        for n in csv_rows.notes if listener is not None else ():
            listener.note(f"note: {n}")
        if scratch is not None:
            try:
                fs, root = filesystem(output, so)
                fs.put_file(csv_rows.path, join(root, FILE_NAME))
            except Exception as e:  # the outputs are stored; only the summary is lost
                summary_error = f"cannot upload {FILE_NAME} to {output}: {type(e).__name__}: {e}"
            shutil.rmtree(scratch, ignore_errors=True)
    summary_error = csv_rows.error or summary_error
    if csv_rows.read_only and not any(r.get("status") == "done" for r in rows.values()):
        # a rerun over a finished survey on a read-only mount: nothing was
        # to be written, and the earlier summary.csv still holds
        if listener is not None:
            listener.note(f"{summary_error} (read-only output folder: the earlier {FILE_NAME} stays)")
        summary_error = None
    return BatchResult(problems + [rows[k] for k in sorted(rows)], total, interrupted, summary_error,
                       len(problems))


#: options that name local files or folders (relative to the folder the command runs in)
PATH_OPTIONS = ("mask", "water_mask", "distance", "altitude", "water_from")


def _on_any_worker(groups: list[list[Item]], opts: dict) -> list[list[Item]]:
    """``groups`` and ``opts`` (in place) with every relative local path
    made absolute, for workers that run in another folder than this
    command, where ``-o out`` or ``--water-from cal`` would name other
    folders than the ones it checked and reports. ``--altitude`` is a path
    only when it names a file (else metres or ``xmp``)."""
    for k in PATH_OPTIONS:
        v = opts.get(k)
        if not isinstance(v, (str, os.PathLike)) or is_url(os.fspath(v)):
            continue
        if k != "altitude" or os.path.isfile(os.fspath(v)):
            opts[k] = os.path.abspath(os.fspath(v))

    def here(p: str) -> str:
        return p if is_url(p) else os.path.abspath(p)

    return [[replace(it, input=here(it.input), out_dir=here(it.out_dir)) for it in g] for g in groups]


def _groups(plan: Plan, overwrite: bool, reuse: int | None, settle) -> list[list[Item]]:
    """The cluster's tasks: an input each, or with ``reuse`` chunks of N in
    name order, each one sequence. What is done already is settled as
    skipped without a task (a chunk all done is skipped whole)."""
    size = reuse or 1
    groups = []
    for i in range(0, len(plan.items), size):
        ch = plan.items[i:i + size]
        if not overwrite and all(it.index in plan.done for it in ch):
            for it in ch:
                settle(it.index, dict(skipped_row(it, join(it.out_dir, it.name + ".json")), worker=None))
        else:
            groups.append(ch)
    return groups


def _run_here(items: list[Item], opts: dict, so: dict, overwrite: bool, reuse: int | None, reuse_water_mask: bool,
              jobs: int, settle, done: set, progress=None) -> None:
    """The batch in this process, one sequence over every input with
    ``reuse`` (as uwhl-rs runs it). With ``jobs`` 1, one input is written
    (the encoders release the GIL) while the next is read and restored (the
    core releases it), and inputs settle in order; on an interrupt the
    write in flight finishes (its files appear whole or not at all) and
    counts. Inputs in ``done`` whose outputs go to object storage are
    skipped from the plan's one listing, without a request each; local
    ones are skipped by their claim."""
    # a scratch folder only for copies of URL inputs and outputs bound for storage
    remote = any(is_url(it.input) or is_url(it.out_dir) for it in items)
    with tempfile.TemporaryDirectory(prefix="uwhl-run-", dir=scratch_root()) if remote \
            else contextlib.nullcontext("") as scratch:
        ctx = context(opts, so, overwrite, reuse, reuse_water_mask, scratch)
        ctx.progress = progress

        def start(it: Item):
            if it.index in done and is_url(it.out_dir):
                return skipped_row(it, join(it.out_dir, it.name + ".json"))
            return begin(it, ctx)

        if jobs == 1:
            with ThreadPoolExecutor(max_workers=1, thread_name_prefix="uwhl-write") as writer:
                pending = []  # (item, future of its write): the previous input

                def settle_pending() -> None:
                    while pending:
                        it, written = pending[0]
                        r = _result(written)  # an interrupt here leaves it pending
                        pending.pop()
                        settle(it.index, r)

                try:
                    for it in items:
                        step = start(it)
                        settle_pending()
                        if callable(step):
                            pending.append((it, writer.submit(step)))
                        else:
                            settle(it.index, step)
                        # the step holds its input's images: not past its write, into the next input's restore
                        del step
                    settle_pending()  # (here, so that an interrupt while the last input is written stops a video)
                except KeyboardInterrupt:
                    # a photo's write finishes; a video (minutes of frames) stops at its next frame
                    ctx.stop.set()
                    raise
                finally:
                    settle_pending()
            return

        def one(it: Item) -> dict:
            step = start(it)
            return step() if callable(step) else step

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(one, it): it for it in items}
            try:
                left = set(futures)
                while left:
                    # in slices: SIGINT delivered to a worker thread reaches the main thread only between waits
                    done_now, left = wait(left, timeout=_WAIT_SLICE, return_when=FIRST_COMPLETED)
                    for f in done_now:
                        settle(futures[f].index, f.result())
            except KeyboardInterrupt:
                ctx.stop.set()
                for f in futures:
                    f.cancel()
                raise


#: seconds the main thread waits on a write at a time: the kernel may deliver SIGINT to
#: any thread (a decoder's, the core's), and only a main thread that returns to Python now
#: and then runs the handler that stops the run (a wait without a timeout would sleep
#: through it until a video's last frame)
_WAIT_SLICE = 0.2


def _result(future):
    """``future``'s result, waited for in slices (:data:`_WAIT_SLICE`)."""
    while True:
        try:
            return future.result(timeout=_WAIT_SLICE)
        except TimeoutError:
            if future.done():
                raise  # the task's own TimeoutError


def restore_many(inputs, output: str, *, client=None, dask: str | None = None, storage_options: dict | None = None,
                 overwrite: bool = False, reuse_estimates: int | None = None, reuse_water_mask: bool = False,
                 progress: bool = False, **options):
    """Restore every input of a batch and write its outputs (docs/SCALE.md).

    ``inputs``: a path, URL or list of them: files, folders (searched
    recursively) and glob patterns; ``output``: a folder or URL. Outputs,
    names and sidecars are those of ``uwhl restore`` (docs/OUTPUTS.md).
    The work runs on ``client`` (a ``dask.distributed.Client``), on the
    cluster ``dask`` names (``"local:N"``: a local cluster of N worker
    processes, or a scheduler address), or, with neither, in this process.
    ``storage_options`` go to fsspec for every URL (also on the workers).

    Inputs whose sidecar exists at the destination are skipped unless
    ``overwrite``. With ``reuse_estimates=N`` the inputs (in name order)
    are restored as a sequence whose frames 0, N, 2N, ... estimate
    (``uwhl_rs.Sequence``): on a cluster, chunks of N, each one task. ``options``: the
    keywords of :func:`uwhl_rs.files.restore_file` (``format``,
    ``water_types``, ``max_side``, ``method``, ...). ``progress``: the
    command's progress lines on stderr.

    Returns a pandas DataFrame, one row per input in name order (columns
    :data:`COLUMNS`; inputs that match nothing first): ``status`` done /
    skipped / failed, the water type, A, flags, seconds, the output paths
    or URLs, and for a failure its kind, message and exit code
    (docs/CLI.md). Raises :class:`BatchError` when the batch cannot start.
    """
    (pd,) = need("pandas")
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [os.fspath(inputs)]
    inputs = [os.fspath(i) for i in inputs]
    output = os.fspath(output)
    # the command's lines, from the one place that writes them
    listener = Console(out=sys.stderr) if progress else None
    _core.new_run()  # a run reads its --water-from folder and navigation log once, as they are when it starts
    result = run_batch(inputs, output, client=client, dask=dask, storage_options=storage_options,
                       overwrite=overwrite, reuse_estimates=reuse_estimates, reuse_water_mask=reuse_water_mask,
                       listener=listener, options=options)
    if result.interrupted:
        raise KeyboardInterrupt
    return pd.DataFrame(result.rows, columns=COLUMNS)


