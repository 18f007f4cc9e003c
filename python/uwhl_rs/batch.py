"""Batches at survey scale: :func:`restore_many` runs ``restore_file`` for
every input of a batch on a Dask cluster (or in this process), with inputs
and outputs on local paths or fsspec URLs (``s3://``, ``gs://``, ...).

The outputs, their names and the sidecars are those of a local
``uwhl restore`` run (docs/OUTPUTS.md), written by the same code; what is
particular to clusters and object storage (resume, retries, memory per
task, the sidecar as commit marker) is in docs/SCALE.md.

Dask, distributed, fsspec, s3fs and pandas are the optional extra
``uwhl_rs[dask]``; this module imports them only when a batch needs them.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import sys
import tempfile
import time
from dataclasses import dataclass, field

from . import _core
from .io import ImageReadError

__all__ = ["restore_many", "BatchError", "parse_storage_options", "plan_batch", "EXTRA"]

#: how to get what this module needs
EXTRA = 'pip install "uwhl_rs[dask]"'

#: the Dask worker resource a task asks for: bytes of its memory plan
MEMORY = "MEMORY"

#: header bytes fetched from object storage to plan an input's memory
_HEADER_BYTES = 1 << 18

#: inputs whose header one planning task reads
_PROBE_BATCH = 32

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")

#: summary columns, in order
COLUMNS = ["input", "status", "water_type", "A_R", "A_G", "A_B", "flags", "seconds", "image", "transmission",
           "transmission_color", "contact_sheet", "sidecar", "reused_estimates", "error_kind", "error", "exit_code",
           "worker", "scores", "taken_at", "latitude", "longitude", "altitude"]


class BatchError(Exception):
    """The batch could not start: the extra is missing, the scheduler or
    the storage cannot be reached, credentials are refused. ``kind`` is
    the exit-code name of docs/CLI.md."""

    def __init__(self, message: str, kind: str = "unreachable"):
        super().__init__(message)
        self.kind = kind


def _need(*modules: str):
    """Imports ``modules`` or raises a BatchError naming the extra."""
    import importlib

    out = []
    for m in modules:
        try:
            out.append(importlib.import_module(m))
        except ImportError as e:
            raise BatchError(f"{m} is not installed ({e}); batches on Dask or object storage need the extra: {EXTRA}",
                             "bad_arguments") from None
    return out


def is_url(path: str) -> bool:
    """Whether ``path`` is a URL of a storage other than the local disk
    (``file://`` URLs are local paths)."""
    return bool(_URL.match(str(path))) and not str(path).startswith("file://")


def _local(path: str) -> str:
    return path[len("file://"):] if str(path).startswith("file://") else str(path)


def parse_storage_options(items: list[str] | None) -> dict:
    """``--storage-option KEY=VALUE`` values as fsspec storage options:
    values ``true``/``false``/``null`` and numbers are read as JSON, others
    kept as text; ``a.b=V`` nests (``client_kwargs.region_name=eu-west-1``)."""
    out: dict = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--storage-option {item!r} is not KEY=VALUE")
        try:
            v = json.loads(value) if value.strip() in ("true", "false", "null") or _is_number(value) else value
        except ValueError:
            v = value
        d = out
        *parents, leaf = key.split(".")
        for p in parents:
            d = d.setdefault(p, {})
            if not isinstance(d, dict):
                raise ValueError(f"--storage-option {item!r}: {p} is given both as a value and as a group")
        d[leaf] = v
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# ------------------------------------------------------------------ planning


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


@dataclass
class Plan:
    """What :func:`plan_batch` found."""

    items: list[Item] = field(default_factory=list)
    #: (input, reason) of inputs that match nothing
    problems: list[tuple[str, str]] = field(default_factory=list)
    #: the items whose sidecar exists at the destination (skipped unless overwrite)
    done: set = field(default_factory=set)


def _storage_error(e: BaseException, where: str) -> BatchError:
    """An error of the storage client as a BatchError that says what to do."""
    name = type(e).__name__
    text = str(e) or name
    if "credential" in text.lower() or name in ("NoCredentialsError", "PartialCredentialsError"):
        return BatchError(f"{where}: no credentials ({text}); give them with --storage-option key=... "
                          "--storage-option secret=... (or profile=NAME, or anon=true for a public bucket), "
                          "or the AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY environment variables")
    if isinstance(e, PermissionError) or "AccessDenied" in text or "Forbidden" in text:
        return BatchError(f"{where}: access refused ({text}); check the credentials and the bucket's policy")
    return BatchError(f"{where}: cannot reach the storage ({name}: {text})")


def _fs(url: str, storage_options: dict):
    """(filesystem, path) of ``url`` through fsspec."""
    (fsspec,) = _need("fsspec")
    try:
        return fsspec.core.url_to_fs(url, **storage_options)
    except ImportError as e:
        raise BatchError(f"{url}: no fsspec backend for this protocol is installed ({e}); "
                         f"{EXTRA} brings s3fs (s3://)", "bad_arguments") from None
    except (ValueError, TypeError) as e:
        raise BatchError(f"{url}: bad storage options ({e})", "bad_arguments") from None


def _list_remote(inputs: list[str], out: str, storage_options: dict) -> tuple[list[tuple[str, str]], list]:
    """URL inputs as (url, folder relative to the output folder), in the
    order a local folder walk gives (sorted by path components, hidden
    entries skipped, the output folder never searched), and the problems."""
    from .cli import _GLOB_CHARS, _supported

    found: list[tuple[str, str]] = []
    problems: list[tuple[str, str]] = []
    out_key = out.rstrip("/") + "/"
    for url in inputs:
        fs, path = _fs(url, storage_options)
        proto = url.split("://", 1)[0]

        def full(p: str) -> str:
            return fs.unstrip_protocol(p) if hasattr(fs, "unstrip_protocol") else f"{proto}://{p}"

        try:
            if _GLOB_CHARS.search(path):
                hits = sorted(h for h in fs.glob(path) if _supported(h) and fs.isfile(h))
                if not hits:
                    problems.append((url, "pattern matches no image file"))
                found += [(full(h), "") for h in hits]
            elif fs.isdir(path):
                root = path.rstrip("/")
                rels = []
                for f in fs.find(root):
                    rel = f[len(root):].lstrip("/")
                    parts = rel.split("/")
                    if any(p.startswith(".") for p in parts) or not _supported(rel):
                        continue
                    if full(f).startswith(out_key):
                        continue
                    rels.append((tuple(parts), f))
                rels.sort()
                if not rels:
                    problems.append((url, "folder holds no JPEG, PNG, TIFF or raw file"))
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
            raise _storage_error(e, url) from None
    seen = set()
    unique = []
    for u, rel in found:
        if u not in seen:
            seen.add(u)
            unique.append((u, rel))
    return unique, problems


def _join(base: str, rel: str) -> str:
    if not rel:
        return base.rstrip("/") if is_url(base) else base
    return base.rstrip("/") + "/" + rel if is_url(base) else os.path.join(base, rel)


def plan_batch(inputs: list[str], out: str, *, format: str = "jpg", contact: bool = False,
               storage_options: dict | None = None) -> Plan:
    """The inputs of a batch, named as a local run names them (the core's
    ``collect_jobs`` for local inputs; fsspec listings named by the same
    rules, ``_core.name_jobs``, for URLs), and which are already done (their
    sidecar exists at the destination)."""
    from .cli import collect_inputs
    from .files import output_suffixes

    so = storage_options or {}
    suffixes = output_suffixes(format, contact)
    plan = Plan()
    local = [_local(i) for i in inputs if not is_url(i)]
    remote = [i for i in inputs if is_url(i)]
    out_local = not is_url(out)
    if local:
        # named against the real output folder when it is local (the output
        # folder is never searched), else against a folder that cannot exist
        anchor = _local(out) if out_local else os.path.join(tempfile.gettempdir(), f".uwhl-none-{os.getpid()}")
        jobs, problems = collect_inputs(local, anchor, format, contact)
        plan.problems += problems
        for j in jobs:
            rel = os.path.relpath(j.out_dir, anchor)
            rel = "" if rel == "." else rel.replace(os.sep, "/")
            plan.items.append(Item(j.path, _join(out if not out_local else anchor, rel), j.name))
    if remote:
        found, problems = _list_remote(remote, out, so)
        plan.problems += problems
        names = _core.name_jobs([(u, rel) for u, rel in found], suffixes)
        base = _local(out)
        plan.items += [Item(u, _join(base, rel), n) for (u, rel), n in zip(found, names)]
    for k, it in enumerate(plan.items):
        it.index = k
    # what is done already: the sidecars at the destination, listed once
    if out_local:
        plan.done = {k for k, it in enumerate(plan.items) if os.path.exists(os.path.join(it.out_dir, it.name + ".json"))}
    elif plan.items:
        fs, root = _fs(out, so)
        try:
            existing = set(fs.find(root.rstrip("/"))) if fs.exists(root.rstrip("/")) else set()
        except FileNotFoundError:
            existing = set()
        except Exception as e:
            raise _storage_error(e, out) from None
        for k, it in enumerate(plan.items):
            key = _fs(_join(it.out_dir, it.name + ".json"), so)[1]
            if key in existing:
                plan.done.add(k)
    return plan


# ------------------------------------------------------------------ tasks


def _worker():
    """The Dask worker running this task, or None (in this process)."""
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):
        return None


