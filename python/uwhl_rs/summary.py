"""``OUTDIR/summary.csv``: one row per input of a batch, written as the
batch goes (each row flushed when its input is settled), so an interrupted
run keeps what it did (docs/OUTPUTS.md "summary.csv").

Rows are the dicts of ``uwhl_rs.batch`` (its ``COLUMNS``); the local run
of ``uwhl restore`` makes the same rows with :func:`row_from_sidecar`.
"""

from __future__ import annotations

import csv
import json
import os
import threading

__all__ = ["SummaryWriter", "CSV_COLUMNS", "row_fields_from_sidecar", "FILE_NAME"]

FILE_NAME = "summary.csv"

#: the Jerlov types, one score column each (custom types go to other_scores)
_TYPES = ("I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C")

#: the columns of summary.csv, in order
CSV_COLUMNS = (["input", "status", "water_type", "A_R", "A_G", "A_B"] + [f"score_{t}" for t in _TYPES]
               + ["other_scores", "flags", "seconds", "taken_at", "latitude", "longitude", "altitude", "image",
                  "transmission", "transmission_color", "contact_sheet", "sidecar", "error_kind", "error",
                  "exit_code"])


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


def _text(v) -> object:
    """A field: None empty; undecodable bytes of a file name (surrogate
    escapes) as U+FFFD, as uwhl-rs writes them."""
    if v is None:
        return ""
    if isinstance(v, str):
        return v.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    return v


class SummaryWriter:
    """Appends one row per settled input to ``OUTDIR/summary.csv``,
    flushing each (the file is started afresh by each run; skipped inputs
    get their row from their sidecar, so it always covers every input)."""

    def __init__(self, out_dir: str):
        self.out_dir = out_dir
        self.path = os.path.join(out_dir, FILE_NAME)
        #: why the summary cannot be written (the command reports it), or None
        self.error = None
        self._lock = threading.Lock()  # --jobs N settles inputs from N threads
        self._f = None
        self._opened = False

    def _open(self) -> None:
        """Made with the first row: a run refused before any input leaves no file."""
        self._opened = True
        try:
            os.makedirs(self.out_dir, exist_ok=True)
            self._f = open(self.path, "w", newline="", encoding="utf-8")
            self._w = csv.DictWriter(self._f, fieldnames=CSV_COLUMNS, extrasaction="ignore")
            self._w.writeheader()
            self._f.flush()
        except OSError as e:
            self._fail(e)

    def _fail(self, e: OSError) -> None:
        self.error = f"cannot write {self.path}: {e.strerror or e}"
        if self._f is not None:
            try:
                self._f.close()
            except OSError:
                pass
        self._f = None

    def add(self, row: dict) -> None:
        """One input's row (a ``uwhl_rs.batch`` row): a skipped input's
        fields come from its sidecar when the row lacks them."""
        r = dict(row)
        if r.get("status") == "skipped" and r.get("water_type") is None:
            side = _read_sidecar(r.get("sidecar"))
            if side is not None:
                r.update(row_fields_from_sidecar(side))
                outs = side.get("outputs") or {}
                folder = os.path.dirname(r["sidecar"])
                for role in ("image", "transmission", "transmission_color", "contact_sheet"):
                    if outs.get(role):
                        r[role] = os.path.join(folder, outs[role])
        scores = r.pop("scores", None) or {}
        for t in _TYPES:
            r[f"score_{t}"] = scores.get(t)
        other = {k: v for k, v in scores.items() if k not in _TYPES}
        r["other_scores"] = json.dumps(other) if other else None
        with self._lock:
            if not self._opened:
                self._open()
            if self._f is None:
                return
            try:
                self._w.writerow({k: _text(v) for k, v in r.items()})
                self._f.flush()
            except OSError as e:
                self._fail(e)

    def close(self) -> None:
        with self._lock:
            if self._f is not None and not self._f.closed:
                try:
                    self._f.close()
                except OSError as e:
                    self._fail(e)
