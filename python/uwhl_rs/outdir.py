"""An output folder as its readers see it: the sidecars of its restored
photos (``uwhl report``, ``uwhl ifdo``) and ``OUTDIR/summary.csv``, one row
per input of a batch, written as the batch goes (each row flushed when its
input is settled), so an interrupted run keeps what it did
(docs/OUTPUTS.md "summary.csv").

Rows are the dicts of ``uwhl_rs.tasks`` (its ``COLUMNS``).
"""

from __future__ import annotations

import csv
import json
import os
import posixpath
import threading
from dataclasses import dataclass

from . import _core
from .sidecars import MAX_BYTES as SIDECAR_MAX_BYTES
from .sidecars import SidecarError, display, is_sha256, local_outputs_problem
from .sidecars import parse as parse_sidecar
from .storage import Folder, filesystem, is_url, join, local_path, read_bytes, read_regular, scheme, sha256_of

__all__ = ["SummaryWriter", "sidecar_seconds", "remove_earlier", "stored_names", "folder_done", "CSV_COLUMNS", "row_fields_from_sidecar", "summary_cell", "FILE_NAME", "REPORT_DIR", "Photo",
           "collect_sidecars", "failed_inputs", "Digests"]

FILE_NAME = "summary.csv"

#: the report's folder inside OUTDIR (an input tree may have its own
#: ``report`` folder: its outputs are found there like any others, and the
#: report's own files have names no output has)
REPORT_DIR = "report"

#: JSON files the commands write at the top of OUTDIR that are no sidecars
#: (``uwhl ifdo --format json``: it grows past a sidecar's size limit with the batch)
OWN_JSON = ("ifdo.json",)

#: the largest summary.csv read back (about a million rows)
SUMMARY_MAX_BYTES = 512 << 20
#: the most rows of summary.csv read (a few hundred bytes each: a run of
#: millions of inputs; past it the report says the count stops there)
SUMMARY_ROWS_MAX = 5_000_000
#: failed rows of summary.csv shown on the report's page, and characters of each cell
FAILED_SHOWN = 200
CELL_SHOWN = 300

#: flags that say something the operator should look at (``estimates_reused`` is the plan of a sequence)
ROUTINE_FLAGS = ("estimates_reused",)

#: the columns of summary.csv, in order (the core's writer owns them)
CSV_COLUMNS = _core.summary_columns()


def row_fields_from_sidecar(side: dict) -> dict:
    """What a row takes from a sidecar: the choice, A, every score, flags,
    and the EXIF time and GPS position the core read (``metadata``)."""
    a = side.get("veiling_light") or [None] * 3
    meta = side.get("metadata") or {}
    gps = meta.get("gps") or {}
    return {"water_type": side.get("water_type"), "A_R": a[0], "A_G": a[1], "A_B": a[2],
            "scores": dict(side.get("scores") or {}), "flags": ",".join(side.get("flags") or []),
            "veil_excess": side.get("veil_excess"), "fallback_share": side.get("fallback_share"),
            "taken_at": meta.get("taken_at"), "latitude": gps.get("latitude"), "longitude": gps.get("longitude"),
            "altitude": gps.get("altitude")}


def _read_sidecar(path: str | None) -> dict | None:
    """The checked sidecar at the local ``path`` (``uwhl_rs.sidecars``),
    or None when there is none, or it is unreadable or malformed."""
    if not path:
        return None
    try:
        return parse_sidecar(read_regular(path, SIDECAR_MAX_BYTES))
    except (OSError, SidecarError):
        return None


def summary_cell(text: str) -> str:
    """A summary.csv cell as it was before the writer neutralised a
    spreadsheet formula in it (``'=x`` back to ``=x``; docs/OUTPUTS.md):
    what a reader of the file shows."""
    return _core.summary_cell(text)


