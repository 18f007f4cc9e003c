"""One input of a batch, from claim to row: the per-input step that every
way of running a batch shares (in this process, overlapped or on threads,
and as Dask tasks), and the row that says what became of the input
(docs/SCALE.md, docs/OUTPUTS.md "summary.csv").

An input's outputs are written by ``files`` as a local run writes them;
on object storage they are written into a local scratch folder, then
uploaded, the sidecar last (the commit marker).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import uwhl_rs

from . import _core, files, video
from .errors import EXIT, CommandError, ImageReadError, UwhlError, describe, kind_of
from .images import DEFAULT_MAX_PIXELS, read_image
from .outdir import remove_earlier, row_fields_from_sidecar, sidecar_seconds
from .storage import download, filesystem, is_url, join, local_path

__all__ = ["COLUMNS", "MEMORY", "DONE_NOTE", "Item", "Context", "MemoryGate", "GateShare", "begin", "restore_items", "probe", "worker", "row"]

#: the Dask worker resource a task asks for: bytes of its memory plan
MEMORY = "MEMORY"

#: the options of videos and sequences (the photos' restore_file does not take them)
VIDEO_KEYS = ("every", "video_codec", "video_quality", "transfer", "scene_cut", "smoothing")

#: header bytes fetched from object storage to plan an input's memory
_HEADER_BYTES = 1 << 18

#: a row's columns, in order (``restore_many``'s DataFrame)
COLUMNS = ["input", "status", "water_type", "A_R", "A_G", "A_B", "flags", "veil_excess", "fallback_share", "seconds",
           "image", "transmission",
           "transmission_color", "confidence", "contact_sheet", "sidecar", "reused_estimates", "error_kind", "error", "exit_code",
           "worker", "scores", "taken_at", "latitude", "longitude", "altitude"]

#: the note of an input skipped because its sidecar exists (uwhl-rs's words)
DONE_NOTE = "already done (sidecar exists; --overwrite redoes it)"


@dataclass
class Item:
    """One input of a batch: where it is, where its outputs go, its name."""

    input: str
    out_dir: str
    name: str
    #: index in name order (the order of the batch)
    index: int = 0
    #: bytes of its memory plan, once known (None: not planned)
    need: int | None = None


# ------------------------------------------------------------------ rows


def worker():
    """The Dask worker running this task, or None (in this process)."""
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):
        return None


def scratch_root() -> str:
    """Where a task keeps its local copies: the worker's own folder, or the
    system's temporary folder."""
    w = worker()
    root = getattr(w, "local_directory", None) if w is not None else None
    return root or tempfile.gettempdir()


def row(item: Item, status: str, **kw) -> dict:
    """An input's row: every column, ``status`` done / skipped / failed."""
    r = {c: None for c in COLUMNS}
    r.update(input=item.input, status=status)
    w = worker()
    r["worker"] = w.address if w is not None else f"{socket.gethostname()}:{os.getpid()}"
    r.update(kw)
    return r


def failure_row(item: Item, e: BaseException, writing: bool, seconds: float | None,
                local_copy: str | None = None) -> dict:
    """The row of an input that failed with ``e`` (while writing its
    outputs, or before); a local copy's path is said as the input's."""
    kind = kind_of(e, writing)
    text = describe(e, local_copy or item.input)
    if local_copy and local_copy != item.input:
        text = text.replace(local_copy, item.input)
    return row(item, "failed", error_kind=kind, error=text, exit_code=EXIT[kind],
               seconds=None if seconds is None else round(seconds, 4))


def skipped_row(item: Item, sidecar: str, note: str = DONE_NOTE) -> dict:
    """The row of an input skipped (its sidecar exists, or ``note`` says why)."""
    return row(item, "skipped", error=note, exit_code=0, sidecar=str(sidecar))


def _done_row(item: Item, result, seconds: float, outputs: dict) -> dict:
    return row(item, "done", **row_fields_from_sidecar(result.sidecar), seconds=sidecar_seconds(result.sidecar, seconds),
               exit_code=0,
               reused_estimates=result.sidecar.get("reused_estimates"),
               **{role: outputs.get(role) for role in ("image", "transmission", "transmission_color",
                                                        "confidence", "contact_sheet", "sidecar")})


