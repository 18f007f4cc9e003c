"""Everything the ``uwhl`` command (and ``restore_many(progress=True)``)
writes to its streams, from one place
(docs/CLI.md "Lines"): the progress line of each input and the summary on
stdout, errors on stderr as ``uwhl: INPUT: MESSAGE`` or, with
``--json-errors``, one JSON object a line. The texts are uwhl-rs's.
"""

from __future__ import annotations

import json
import os
import sys
import threading

from . import _core
from .errors import EXIT, CommandError, describe, kind_of
from .sidecars import display, printable
from .tasks import DONE_NOTE

__all__ = ["Console"]


class Console:
    """The command's streams. ``out`` and ``err`` default to the process's
    stdout and stderr as they are when written to; ``quiet`` keeps
    everything but errors off; ``json_errors`` writes errors as objects."""

    def __init__(self, out=None, err=None, *, quiet: bool = False, json_errors: bool = False,
                 program: str = "uwhl"):
        self._out, self._err = out, err
        self.quiet, self.json_errors, self.program = quiet, json_errors, program
        # --jobs N settles inputs from N threads: a line is written whole
        self._lock = threading.Lock()
        #: the run's options (``files.restore_file``'s keywords), so that a
        #: skipped input's line can say it was restored with others
        self.options: dict | None = None
        #: its video options as given (``videofiles.given_video_options``)
        self.video_options: dict = {}
        self._parameters: str | None = None

    @property
    def out(self):
        return self._out or sys.stdout

    @property
    def err(self):
        return self._err or sys.stderr

    def _write(self, stream, text: str) -> None:
        # a line quoting a file name cannot move the cursor or recolour the
        # terminal: control characters as \xNN, as uwhl-rs writes them.
        # A stream that is closed or full (>&-, /dev/full) loses its lines,
        # as the binary's do: the outputs and the exit code stay what the
        # inputs made them (stdout is not the command's result in batch mode)
        with self._lock:
            try:
                stream.write(printable(text) + "\n")
                stream.flush()
            except (AttributeError, OSError, ValueError):
                pass

    def line(self, text: str = "") -> None:
        """A line of the command's output (stdout), unless quiet."""
        if not self.quiet:
            self._write(self.out, text)

    def _recorded(self) -> str:
        """The run's options as a sidecar records them (JSON), made when an
        input is first skipped (settings that cannot be made: none)."""
        if self._parameters is None and self.options is not None:
            from .files import settings_of

            try:
                self._parameters = settings_of(**self.options).parameters
            except (Exception, MemoryError):  # noqa: BLE001 - only a remark is lost; each input says its own error
                self._parameters = ""
        return self._parameters or ""

    def note(self, text: str, always: bool = False) -> None:
        """A remark on stderr (``uwhl: TEXT``) that is not an error, unless
        quiet (or ``always``)."""
        if always or not self.quiet:
            self._write(self.err, f"{self.program}: {text}")

    def error(self, kind: str, message: str, input: str | None = None) -> int:
        """One error on stderr; returns its exit code."""
        code = EXIT[kind]
        if self.json_errors:
            # undecodable bytes of a name as U+FFFD, as the binary's lines: a lone surrogate's
            # escape is no character a JSON reader can give back
            text = json.dumps({"error": kind, "input": None if input is None else display(input),
                               "message": display(message), "exit_code": code})
        else:
            text = f"{self.program}: {input}: {message}" if input is not None else f"{self.program}: {message}"
        self._write(self.err, text)
        return code

    def failure(self, e: BaseException, input: str | None = None) -> int:
        """An exception as its error line (its kind and message, the input
        it names); returns its exit code."""
        if isinstance(e, KeyboardInterrupt):
            e = CommandError("interrupted; run the same command again to resume", "interrupted")
        kind = kind_of(e)
        # a bug says what it is
        message = describe(e) if kind != "internal" else f"{type(e).__name__}: {e}"
        return self.error(kind, message, input if input is not None else getattr(e, "input", None))

    def row(self, row: dict, k: int | None, total: int) -> None:
        """The line of one settled input (a ``tasks`` row): its progress
        line (``k`` of ``total``), or its error."""
        if row["status"] == "failed":
            self.error(row["error_kind"], row["error"], row["input"])
        elif row["status"] == "skipped":
            if row["error"] == DONE_NOTE:
                # the options it was restored with, when they are not this run's (as uwhl-rs says)
                p = self._recorded()
                if p and os.path.splitext(str(row["input"]))[1].lower().lstrip(".") in _core.VIDEO_EXTENSIONS:
                    p = json.dumps({**json.loads(p), **self.video_options})  # as a video's sidecar records them
                other = _core.skipped_with_other_options(row["sidecar"], p) if p else ""
                why = f"{row['sidecar']} exists{other}"
            else:
                why = row["error"]
            self.line(f"[{k}/{total}] {row['input']}: skipped ({why})")
        else:
            share = row.get("fallback_share")
            flags = [f for f in (row.get("flags") or "").split(",") if f]
            said = _core.progress_said(share if isinstance(share, float) else None, flags)
            self.line(f"[{k}/{total}] {row['input']} -> {row['image']} "
                      f"(water type {row['water_type']}{said}, {row['seconds'] or 0.0:.2f} s)")
            if row.get("error"):
                # done, but not all of it (a video that stops part way)
                self.error(row["error_kind"], row["error"], row["input"])

    def summary(self, rows: list[dict], seconds: float) -> None:
        """The batch's last line: how many inputs were done, skipped, failed."""
        n = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped", "failed")}
        self.line(f"{n['done']} done, {n['skipped']} skipped, {n['failed']} failed in {seconds:.1f} s")

    def failed_count(self, n: int) -> None:
        """After a batch in which ``n`` inputs failed (each said already)."""
        if n and not self.json_errors:
            self._write(self.err, f"{self.program}: {n} input(s) failed")
