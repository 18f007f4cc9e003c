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
from dataclasses import dataclass

from . import _core
from .storage import Folder

__all__ = ["SummaryWriter", "CSV_COLUMNS", "row_fields_from_sidecar", "summary_cell", "FILE_NAME", "REPORT_DIR", "Photo",
           "collect_sidecars", "failed_inputs"]

FILE_NAME = "summary.csv"

#: the report's folder inside OUTDIR (never searched for sidecars)
REPORT_DIR = "report"

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
            "taken_at": meta.get("taken_at"), "latitude": gps.get("latitude"), "longitude": gps.get("longitude"),
            "altitude": gps.get("altitude")}


def _read_sidecar(path: str | None) -> dict | None:
    if not path or not os.path.exists(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
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

    def __init__(self, out_dir: str):
        self.out_dir = out_dir
        self._core = _core.Summary(out_dir)
        self.path = os.fspath(self._core.path)

    @property
    def error(self) -> str | None:
        """Why the summary cannot be written (the command reports it), or None."""
        return self._core.error

    @property
    def read_only(self) -> bool:
        """It cannot be written because the output folder is read-only."""
        return self._core.read_only

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


def failed_inputs(out_dir, storage_options: dict | None = None) -> list[dict]:
    """The failed rows of ``OUTDIR/summary.csv`` (inputs without a sidecar
    to show), or none when there is no summary."""
    folder = out_dir if isinstance(out_dir, Folder) else Folder(out_dir, storage_options)
    try:
        text = folder.read(FILE_NAME).decode("utf-8")
        return [r for r in csv.DictReader(text.splitlines()) if r.get("status") == "failed"]
    except (OSError, ValueError, csv.Error):
        return []


def _is_sidecar(doc) -> bool:
    return isinstance(doc, dict) and "water_type" in doc and isinstance(doc.get("outputs"), dict) and "input" in doc


def collect_sidecars(out_dir, storage_options: dict | None = None, *,
                     listed: list[tuple[str, float | None]] | None = None) -> tuple[list[Photo], list[str]]:
    """Every sidecar under ``out_dir`` (a local folder, a storage URL or a
    ``storage.Folder``; the report's own folder and hidden entries skipped),
    in path order, and the problems (unreadable ones). ``listed``: the
    folder's files as ``Folder.files`` gives them, when already listed."""
    folder = out_dir if isinstance(out_dir, Folder) else Folder(out_dir, storage_options)
    if listed is None:
        listed = folder.files(skip_top=(REPORT_DIR,))
    listed = [(rel, when) for rel, when in listed if rel.endswith(".json")]
    got = folder.read_many([rel for rel, _ in listed])
    photos, problems = [], []
    for rel, when in listed:
        data = got.pop(rel)  # each document parsed, its bytes let go
        try:
            if isinstance(data, Exception):
                raise data
            doc = json.loads(data)
        except (OSError, ValueError) as e:
            problems.append(f"{folder.path(rel)}: cannot read ({type(e).__name__}: {e})")
            continue
        if _is_sidecar(doc):
            photos.append(Photo(rel, doc, when))
    return photos, problems