def _scratch_root() -> str:
    w = _worker()
    root = getattr(w, "local_directory", None) if w is not None else None
    return root or tempfile.gettempdir()


def _fetch(url: str, scratch: str, storage_options: dict, header: bool = False) -> str:
    """A local copy of ``url`` in ``scratch`` under its own base name (so
    the contact sheet and the readers see the same name and extension);
    ``header``: only its first bytes."""
    fs, path = _fs(url, storage_options)
    local = os.path.join(scratch, os.path.basename(path))
    try:
        if header:
            with open(local, "wb") as f:
                f.write(fs.cat_file(path, start=0, end=_HEADER_BYTES))
        else:
            fs.get_file(path, local)
    except FileNotFoundError:
        raise FileNotFoundError(2, "No such file or folder", url) from None
    return local


class _Planned(ImageReadError):
    """Raised from the header hook: the input's plan is known (an
    ImageReadError, so that read_image lets it through)."""


def _header_need(path: str, opts: dict) -> int:
    """Bytes the input at local ``path`` needs (files.input_need), from its header."""
    from .files import input_need
    from .io import DEFAULT_MAX_PIXELS, read_image

    got = []
    masks = int(opts.get("mask") is not None) + int(opts.get("water_mask") is not None)

    def hook(h, w, bpp, oriented):
        got.append(input_need(h, w, bpp, oriented, half_size=opts.get("half_size", False),
                              max_side=opts.get("max_side"), preprocess=opts.get("preprocess", "none"),
                              masks=masks, contact=opts.get("contact", False)))
        raise _Planned

    try:
        read_image(path, preprocess=opts.get("preprocess", "none"), half_size=opts.get("half_size", False),
                   max_pixels=opts.get("max_pixels", DEFAULT_MAX_PIXELS), _on_header=hook)
    except _Planned:
        pass
    if not got:
        raise ValueError("no header")
    return got[0]