class SummaryWriter:
    """Appends one row per settled input to ``OUTDIR/summary.csv`` through
    the core's writer (``_core.Summary``, the binary's): the same columns,
    quoting and neutralised formula cells, each row one locked append, so
    two runs on one folder keep every row whole. A skipped input's row is
    filled from its sidecar."""

    def __init__(self, out_dir: str, waiting=None):
        """``waiting``: called with a note if another program's lock keeps
        the folder (the batch then waits for it: docs/OUTPUTS.md)."""
        self.out_dir = out_dir
        self._core = _core.Summary(out_dir, waiting)
        self.path = os.fspath(self._core.path)

    @property
    def error(self) -> str | None:
        """Why the summary cannot be written (the command reports it), or None."""
        return self._core.error

    @property
    def read_only(self) -> bool:
        """It cannot be written because the output folder is read-only."""
        return self._core.read_only

    @property
    def notes(self) -> list[str]:
        """What to tell the user about the file (an earlier summary's failures not listed again)."""
        return list(self._core.notes)

    def given(self, inputs) -> None:
        """This run's inputs, as its rows' ``input`` cells name them: a run
        that starts the file afresh keeps an earlier run's failed rows of
        every other input (docs/OUTPUTS.md "summary.csv")."""
        self._core.given([os.fspath(i) for i in inputs])

    def add(self, row: dict) -> None:
        """One input's row (a ``uwhl_rs.tasks`` row)."""
        self._core.add({k: v for k, v in row.items() if k in CSV_COLUMNS or k == "scores"})

    def close(self) -> None:
        self._core.close()


# ------------------------------------------------------------------ sidecars


@dataclass
class Photo:
    """One restored input, as its sidecar tells."""

    sidecar: str  # path, relative to OUTDIR, /-separated
    doc: dict
    modified: float | None = None  # when the sidecar was written (seconds since the epoch)

    @property
    def folder(self) -> str:
        return posixpath.dirname(self.sidecar)

    def output(self, role: str) -> str | None:
        """The path of an output (``image``, ``transmission_color``, ...),
        relative to OUTDIR, or None."""
        name = (self.doc.get("outputs") or {}).get(role)
        return None if not name else posixpath.join(self.folder, name)

    @property
    def flags(self) -> list[str]:
        return [f for f in self.doc.get("flags") or [] if f not in ROUTINE_FLAGS]


#: the longest line of summary.csv read (a row is a few hundred bytes)
LINE_MAX = 1 << 20


def _lines(raw):
    """The lines of the binary file ``raw`` decoded as UTF-8, each at most
    :data:`LINE_MAX` bytes: a longer one is a ValueError, found without
    holding it. Decoded a line at a time (no character spans a newline
    byte), so a bad byte stops the reading at its own row."""
    while True:
        line = raw.readline(LINE_MAX)
        if not line:
            return
        if len(line) == LINE_MAX and not line.endswith(b"\n"):
            raise ValueError(f"a line over {LINE_MAX} bytes")
        yield line.decode("utf-8")


def failed_inputs(out_dir, storage_options: dict | None = None,
                  keep: int = FAILED_SHOWN) -> tuple[list[dict], int, str | None]:
    """The first ``keep`` failed rows of ``OUTDIR/summary.csv`` (inputs
    without a sidecar to show), every value text cut to ``CELL_SHOWN``
    characters, how many rows failed in all, and why the summary was not
    read to its end (None: it was, or there is none). A summary that
    cannot be read from some row on (a line or field too long, bytes not
    UTF-8, more than ``SUMMARY_ROWS_MAX`` rows) keeps the failures before
    it; one that cannot be opened (a FIFO, a link, over
    ``SUMMARY_MAX_BYTES``) gives none, and says so. The rows are read one
    by one: a summary of a million failures is not held in memory, nor
    put whole on a page."""
    folder = out_dir if isinstance(out_dir, Folder) else Folder(out_dir, storage_options)
    rows, total, n, why = [], 0, 0, None
    try:
        # streamed: the file (or its private copy off object storage) is decoded a block at a time, and a line
        # over LINE_MAX or a field past csv's own limit (128 KiB) ends the reading: a planted 512 MiB summary
        # took 6 GB read whole
        with folder.open(FILE_NAME, SUMMARY_MAX_BYTES) as raw:
            reader = csv.reader(_lines(raw))
            header = next(reader, [])
            status = header.index("status") if "status" in header else None
            for row in reader:
                n += 1
                if n > SUMMARY_ROWS_MAX:
                    raise ValueError(f"more than {SUMMARY_ROWS_MAX} rows")
                if status is not None and status < len(row) and row[status] == "failed":
                    total += 1
                    if len(rows) < keep:
                        rows.append(dict(zip(header, row)))
    except FileNotFoundError:
        return [], 0, None
    except (OSError, ValueError, csv.Error) as e:
        said = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        where = f"from row {n + 1} on" if n else "at all"
        why = f"{display(folder.path(FILE_NAME))}: not read {where} ({display(said)[:200]})"

    def cell(v) -> str:
        t = display(summary_cell(v)) if isinstance(v, str) else ""
        return t if len(t) <= CELL_SHOWN else t[:CELL_SHOWN - 1] + "\u2026"
    # a short row lacks its missing cells, a long one's extra cells have no column
    return [{k: cell(v) for k, v in r.items()} for r in rows], total, why


