"""The ``uwhl`` command (also ``python -m uwhl_rs``).

``uwhl restore INPUT... -o OUTDIR`` restores files, folders (recursively)
and globs, writing per input the corrected photo, the transmission maps
and a JSON sidecar (docs/OUTPUTS.md), a line per input, a summary and a
non-zero exit status when any input failed; ``uwhl report``, ``uwhl
ifdo``, ``uwhl evaluate`` and ``uwhl demo`` are the other commands, one
module each. Everything written to the streams is :mod:`.console`'s;
:func:`main` is the one place where an exception becomes its message and
exit status (docs/CLI.md "Exit codes").
"""

from __future__ import annotations

import argparse

from . import demo, evaluate, ifdo, report, restore
from .. import _core
from ..console import Console
from ..errors import kind_of
import sys

from .parser import attach_values, build_parser, usage_errors_as_json

__all__ = ["main", "build_parser"]

_COMMANDS = {"restore": restore.run, "demo": demo.run, "report": report.run, "ifdo": ifdo.run,
             "evaluate": evaluate.run}


def _binary_only(argv: list[str]) -> str | None:
    """The first flag of ``argv`` that only the binary takes (the table's
    "rust" face: --stream, --raw-frames, ...), or None."""
    flags = {o["flag"] for o in _core.OPTIONS if o["faces"] == "rust"}
    for tok in argv:
        if tok == "--":
            break
        if tok.split("=", 1)[0] in flags:
            return tok.split("=", 1)[0]
    return None


def _stop_on_sigterm() -> None:
    """SIGTERM (how batch systems and ``timeout`` stop a job) stops the
    command as SIGINT does: the input being written finishes, exit 130,
    nothing half-written stays. Only where SIGTERM still has its default
    (a program that embeds the command keeps its own handler)."""
    import signal

    def stop(signum, frame):
        raise KeyboardInterrupt

    try:
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, stop)
    except (ValueError, AttributeError, OSError):
        pass  # not the main thread, or no SIGTERM on this platform


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``uwhl`` command; returns the exit status."""
    _stop_on_sigterm()
    p = build_parser()
    args = list(sys.argv[1:] if argv is None else argv)
    usage_errors_as_json(args)
    flag = _binary_only(args)
    sub = next((t for t in args if not t.startswith("-")), None)
    if flag is not None and sub == "restore":
        # as uwhl-rs names the command that has an option of the Python
        # command's; in restore's words (and JSON with --json-errors)
        restore_parser = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction)).choices["restore"]
        restore_parser.error(f"{flag} is an option of the binary only: run 'uwhl-rs restore' (docs/CLI.md)")
    a = p.parse_args(attach_values(args))
    if a.cmd == "demo":
        try:
            h, w = (int(v) for v in a.size.lower().split("x"))
        except ValueError:
            p.error(f"--size must look like 480x640, not {a.size!r}")
        if h < 4 or w < 4:
            p.error(f"--size must be at least 4x4, not {a.size!r}")
        a.size = (h, w)
    console = Console(quiet=getattr(a, "quiet", False), json_errors=getattr(a, "json_errors", False))
    try:
        return _COMMANDS[a.cmd](a, console)
    except (Exception, MemoryError, KeyboardInterrupt) as e:
        code = console.failure(e)
        if kind_of(e) == "bad_arguments" and not console.json_errors:
            # where to look, after a usage error found past the parser (options that do not go together), as uwhl-rs says
            console._write(console.err, f"Try 'uwhl {a.cmd} --help'.")
        return code