def _probe(items: list[tuple[int, str]], opts: dict, storage_options: dict) -> list[tuple[int, int | None]]:
    """Task: the memory plan of each (index, input) from its header, or
    None when the header cannot be read (the restore task then reports why)."""
    out = []
    with tempfile.TemporaryDirectory(prefix="uwhl-probe-", dir=_scratch_root()) as scratch:
        for k, path in items:
            need = None
            for header in ((True, False) if is_url(path) else (None,)):
                try:
                    local = _fetch(path, scratch, storage_options, header=header) if header is not None else _local(path)
                    need = _header_need(local, opts)
                    break
                except Exception:  # a truncated header copy: try the whole file; a bad file: the restore says why
                    continue
            out.append((k, need))
    return out


def _worker_resources(threads_default: int | None) -> tuple[int | None, int | None]:
    """(threads, max_memory) for the core on this worker: the cores shared
    among the worker's task threads unless given, the worker's MEMORY
    resource or memory limit as the budget."""
    w = _worker()
    if w is None:
        return threads_default, None
    nthreads = getattr(getattr(w, "state", None), "nthreads", None) or getattr(w, "nthreads", 1) or 1
    threads = threads_default if threads_default is not None else max(1, (os.cpu_count() or 1) // int(nthreads))
    budget = (getattr(getattr(w, "state", None), "total_resources", None) or {}).get(MEMORY)
    if budget is None:
        limit = getattr(getattr(w, "memory_manager", None), "memory_limit", None)
        budget = int(limit) if limit else None
    return threads, None if budget is None else int(budget)


def _row(item: Item, status: str, **kw) -> dict:
    r = {c: None for c in COLUMNS}
    r.update(input=item.input, status=status)
    w = _worker()
    r["worker"] = w.address if w is not None else f"{socket.gethostname()}:{os.getpid()}"
    r.update(kw)
    return r


def _failure_row(item: Item, e: BaseException, writing: bool, seconds: float, local_path: str | None = None) -> dict:
    from .cli import EXIT, _describe, _error_kind

    kind = _error_kind(e, writing)
    if kind == "internal" and type(e).__module__.split(".")[0] in ("botocore", "aiobotocore", "s3fs", "gcsfs",
                                                                   "adlfs", "fsspec", "aiohttp"):
        kind = "write_failed" if writing else "unreadable_input"
    text = _describe(e, local_path or item.input)
    if local_path and local_path != item.input:
        text = text.replace(local_path, item.input)
    return _row(item, "failed", error_kind=kind, error=text, exit_code=EXIT[kind], seconds=round(seconds, 4))


def _done_row(item: Item, result, seconds: float, outputs: dict) -> dict:
    from .summary import row_fields_from_sidecar

    res = result.restoration
    return _row(item, "done", **row_fields_from_sidecar(result.sidecar), seconds=round(seconds, 4), exit_code=0,
                reused_estimates="estimates_reused" in res.flags if "reused_estimates" in result.sidecar else None,
                **{role: outputs.get(role) for role in ("image", "transmission", "transmission_color",
                                                         "contact_sheet", "sidecar")})


def _publish(files_written: dict, item: Item, storage_options: dict, overwrite: bool) -> dict:
    """Uploads an input's outputs to object storage, the sidecar last: the
    sidecar is the commit marker (docs/SCALE.md). An earlier sidecar goes
    first, so that no sidecar ever lists outputs of another attempt."""
    fs, _ = _fs(item.out_dir, storage_options)
    dest = {role: _join(item.out_dir, os.path.basename(p)) for role, p in files_written.items()}
    side = _fs(dest["sidecar"], storage_options)[1]
    if overwrite:
        try:
            fs.rm_file(side)
        except FileNotFoundError:
            pass
    for role, p in files_written.items():
        if role != "sidecar":
            fs.put_file(p, _fs(dest[role], storage_options)[1])
    fs.put_file(files_written["sidecar"], side)
    return dest


def _restore_items(items: list[Item], opts: dict, storage_options: dict, overwrite: bool,
                   reuse: int | None, reuse_water_mask: bool) -> list[dict]:
    """Task: restores ``items`` (in order; with ``reuse``, one chunk of a
    sequence whose first frame estimates) and writes their outputs as a
    local run does. One input's failure never stops the others."""
    import uwhl_rs

    from . import files

    opts = dict(opts)
    threads, budget = _worker_resources(opts.get("threads"))
    if threads is not None:
        opts["threads"] = threads
    if budget is not None and opts.get("max_memory") is None:
        opts["max_memory"] = budget
    fmt, contact = opts.get("format", "jpg"), opts.get("contact", False)
    method = {k: opts[k] for k in files.METHOD_KEYS if k in opts}
    sequence = None
    if reuse is not None:
        sequence = uwhl_rs.Sequence(refresh_every=reuse, reuse_water_mask=reuse_water_mask, **method)
    base = _core.process_base() + (4 << 20)
    rows = []
    with tempfile.TemporaryDirectory(prefix="uwhl-task-", dir=_scratch_root()) as scratch:
        for pos, item in enumerate(items):
            t0 = time.perf_counter()
            remote_out = is_url(item.out_dir)
            local_in = None
            try:
                if not remote_out:
                    status, sidecar, reason, claim = files.claim_outputs(
                        _local(item.out_dir), item.name, item.input, fmt, contact, overwrite=overwrite, rename=True)
                    if status != "claimed":
                        if pos == 0 and sequence is not None and status == "done":
                            _prime(sequence, item, scratch, opts, storage_options, base)
                        note = "already done (sidecar exists)" if status == "done" else reason
                        rows.append(_row(item, "skipped", error=note, exit_code=0, sidecar=sidecar))
                        continue
                    out_dir = _local(item.out_dir)
                else:
                    sidecar = _join(item.out_dir, item.name + ".json")
                    fs, side = _fs(sidecar, storage_options)
                    if not overwrite and fs.exists(side):
                        if pos == 0 and sequence is not None:
                            _prime(sequence, item, scratch, opts, storage_options, base)
                        rows.append(_row(item, "skipped", error="already done (sidecar exists)", exit_code=0,
                                         sidecar=sidecar))
                        continue
                    out_dir = os.path.join(scratch, f"out{pos}")
                    status, _, _, claim = files.claim_outputs(out_dir, item.name, item.input, fmt, contact,
                                                              overwrite=True, rename=False)
                local_in = _fetch(item.input, scratch, storage_options) if is_url(item.input) else _local(item.input)
                write = files._restore_staged(local_in, out_dir, name=item.name, _claim=claim, _base=base,
                                              _label=item.input, sequence=sequence, **opts)
            except (Exception, MemoryError) as e:
                rows.append(_failure_row(item, e, False, time.perf_counter() - t0, local_in))
                continue
            try:
                result = write()
                outputs = dict(result.paths)
                if remote_out:
                    outputs = _publish(result.paths, item, storage_options, overwrite)
            except (Exception, MemoryError) as e:
                rows.append(_failure_row(item, e, True, time.perf_counter() - t0, local_in))
                continue
            finally:
                if local_in is not None and local_in != _local(item.input):
                    _unlink(local_in)
            rows.append(_done_row(item, result, time.perf_counter() - t0, outputs))
            if remote_out:
                shutil.rmtree(out_dir, ignore_errors=True)
    return rows


def _prime(sequence, item: Item, scratch: str, opts: dict, storage_options: dict, base: int) -> None:
    """A chunk's first frame is done already: restore it (nothing written)
    so the chunk's other frames reuse its estimates, as in a full run."""
    from . import files

    d = os.path.join(scratch, "prime")
    local_in = _fetch(item.input, scratch, storage_options) if is_url(item.input) else _local(item.input)
    status, _, _, claim = files.claim_outputs(d, item.name, item.input, opts.get("format", "jpg"),
                                              opts.get("contact", False), overwrite=True, rename=False)
    try:
        files._restore_staged(local_in, d, name=item.name, _claim=claim, _base=base, sequence=sequence, **opts)
    except (Exception, MemoryError):
        pass  # the frames after it then estimate for themselves, as after a failed first frame
    finally:
        claim.release()


def _unlink(p: str) -> None:
    try:
        os.unlink(p)
    except OSError:
        pass


# ------------------------------------------------------------------ running


def _connect(client, dask: str | None, threads: int | None):
    """(client, cluster to close or None, threads for the core) for ``dask``
    (None: ``client`` as given, or in this process)."""
    if client is not None or dask is None:
        return client, None, threads
    (distributed,) = _need("distributed")
    if dask == "local" or dask.startswith("local:"):
        n = int(dask.split(":", 1)[1]) if ":" in dask else max(1, (os.cpu_count() or 1))
        from distributed.system import MEMORY_LIMIT

        cores = os.cpu_count() or 1
        # Dask's own share of the machine (cgroups and ulimit counted); a
        # task may plan up to 80% of it, where Dask would pause the worker
        memory = int(MEMORY_LIMIT // n)
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           memory_limit=memory, resources={MEMORY: int(memory * 0.8)},
                                           dashboard_address="127.0.0.1:0", host="127.0.0.1",
                                           silence_logs=40)
        return distributed.Client(cluster), cluster, threads if threads is not None else max(1, cores // n)
    address = dask if "://" in dask else f"tcp://{dask}"
    try:
        c = distributed.Client(address, timeout=float(os.environ.get("UWHL_DASK_TIMEOUT", "10")))
    except (OSError, TimeoutError) as e:
        raise BatchError(f"--dask {dask}: cannot reach the Dask scheduler ({type(e).__name__}: {e})") from None
    return c, None, threads


def _check_workers(client) -> None:
    """The workers have this uwhl_rs (another version would write other
    outputs; none would fail every task)."""
    import importlib.metadata

    import uwhl_rs

    try:
        found = client.run(importlib.metadata.version, "uwhl_rs", on_error="return")
    except Exception as e:
        raise BatchError(f"cannot ask the Dask workers for their uwhl_rs ({type(e).__name__}: {e})") from None
    if not found:
        raise BatchError("the Dask cluster has no workers")
    wrong = {w: v for w, v in found.items() if v != uwhl_rs.__version__}
    if wrong:
        w, v = sorted(wrong.items())[0]
        v = "no uwhl_rs" if isinstance(v, BaseException) else f"uwhl_rs {v}"
        raise BatchError(f"{len(wrong)} of {len(found)} Dask workers do not run uwhl_rs {uwhl_rs.__version__} "
                         f"(worker {w}: {v}); install the same version on the workers", "bad_arguments")


def _largest_worker_memory(client) -> int | None:
    """The largest MEMORY resource of the workers, or None when some worker
    has none (then tasks ask for no resource, and each worker checks its
    own limit)."""
    info = client.scheduler_info().get("workers", {})
    values = [w.get("resources", {}).get(MEMORY) for w in info.values()]
    if not values or any(v is None for v in values):
        return None
    return max(int(v) for v in values)


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
    are split into chunks of N, each restored by one task as a sequence
    whose first frame estimates (``uwhl_rs.Sequence``). ``options``: the
    keywords of :func:`uwhl_rs.files.restore_file` (``format``,
    ``water_types``, ``max_side``, ``method``, ...). ``progress``: the
    command's progress lines on stderr.

    Returns a pandas DataFrame, one row per input in name order (columns
    :data:`COLUMNS`; inputs that match nothing first): ``status`` done /
    skipped / failed, the water type, A, flags, seconds, the output paths
    or URLs, and for a failure its kind, message and exit code
    (docs/CLI.md). Raises :class:`BatchError` when the batch cannot start.
    """
    (pd,) = _need("pandas")
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [os.fspath(inputs)]
    inputs = [os.fspath(i) for i in inputs]
    output = os.fspath(output)
    bar = None
    if progress:
        from .cli import Progress

        bar = _Bar(Progress(0, sys.stderr), sys.stderr, False)
    result = run_batch(inputs, output, client=client, dask=dask, storage_options=storage_options,
                       overwrite=overwrite, reuse_estimates=reuse_estimates, reuse_water_mask=reuse_water_mask,
                       bar=bar, options=options)
    if result.interrupted:
        raise KeyboardInterrupt
    return pd.DataFrame(result.rows, columns=COLUMNS)


class _Bar:
    """The command's progress bar fed with rows (errors reported as the
    local run reports them)."""

    def __init__(self, progress, err, json_errors: bool):
        self.progress, self.err, self.json_errors = progress, err, json_errors

    def total(self, n: int) -> None:
        self.progress.total = n

    def start(self, name: str) -> None:
        self.progress.start(name)

    def row(self, row: dict) -> None:
        from .cli import _report

        line, error = _progress_line(row)
        self.progress.finish(line, error=error, report=lambda: _report(
            self.err, self.json_errors, row["input"], row["error_kind"], row["error"]))


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


def run_batch(inputs: list[str], output: str, *, client=None, dask=None, storage_options=None, overwrite=False,
              reuse_estimates=None, reuse_water_mask=False, bar=None, options=None, announce=None) -> BatchResult:
    """The body of :func:`restore_many` (and of ``uwhl restore`` on a
    cluster or object storage): rows as dicts, and whether it was
    interrupted. ``announce(text)`` is told the Dask dashboard's address."""
    so = dict(storage_options or {})
    if any(is_url(p) for p in [*inputs, output]):
        _need("fsspec")
    opts = dict(options or {})
    fmt, contact = opts.get("format", "jpg"), opts.get("contact", False)
    if not is_url(output):
        os.makedirs(_local(output), exist_ok=True)
    plan = plan_batch(inputs, output, format=fmt, contact=contact, storage_options=so)
    if not is_url(output):
        # what a killed run left in the output folders goes first
        for d in sorted({_local(it.out_dir) for it in plan.items}):
            _core.remove_stale_temps(d)
    rows: dict[int, dict] = {}
    from .cli import EXIT

    problems = [dict(_row(Item(i, "", ""), "failed"), error_kind="unreadable_input", error=why,
                     exit_code=EXIT["unreadable_input"], worker=None) for i, why in plan.problems]
    if bar is not None:
        bar.total(len(plan.items))
        for r in problems:
            from .cli import _report

            _report(bar.err, bar.json_errors, r["input"], r["error_kind"], r["error"])

    from .summary import FILE_NAME, SummaryWriter

    # summary.csv as the batch goes: in OUTDIR, or (object storage) in a
    # local file uploaded when the batch ends
    scratch = None if not is_url(output) else tempfile.mkdtemp(prefix="uwhl-summary-")
    csv_rows = SummaryWriter(scratch or _local(output))
    for r in problems:
        csv_rows.add(r)

    def settle(k: int, row: dict) -> None:
        rows[k] = row
        csv_rows.add(row)
        if bar is not None:
            bar.row(row)

    def skipped_row(it: Item) -> dict:
        return _row(it, "skipped", error="already done (sidecar exists)", exit_code=0, worker=None,
                    sidecar=_join(it.out_dir, it.name + ".json"))

    if reuse_estimates is not None:
        # chunks of N in name order; a chunk all done is skipped whole
        groups = []
        for i in range(0, len(plan.items), reuse_estimates):
            ch = plan.items[i:i + reuse_estimates]
            if not overwrite and all(it.index in plan.done for it in ch):
                for it in ch:
                    settle(it.index, skipped_row(it))
            else:
                groups.append(ch)
    else:
        groups = []
        for it in plan.items:
            if not overwrite and it.index in plan.done:
                settle(it.index, skipped_row(it))
            else:
                groups.append([it])
    interrupted = False
    c, cluster = None, None
    try:
        if groups:
            c, cluster, threads = _connect(client, dask, opts.get("threads"))
            if threads is not None:
                opts["threads"] = threads
        if c is None:
            for g in groups:
                if bar is not None:
                    bar.start(os.path.basename(g[0].input))
                for row, it in zip(_restore_items(g, opts, so, overwrite, reuse_estimates, reuse_water_mask), g):
                    settle(it.index, row)
        else:
            _check_workers(c)
            if announce is not None:
                announce(f"Dask dashboard: {c.dashboard_link}")
            _run_on_cluster(c, groups, opts, so, overwrite, reuse_estimates, reuse_water_mask, settle)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if cluster is not None:
            c.close()
            cluster.close()
        csv_rows.close()
        if scratch is not None:
            try:
                fs, root = _fs(output, so)
                fs.put_file(csv_rows.path, _join(root, FILE_NAME))
            except Exception as e:  # the outputs are stored; only the summary is lost
                print(f"uwhl: cannot upload {FILE_NAME} to {output}: {type(e).__name__}: {e}", file=sys.stderr)
            shutil.rmtree(scratch, ignore_errors=True)
    return BatchResult(problems + [rows[k] for k in sorted(rows)], len(plan.items), interrupted, csv_rows.error)


def _progress_line(row: dict) -> tuple[str, bool]:
    if row["status"] == "failed":
        return f"{row['input']}: {row['error']}", True
    if row["status"] == "skipped":
        return f"{row['input']}: skipped ({row['error']})", False
    return f"{row['input']} -> {row['image']} (water type {row['water_type']}, {row['seconds']:.2f} s)", False


def _run_on_cluster(c, groups: list[list[Item]], opts, so, overwrite, reuse, reuse_wm, settle) -> None:
    """Submits the planning and restoring tasks and settles each input as
    its task completes. A task whose worker died is retried by the
    scheduler (its ``allowed-failures``); one that kept killing workers is
    reported failed with the reason."""
    from distributed import as_completed

    budget = _largest_worker_memory(c)
    pending = as_completed()
    meta = {}  # future key -> ("probe"|"restore", payload)

    def submit_restore(g: list[Item]):
        need = max((it.need or 0) for it in g)
        if budget is not None and need > budget:
            from .cli import EXIT

            for it in g:
                settle(it.index, _row(it, "failed", error_kind="over_budget", exit_code=EXIT["over_budget"],
                                      worker=None, error=f"needs about {need} bytes, over every worker's "
                                      f"memory ({budget} bytes); use --max-side or larger workers"))
            return
        kw = {"resources": {MEMORY: need}} if budget is not None and need > 0 else {}
        f = c.submit(_restore_items, g, opts, so, overwrite, reuse, reuse_wm, pure=False,
                     key=f"uwhl-restore-{g[0].index}-{os.urandom(4).hex()}", **kw)
        meta[f.key] = ("restore", g)
        pending.add(f)

    if budget is not None:
        # a group is submitted once the headers of all its items are read:
        # per group, how many are still unread
        unread = {id(g): len(g) for g in groups}
        group_of = {it.index: g for g in groups for it in g}
        flat = [it for g in groups for it in g]
        item_of = {it.index: it for it in flat}
        for i in range(0, len(flat), _PROBE_BATCH):
            chunk = [(it.index, it.input) for it in flat[i:i + _PROBE_BATCH]]
            f = c.submit(_probe, chunk, opts, so, pure=False, key=f"uwhl-probe-{chunk[0][0]}-{os.urandom(4).hex()}")
            meta[f.key] = ("probe", chunk)
            pending.add(f)
    else:
        for g in groups:
            submit_restore(g)
    try:
        for f in pending:
            what, payload = meta.pop(f.key)
            try:
                result = f.result()
            except Exception as e:  # the task itself never raises: its worker died, or it was cancelled
                if what == "probe":
                    result = [(k, None) for k, _ in payload]
                else:
                    for it in payload:
                        settle(it.index, _lost_row(it, e))
                    continue
            if what == "probe":
                for k, need in result:
                    item_of[k].need = need
                    g = group_of[k]
                    unread[id(g)] -= 1
                    if unread[id(g)] == 0:
                        submit_restore(g)
            else:
                for it, row in zip(payload, result):
                    settle(it.index, row)
    except KeyboardInterrupt:
        for f in list(pending.futures):
            f.cancel()
        raise


def _lost_row(item: Item, e: BaseException) -> dict:
    from .cli import EXIT

    name = type(e).__name__
    if name == "KilledWorker":
        why = ("the workers running it died every time it was tried (killed, out of memory or preempted): "
               f"{e}")
    else:
        why = f"the task was lost ({name}: {e})"
    return _row(item, "failed", error_kind="internal", error=why, exit_code=EXIT["internal"], worker=None)