class Digests:
    """The SHA-256 of each input a report run has hashed: a local file by
    its identity (device, inode, size, modification time), a stored one by
    its URL. Sidecars naming the same file, planted ones too, then cost one
    read of it per run, not one each. Safe across the run's threads: a
    thread asking for a file another is hashing waits for its answer."""

    def __init__(self):
        self._lock = threading.Lock()
        self._known: dict = {}
        self._busy: dict = {}

    def of_file(self, f) -> str:
        """The SHA-256 of the open local file ``f`` (read from where it
        stands when not known; the caller seeks back)."""
        st = os.fstat(f.fileno())
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
        with self._lock:
            one = self._busy.setdefault(key, threading.Lock())
        with one:
            with self._lock:
                known = self._known.get(key)
            if known is None:
                known = sha256_of(f)
                with self._lock:
                    self._known[key] = known
        return known

    def of_url(self, url: str) -> str | None:
        """The SHA-256 a stored input had when fetched this run, or None."""
        with self._lock:
            return self._known.get(("url", url))

    def fetched(self, url: str, digest: str) -> None:
        """Remembers what ``url`` held when fetched."""
        with self._lock:
            self._known[("url", url)] = digest


#: bytes of sidecars fetched together off object storage (by their listed sizes)
READ_BATCH_BYTES = 64 << 20


def _read_each(folder: Folder, listed: list):
    """(rel, when, bytes or the error reading raised) for each of
    ``listed``, in order: a local folder's files one at a time, object
    storage's fetched together in batches of at most READ_BATCH_BYTES by
    their listed sizes, so that many large planted ``.json`` files are not
    held at once."""
    if not folder.is_url:
        for rel, when in listed:
            try:
                data = folder.read(rel, SIDECAR_MAX_BYTES)
            except OSError as e:
                data = e
            yield rel, when, data
        return
    sizes = [min(folder.listed_size(rel) or 0, SIDECAR_MAX_BYTES + 1) for rel, _ in listed]
    start = 0
    while start < len(listed):
        end, size = start, 0
        while end < len(listed) and (end == start or size + sizes[end] <= READ_BATCH_BYTES):
            size += sizes[end]
            end += 1
        got = folder.read_many([rel for rel, _ in listed[start:end]], SIDECAR_MAX_BYTES)
        for rel, when in listed[start:end]:
            yield rel, when, got.pop(rel)
        start = end


def collect_sidecars(out_dir, storage_options: dict | None = None, *,
                     listed: list[tuple[str, float | None]] | None = None) -> tuple[list[Photo], list[str]]:
    """Every sidecar under ``out_dir`` (a local folder, a storage URL or a
    ``storage.Folder``; hidden entries skipped), checked
    (``uwhl_rs.sidecars``), in path order, and the problems: one line per
    ``.json`` file that cannot be read or is a malformed sidecar. JSON
    files of other programs are left alone. ``listed``: the folder's files
    as ``Folder.files`` gives them, when already listed."""
    folder = out_dir if isinstance(out_dir, Folder) else Folder(out_dir, storage_options)
    if listed is None:
        listed = folder.files()
    listed = [(rel, when) for rel, when in listed if rel.endswith(".json") and rel not in OWN_JSON]
    photos, problems = [], []
    for rel, when, data in _read_each(folder, listed):
        where = display(folder.path(rel))
        if isinstance(data, Exception):
            why = data.strerror if isinstance(data, OSError) and data.strerror else str(data)
            problems.append(f"{where}: cannot read ({display(why)})")
            continue
        try:
            doc = parse_sidecar(data)
            # a backslash is a name's own character on object storage and POSIX, a separator on Windows
            why = None if doc is None or folder.is_url else local_outputs_problem(doc)
            if why:
                raise SidecarError(why)
            if doc is not None:
                _own_outputs(rel, doc)
        except SidecarError as e:
            problems.append(f"{where}: not a usable sidecar: {display(str(e))}")
            continue
        if doc is not None:
            photos.append(Photo(rel, doc, when))
    return photos, problems