# ------------------------------------------------------------------ storage


def _stored(kind: str, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` on object storage; the storage client's own
    errors (which are neither the package's nor OSErrors) as a failure of
    ``kind``, with the client's message."""
    try:
        return fn(*args, **kwargs)
    except (UwhlError, OSError, MemoryError):
        raise
    except Exception as e:
        raise CommandError(str(e) or type(e).__name__, kind) from e


def fetch(url: str, scratch: str, storage_options: dict, header: bool = False) -> str:
    """A local copy of ``url`` in ``scratch`` under its own base name (so
    the contact sheet and the readers see the same name and extension);
    ``header``: only its first bytes."""
    fs, path = filesystem(url, storage_options)
    local = os.path.join(scratch, os.path.basename(path))

    def get():
        if header:
            with open(local, "wb") as f:
                f.write(fs.cat_file(path, start=0, end=_HEADER_BYTES))
        else:
            download(url, local, storage_options)

    try:
        _stored("unreadable_input", get)
    except FileNotFoundError:
        raise FileNotFoundError(2, "No such file or folder", url) from None
    return local


def _local_input(item: Item, ctx: "Context") -> str:
    """``item``'s input as a local file: the file itself, or a copy of a URL
    in a scratch folder of its own. Two inputs of one name in different
    folders of a listing are fetched while the one before is still being
    written (its hash and metadata read from its copy): a shared folder
    would let one overwrite or remove the other's copy."""
    if not is_url(item.input):
        return local_path(item.input)
    d = os.path.join(ctx.scratch, f"in{item.index}")
    os.makedirs(d, exist_ok=True)
    return fetch(item.input, d, ctx.storage_options)


def _publish(files_written: dict, item: Item, storage_options: dict, overwrite: bool) -> dict:
    """Uploads an input's outputs to object storage, the sidecar last: the
    sidecar is the commit marker (docs/SCALE.md). An earlier sidecar goes
    first (with what it lists that this run does not write), so that no
    sidecar ever lists outputs of another attempt."""
    fs, _ = filesystem(item.out_dir, storage_options)
    dest = {role: join(item.out_dir, os.path.basename(p)) for role, p in files_written.items()}
    side = filesystem(dest["sidecar"], storage_options)[1]
    if overwrite:
        remove_earlier(fs, side, dest, storage_options)
    for role, p in files_written.items():
        if role != "sidecar":
            fs.put_file(p, filesystem(dest[role], storage_options)[1])
    fs.put_file(files_written["sidecar"], side)
    return dest


def _drop_copy(item: Item, p: str | None) -> None:
    """Removes ``p`` (``item``'s input from :func:`_local_input`) with its folder, if it is a copy."""
    if p is not None and p != local_path(item.input):
        with contextlib.suppress(OSError):
            os.unlink(p)
            os.rmdir(os.path.dirname(p))


# ------------------------------------------------------------------ the step


@dataclass
class Context:
    """What every input of one run (or one task) shares."""

    opts: dict
    storage_options: dict
    overwrite: bool
    #: the scratch folder (local copies, outputs bound for object storage)
    scratch: str
    #: the ``uwhl_rs.Sequence`` of ``--reuse-estimates``, or None
    sequence: object = None
    #: what the process holds anyway, counted in every input's memory check
    base: int = 0
    #: --reuse-estimates N (a video's own schedule of estimates), None without
    reuse: int | None = None
    reuse_water_mask: bool = False
    #: called with a line of a long input's progress (a video's frames), or None
    progress: Callable[[str], None] | None = None
    #: set on an interrupt: a video being restored stops at its next frame (a photo's write finishes)
    stop: threading.Event = field(default_factory=threading.Event)
    #: the inputs of a run (or a task) in this process share its memory (:class:`MemoryGate`)
    gate: MemoryGate | None = None


class MemoryGate:
    """The memory a run's inputs hold at once, within its budget: an input
    restored while the previous one is written, or the inputs of ``--jobs``
    restored side by side, each wait (after reading their header, before
    decoding) until the others' plans leave room for theirs, as the
    binary's reader waits for its writer. An input alone always goes: its
    own plan was checked against the whole budget."""

    def __init__(self, budget: int, stop: threading.Event | None = None):
        self.budget = int(budget)
        self.held = 0
        #: set on an interrupt: an input waiting for room is not restored then
        self.stop = stop
        self._cv = threading.Condition()

    def try_reserve(self, need: int) -> bool:
        """Holds ``need`` bytes if they fit beside what is held (or nothing
        is), without waiting; whether it did."""
        with self._cv:
            if self.held > 0 and self.held + need > self.budget:
                return False
            self.held += need
        return True

    def reserve(self, need: int) -> int:
        """Waits until ``need`` bytes fit beside what is held (or nothing
        is), then holds them; returns ``need``, for :meth:`release`."""
        with self._cv:
            while self.held > 0 and self.held + need > self.budget:
                if self.stop is not None and self.stop.is_set():
                    raise KeyboardInterrupt  # the run stops: no input waiting for room starts
                self._cv.wait(0.2)  # in slices: an interrupt reaches the main thread between waits
            self.held += need
        return need

    def release(self, n: int) -> None:
        """Gives back ``n`` bytes of :meth:`reserve`."""
        if n:
            with self._cv:
                self.held -= n
                self._cv.notify_all()

    def share(self) -> "GateShare":
        """One input's share of the gate (what ``restore_staged``'s ``_make_room`` takes)."""
        return GateShare(self)


class GateShare:
    """What one input holds of a :class:`MemoryGate`: it reserves once and
    gives back what it holds, once, whatever path the input took."""

    def __init__(self, gate: MemoryGate):
        self.gate = gate
        self.held = 0

    def try_reserve(self, need: int) -> bool:
        """:meth:`MemoryGate.try_reserve`, remembered."""
        if self.gate.try_reserve(need):
            self.held = need
            return True
        return False

    def reserve(self, need: int) -> None:
        """:meth:`MemoryGate.reserve`, remembered."""
        self.held = self.gate.reserve(need)

    def release(self) -> None:
        """Gives back what is held (nothing the second time)."""
        self.gate.release(self.held)
        self.held = 0


def context(opts: dict, storage_options: dict, overwrite: bool, reuse: int | None, reuse_water_mask: bool,
            scratch: str) -> Context:
    """The context of a run here or of a task on a worker: the worker's
    threads and memory as defaults, the sequence of ``reuse``, the base."""
    opts = dict(opts)
    threads, budget = _worker_resources(opts.get("threads"))
    if threads is not None:
        opts["threads"] = threads
    if budget is not None and opts.get("max_memory") is None:
        opts["max_memory"] = budget
    method = {k: opts[k] for k in files.METHOD_KEYS if k in opts}
    sequence = None
    if reuse is not None and opts.get("water_from") is not None:
        # METHOD §13.6: a sequence restores with the dive's water too (restore_file gives it to single photos)
        dive = _core.FileSettings(water_from=os.fspath(opts["water_from"])).dive_water_type
        if dive is not None:
            method["water_types"] = [dive]
    if reuse is not None:
        # photos: a cut or drift re-estimates only when asked for (--scene-cut), A smoothed only with --smoothing
        sequence = uwhl_rs.Sequence(refresh_every=reuse, reuse_water_mask=reuse_water_mask,
                                    scene_cut=opts.get("scene_cut") or 0.0, smoothing=opts.get("smoothing") or 1.0,
                                    **method)
    # --max-memory bounds the process's peak: what it holds before the
    # first input (the interpreter, numpy, the codecs, imported now so that
    # they are counted here and not while the first input is written) counts
    import imageio.v3  # noqa: F401  (counted in the base)
    from PIL import Image  # noqa: F401

    # (and 4 MiB for the writer threads' stacks and allocator arenas)
    base = _core.process_base() + (4 << 20)
    budget = opts.get("max_memory") or _core.default_max_memory()
    ctx = Context(opts, dict(storage_options), overwrite, scratch, sequence, base, reuse, reuse_water_mask,
                  gate=MemoryGate(max(0, int(budget) - base)))
    ctx.gate.stop = ctx.stop
    return ctx


def _worker_resources(threads_default: int | None) -> tuple[int | None, int | None]:
    """(threads, max_memory) for the core on this worker: the cores shared
    among the worker's task threads unless given, the worker's MEMORY
    resource or memory limit as the budget."""
    w = worker()
    if w is None:
        return threads_default, None
    nthreads = getattr(getattr(w, "state", None), "nthreads", None) or getattr(w, "nthreads", 1) or 1
    threads = threads_default if threads_default is not None else max(1, (os.cpu_count() or 1) // int(nthreads))
    budget = (getattr(getattr(w, "state", None), "total_resources", None) or {}).get(MEMORY)
    if budget is None:
        limit = getattr(getattr(w, "memory_manager", None), "memory_limit", None)
        budget = int(limit) if limit else None
    return threads, None if budget is None else int(budget)


def begin(item: Item, ctx: Context, prime: bool = False) -> dict | Callable[[], dict]:
    """Claims ``item``'s output names, reads and restores it. Returns its
    row when that settles it (skipped, failed), else the function that
    writes its outputs and returns its row, so that a caller can write one
    input while the next is restored. ``prime``: the input starts a chunk
    of a sequence; when it is done already it is restored again, unwritten,
    so the chunk's other frames reuse its estimates as in a full run.

    One input's failure is its row; an interrupt propagates (the claim is
    released)."""
    if video.is_video(item.input):
        return _begin_video(item, ctx)
    t0 = time.perf_counter()
    so = ctx.storage_options
    opts = {k: v for k, v in ctx.opts.items() if k not in VIDEO_KEYS}
    fmt, contact = opts.get("format", "jpg"), opts.get("contact", False)
    remote_out = is_url(item.out_dir)
    local_in = None
    # the run's other inputs (the one being written, --jobs) leave room for this one's plan
    room = ctx.gate.share() if ctx.gate is not None else None

    def _give_back() -> None:
        if room is not None:
            room.release()

    if not remote_out:
        out_dir = local_path(item.out_dir)
        try:
            status, sidecar, reason, claim = files.claim_outputs(out_dir, item.name, item.input, fmt, contact,
                                                                 overwrite=ctx.overwrite, rename=True)
        except OSError as e:
            return failure_row(item, OSError(e.errno, f"cannot claim output names in {out_dir}: {e}"), True, None)
        if status != "claimed":
            if prime and ctx.sequence is not None and status == "done":
                _prime(item, ctx)
            return skipped_row(item, sidecar, DONE_NOTE if status == "done" else reason)
    try:
        if remote_out:
            sidecar = join(item.out_dir, item.name + ".json")
            fs, side = filesystem(sidecar, so)
            if not ctx.overwrite and _stored("unreadable_input", fs.exists, side):
                if prime and ctx.sequence is not None:
                    _prime(item, ctx)
                return skipped_row(item, sidecar)
            out_dir = os.path.join(ctx.scratch, f"out{item.index}")
            _, _, _, claim = files.claim_outputs(out_dir, item.name, item.input, fmt, contact,
                                                 overwrite=True, rename=False)
        local_in = _local_input(item, ctx)
        write = files.restore_staged(local_in, out_dir, name=item.name, _claim=claim, _base=ctx.base,
                                     _label=item.input, sequence=ctx.sequence, _make_room=room, **opts)
    except (Exception, MemoryError) as e:  # one bad file never stops the batch
        _give_back()
        return failure_row(item, e, False, time.perf_counter() - t0, local_in)
    except BaseException:
        _give_back()
        raise

    def finish() -> dict:
        try:
            result = write()
            outputs = dict(result.paths)
            if remote_out:
                outputs = _stored("write_failed", _publish, result.paths, item, so, ctx.overwrite)
        except (Exception, MemoryError) as e:
            return failure_row(item, e, True, time.perf_counter() - t0, local_in)
        finally:
            _give_back()
            _drop_copy(item, local_in)
        done = _done_row(item, result, time.perf_counter() - t0, outputs)
        if remote_out:
            shutil.rmtree(out_dir, ignore_errors=True)
        return done

    return finish


def _begin_video(item: Item, ctx: Context) -> dict | Callable[[], dict]:
    """:func:`begin` for a video: its output names claimed (or the video
    skipped), then the function that restores and writes it whole
    (``uwhl_rs.videofiles.restore_video``): its frames are read, restored
    and encoded as they come, so nothing is done before the write."""
    from . import videofiles

    t0 = time.perf_counter()
    opts, so = dict(ctx.opts), ctx.storage_options
    for k in ("contact", "sequence"):
        opts.pop(k, None)
    every, codec = opts.get("every"), opts.get("video_codec") or "h264"
    remote_out = is_url(item.out_dir)
    if codec == "input" and not is_url(item.input):
        # the container the input's codec goes in is part of the names claimed (FFV1 in an AVI stays an AVI)
        codec = videofiles.resolve_codec(codec, local_path(item.input))
    suffixes = videofiles.video_suffixes(item.input, every=every, codec=codec)
    out_dir = os.path.join(ctx.scratch, f"out{item.index}") if remote_out else local_path(item.out_dir)
    if remote_out:
        sidecar = join(item.out_dir, item.name + ".json")
        fs, side = filesystem(sidecar, so)
        try:
            if not ctx.overwrite and _stored("unreadable_input", fs.exists, side):
                return skipped_row(item, sidecar)
        except (Exception, MemoryError) as e:
            return failure_row(item, e, False, None)
    try:
        status, sidecar, reason, claim = _core.claim_outputs(out_dir, item.name, item.input, suffixes,
                                                             ctx.overwrite or remote_out, not remote_out)
    except OSError as e:
        return failure_row(item, OSError(e.errno, f"cannot claim output names in {out_dir}: {e}"), True, None)
    if status != "claimed":
        return skipped_row(item, sidecar, DONE_NOTE if status == "done" else reason)
    # a frame's plan is held from here (not from the write, which runs beside the next input's restore)
    # to its last frame, as a photo's from its header to its write: photos wait for it, it for them
    room, local_in = ctx.gate.share() if ctx.gate is not None else None, None
    try:
        local_in = _local_input(item, ctx)
        if room is not None:
            room.reserve(_header_need(local_in, opts))
    except BaseException as e:
        claim.release()
        _drop_copy(item, local_in)
        if isinstance(e, (Exception, MemoryError)):
            return failure_row(item, e, False, time.perf_counter() - t0, local_in)
        raise  # an interrupt while it waited for room: its names are free again

    def finish() -> dict:
        try:
            result = videofiles.restore_video(local_in, out_dir, name=claim.name, _claim=claim, _label=item.input,
                                              reuse_estimates=ctx.reuse, reuse_water_mask=ctx.reuse_water_mask,
                                              overwrite=ctx.overwrite, progress=ctx.progress, _stop=ctx.stop,
                                              _base=ctx.base, **opts)
        except (Exception, MemoryError) as e:
            claim.release()
            return failure_row(item, e, False, time.perf_counter() - t0, local_in)
        finally:
            if room is not None:
                room.release()
            _drop_copy(item, local_in)
        written = {"sidecar": result.paths["sidecar"], "strip": result.paths["strip"]}
        if "video" in result.paths:
            written["video"] = result.paths["video"]
        if remote_out:
            stills = [os.path.join(out_dir, f) for f in sorted(os.listdir(out_dir))
                      if f.endswith(tuple(files.output_suffixes(opts.get("format", "jpg")) + [".json"]))
                      and os.path.join(out_dir, f) not in written.values()]
            try:
                dest = _stored("write_failed", _publish, {**{f"still{i}": p for i, p in enumerate(stills)}, **written},
                               item, so, ctx.overwrite)
            except (Exception, MemoryError) as e:
                return failure_row(item, e, True, time.perf_counter() - t0)
            finally:
                shutil.rmtree(out_dir, ignore_errors=True)
            written = {k: v for k, v in dest.items() if not k.startswith("still")}
        side = result.sidecar
        shown = written.get("video") or f"{len(side['video']['stills'])} stills beside {written['strip']}"
        r = row(item, "done", **row_fields_from_sidecar(side), seconds=sidecar_seconds(side, time.perf_counter() - t0),
                exit_code=0, image=shown, sidecar=written["sidecar"], reused_estimates=None)
        if result.stopped is not None:
            # restored up to where the file stops: its outputs stand, and the run says so
            stop = result.stopped
            where = f"frame {stop['frame']}" + ("" if stop["time"] is None else f" ({stop['time']:.3f} s)")
            r.update(error_kind="unreadable_input", exit_code=EXIT["unreadable_input"],
                     error=f"the video stops at {where}: {stop['error']}; the {side['video']['frames']['restored']} "
                           "frames before it are restored")
        return r

    return finish


def _prime(item: Item, ctx: Context) -> None:
    """Restores ``item`` (done already) into the scratch folder, unwritten,
    as the first frame of its chunk's sequence."""
    d = os.path.join(ctx.scratch, "prime")
    opts = ctx.opts
    try:
        local_in = _local_input(item, ctx)
        _, _, _, claim = files.claim_outputs(d, item.name, item.input, opts.get("format", "jpg"),
                                             opts.get("contact", False), overwrite=True, rename=False)
    except (Exception, MemoryError):
        return  # the frames after it then estimate for themselves, as after a failed first frame
    try:
        files.restore_staged(local_in, d, name=item.name, _claim=claim, _base=ctx.base, sequence=ctx.sequence, **opts)
    except (Exception, MemoryError):
        pass
    finally:
        claim.release()


def restore_items(items: list[Item], opts: dict, storage_options: dict, overwrite: bool,
                  reuse: int | None, reuse_water_mask: bool) -> list[dict]:
    """Task: restores ``items`` (in order; with ``reuse``, one chunk of a
    sequence whose first frame estimates) and writes their outputs as a
    local run does; their rows."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="uwhl-task-", dir=scratch_root()) as scratch:
        ctx = context(opts, storage_options, overwrite, reuse, reuse_water_mask, scratch)
        for pos, item in enumerate(items):
            step = begin(item, ctx, prime=pos == 0)
            rows.append(step() if callable(step) else step)
    return rows


# ------------------------------------------------------------------ planning


class _Planned(ImageReadError):
    """Raised from the header hook: the input's plan is known (an
    ImageReadError, so that read_image lets it through)."""


def _header_need(path: str, opts: dict) -> int:
    """Bytes the input at local ``path`` needs (files.input_need; a video's
    frame plan, ``videofiles``), from its header."""
    if video.is_video(path):
        from . import videofiles

        info = video.probe(path, transfer=opts.get("transfer"), rotation=False)
        return videofiles.frame_need(info, opts.get("max_side"))
    got = []
    masks = int(opts.get("mask") is not None) + int(opts.get("water_mask") is not None)

    def hook(h, w, bpp, oriented):
        got.append(files.input_need(h, w, bpp, oriented, half_size=opts.get("half_size", False),
                                    max_side=opts.get("max_side"), preprocess=opts.get("preprocess", "none"),
                                    masks=masks, contact=opts.get("contact", False),
                                    sphere_points=opts.get("sphere_points")))
        raise _Planned

    try:
        read_image(path, preprocess=opts.get("preprocess", "none"), half_size=opts.get("half_size", False),
                   max_pixels=opts.get("max_pixels", DEFAULT_MAX_PIXELS), _on_header=hook)
    except _Planned:
        pass
    if not got:
        raise ValueError("no header")
    return got[0]


def probe(items: list[tuple[int, str]], opts: dict, storage_options: dict) -> list[tuple[int, int | None]]:
    """Task: the memory plan of each (index, input) from its header, or
    None when the header cannot be read (the restore task then reports why)."""
    out = []
    with tempfile.TemporaryDirectory(prefix="uwhl-probe-", dir=scratch_root()) as scratch:
        for k, path in items:
            need = None
            for header in ((True, False) if is_url(path) else (None,)):
                try:
                    local = fetch(path, scratch, storage_options, header=header) if header is not None \
                        else local_path(path)
                    need = _header_need(local, opts)
                    break
                except Exception:  # a truncated header copy: try the whole file; a bad file: the restore says why
                    continue
            out.append((k, need))
    return out