def _own_outputs(rel: str, doc: dict) -> None:
    """Raises :class:`SidecarError` when the sidecar at ``rel`` lists an
    output that is not its own: both commands write NAME.json beside
    NAME.jpg, NAME_t.png and the rest (``_core.is_output_of``), so a
    ``a.json`` naming ``blue.jpg`` was planted, and taking it would hand
    blue.jpg another image UUID and history in the report and the iFDO."""
    name = posixpath.basename(rel)[: -len(".json")]
    for role, value in (doc.get("outputs") or {}).items():
        if isinstance(value, str) and not _core.is_output_of(name, value):
            raise SidecarError(f"outputs.{role} is {display(value)!r}, not an output of its own name "
                               f"{display(name)!r} (NAME.json lists NAME.jpg, NAME_t.png, ...)")


def earlier_objects(fs, dest: dict, storage_options: dict) -> list[str]:
    """The objects (``fs``'s paths) an ``--overwrite`` on object storage
    removes with the earlier sidecar at ``dest["sidecar"]`` (``dest``: role
    -> URL of this run's outputs): those it lists that this run does not
    write (``_core.listed_outputs``: the input's name plus a suffix the
    commands write), none that is another input's (its own sidecar there).
    As ``Claim::commit`` does in a folder."""
    try:
        text = read_bytes(dest["sidecar"], storage_options, limit=SIDECAR_MAX_BYTES)
    except (OSError, ValueError):
        return []
    name = os.path.basename(dest["sidecar"])[: -len(".json")]
    written = {os.path.basename(v) for v in dest.values()}
    folder = os.path.dirname(dest["sidecar"])
    out = []
    for n in _core.listed_outputs(name, text):
        own_side = join(folder, os.path.splitext(n)[0] + ".json")
        if n in written or (own_side != dest["sidecar"] and fs.exists(filesystem(own_side, storage_options)[1])):
            continue
        out.append(filesystem(join(folder, n), storage_options)[1])
    return out


def remove_earlier(fs, side: str, dest: dict, storage_options: dict) -> None:
    """An ``--overwrite`` on object storage: the earlier sidecar at ``side``
    is deleted, then the objects it listed that this run does not write
    (:func:`earlier_objects`; best effort, as in a folder)."""
    extra = earlier_objects(fs, dest, storage_options)
    try:
        fs.rm_file(side)
    except FileNotFoundError:
        pass
    for p in extra:
        try:
            fs.rm_file(p)
        except OSError:
            pass


#: the names an input on object storage tries (``NAME``, ``NAME_2``, ...), as a claim in a folder does
MAX_NAMES = _core.MAX_NAMES
#: the bytes of earlier sidecars fetched at once while a batch is planned
PLAN_READ_BYTES = 64 << 20


def _recorded(data: object) -> tuple | None:
    """What a sidecar's bytes say of its input: (``input``,
    ``input_resolved`` or None, ``metadata.input_sha256`` or None); None
    when they are no sidecar. Nothing else of the document is kept."""
    try:
        doc = json.loads(data) if isinstance(data, bytes) and len(data) <= SIDECAR_MAX_BYTES else None
    except (ValueError, RecursionError):
        return None
    if not isinstance(doc, dict) or not isinstance(doc.get("input"), str):
        return None
    resolved = doc.get("input_resolved")
    md = doc.get("metadata")
    sha = md.get("input_sha256") if isinstance(md, dict) else None
    return (doc["input"], resolved if isinstance(resolved, str) and resolved.startswith("/") else None,
            sha.lower() if is_sha256(sha) else None)


def _same_object(given: str, input: str, storage_options: dict) -> bool:
    """Whether the recorded URL ``given`` names the object of the input URL
    ``input``: equal, or equal once the input's own file system strips
    its protocol (``memory:///x`` and ``memory://x``). No file system is
    made from the recorded text (a chained URL could reach any host), and
    a chained URL (``::``) is compared as it is."""
    if given == input:
        return True
    if "::" in given or "::" in input or not is_url(given) or scheme(given) != scheme(input):
        return False
    fs, path = filesystem(input, storage_options)
    try:
        return type(fs)._strip_protocol(given).rstrip("/") == path.rstrip("/")
    except Exception:  # a recorded URL the input's file system cannot read
        return False


def _records(rec: tuple | None, input: str, hashes: dict, storage_options: dict) -> bool:
    """Whether the sidecar that says ``rec`` is ``input``'s (:func:`_match`)."""
    return _match(rec, input, hashes, storage_options) is not None


def _match(rec: tuple | None, input: str, hashes: dict, storage_options: dict) -> str | None:
    """Whether the sidecar that says ``rec`` (:func:`_recorded`) is the
    restoration of ``input`` (a URL or a local path as the batch was given
    it), as ``commit::sidecar_is_inputs`` decides in a folder: a URL by
    naming its object; a local file by its resolved path where the sidecar
    records one, by its absolute path, or by the contents (its SHA-256,
    the only thing a relative path recorded by a run in another folder
    says). A stored input is never fetched to be hashed: another spelling
    of its URL is restored again under the next name. ``hashes`` keeps
    each local input's hash once computed. Returns ``"named"`` (by its URL
    or path), ``"contents"`` (by the hash alone) or None."""
    if rec is None:
        return None
    given, resolved, want = rec
    if is_url(input):
        return "named" if _same_object(given, input, storage_options) else None
    if is_url(given) or "\0" in given or "\0" in (resolved or ""):
        return None
    if _core.sidecar_names_input(given, resolved, want is not None, local_path(input)):
        return "named"
    if want is None:
        return None
    if input not in hashes:
        try:
            with open(local_path(input), "rb") as f:
                hashes[input] = sha256_of(f)
        except OSError:  # unreadable now: its own task says why
            hashes[input] = None
    return "contents" if hashes[input] == want else None


def folder_done(items: list) -> list:
    """The items (of a batch into local folders) whose planned sidecar
    records them (:func:`_match`: by path, or by the bytes' hash), read
    once each; what a cluster's batch settles as skipped without a task.
    Another input's sidecar at the name is not this one's: its claim then
    finds it a name (``commit::claim``)."""
    hashes: dict = {}
    done = []
    for it in items:
        try:
            data = read_regular(os.path.join(it.out_dir, it.name + ".json"), SIDECAR_MAX_BYTES)
        except (OSError, ValueError):
            continue
        if _records(_recorded(data), it.input, hashes, {}):
            done.append(it)
    return done


def _family(it, key, existing: dict) -> list:
    """The names other than its planned one that a batch may have given
    ``it`` (``_core.name_bases``: ``S``, ``S_E``, each followed by ``_2``,
    ``_3``, ...) that hold a sidecar in ``existing``, each sequence until
    ``_core.FAMILY_GAP`` names in a row hold none, as (name, sidecar key)."""
    out = []
    for base in _core.name_bases(it.input.rstrip("/")):
        missing = 0
        for k in range(1, MAX_NAMES + 1):
            name = base if k == 1 else f"{base}_{k}"
            side = key(it, name)
            if side not in existing:
                missing += 1
                if missing > _core.FAMILY_GAP:
                    break
                continue
            missing = 0
            if name != it.name:
                out.append((name, side))
    return out


def stored_names(items: list, existing: dict, storage_options: dict) -> tuple[list, list]:
    """Names on object storage the way a folder's claims give them
    (docs/OUTPUTS.md "Names already in use"): an input whose ``NAME.json``
    at the destination records another input (an earlier batch of another
    dive into the same prefix) takes the first of ``NAME_2``, ``NAME_3``,
    ... that is free or records it, so that neither is skipped as done nor
    written over the other's outputs. ``items``: the batch's ``Item``s
    (their ``name`` changed in place); ``existing``: the destination's
    objects (file system paths) and their sizes (None if not listed).
    Returns the items whose sidecar records them (done, unless
    overwritten), and (item, reason) for those that found no name.

    The sidecars of one name level are fetched together (ranged reads of
    at most the sidecar limit, :data:`PLAN_READ_BYTES` at a time), and of
    each only what names its input is kept."""
    if not items:
        return [], []
    fs = filesystem(items[0].out_dir, storage_options)[0]

    def key(it, name: str) -> str:
        return filesystem(join(it.out_dir, name + ".json"), storage_options)[1]

    def read(paths: list[str]) -> dict:
        # what is larger than any sidecar, or empty, records nothing
        todo = [p for p in paths if existing.get(p) is None or 0 < existing[p] <= SIDECAR_MAX_BYTES]
        got: dict = {}
        i = 0
        while i < len(todo):
            j, size = i, 0
            while j < len(todo) and (j == i or size + (existing.get(todo[j]) or SIDECAR_MAX_BYTES) <= PLAN_READ_BYTES):
                size += existing.get(todo[j]) or SIDECAR_MAX_BYTES
                j += 1
            part, i = todo[i:j], j
            data = fs.cat_ranges(part, 0, SIDECAR_MAX_BYTES + 1, on_error="return")
            got.update((p, _recorded(d)) for p, d in zip(part, data))
        return got

    hashes: dict = {}
    done, refused = [], []
    # an earlier batch may have named an input otherwise (it held other
    # inputs of its stem, or in another order): its sidecar there decides,
    # as commit::earlier_name does in a folder
    # (by its name only: a sidecar of another file with the same bytes is
    # that file's, which an --overwrite would write over)
    family = {id(it): _family(it, key, existing) for it in items}
    planned = {id(it): key(it, it.name) for it in items}
    recs = read(sorted({side for v in family.values() for _, side in v} | {p for p in planned.values() if p in existing}))
    found: dict = {}
    for it in items:
        if _match(recs.get(planned[id(it)]), it.input, hashes, storage_options) == "named":
            continue
        for name, side in family[id(it)]:
            if (it.out_dir, name) not in found and _match(recs.get(side), it.input, hashes, storage_options) == "named":
                found[(it.out_dir, name)] = it
                break
    placed = {id(it): name for (_, name), it in found.items()}
    taken = {(it.out_dir, placed.get(id(it), it.name)) for it in items}
    for it in items:
        if id(it) in placed:
            it.name = placed[id(it)]
            done.append(it)
    # the items still looking for a name, each at its next candidate (the
    # planned name first, unless an input found its own there)
    looking = [(it, it.name, 2 if (it.out_dir, it.name) in found else 1) for it in items if id(it) not in placed]
    for i, (it, base, n) in enumerate(looking):
        while n > 1 and n <= MAX_NAMES and (it.out_dir, f"{base}_{n}") in taken:
            n += 1
        looking[i] = (it, base, n)
    refused = [(it, f"{base}.json and the further names are other inputs': no name is left for its outputs")
               for it, base, n in looking if n > MAX_NAMES]
    looking = [x for x in looking if x[2] <= MAX_NAMES]
    while looking:
        paths = {}
        for it, base, n in looking:
            name = base if n == 1 else f"{base}_{n}"
            paths[id(it)] = (name, key(it, name))
        recs = read(sorted({p for _, p in paths.values() if p in existing}))
        after = []
        for it, base, n in looking:
            name, side = paths[id(it)]
            if side in existing and not _records(recs.get(side), it.input, hashes, storage_options):
                # another input's name: the next one this batch has not given
                m = n + 1
                while m <= MAX_NAMES and (it.out_dir, f"{base}_{m}") in taken:
                    m += 1
                if m > MAX_NAMES:
                    refused.append((it, f"{base}.json and the further names at the destination are other inputs' "
                                        "sidecars: no name is left for its outputs"))
                else:
                    after.append((it, base, m))
                continue
            if side in existing:
                done.append(it)
            if name != it.name:
                taken.add((it.out_dir, name))
                it.name = name
        looking = after
    return done, refused


def sidecar_seconds(sidecar: dict, wall: float) -> float:
    """A done row's time: its sidecar's ``seconds.total``, as the binary's
    summary gives it, else ``wall``, the time the task took."""
    total = (sidecar.get("seconds") or {}).get("total")
    return total if isinstance(total, (int, float)) and not isinstance(total, bool) else round(wall, 4)
