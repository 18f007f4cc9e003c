"""``uwhl report OUTDIR`` (and ``restore --report``): the batch's page
(``uwhl_rs.report``, docs/REPORT.md)."""

from __future__ import annotations

import argparse
import os

from ..errors import BatchError, CommandError, describe
from ..report import NotAnOutputFolder, write_report
from ..storage import is_url, parse_storage_options
from ..console import Console

__all__ = ["run", "write"]


def write(out_dir: str, console: Console, storage_options: dict | None = None) -> int:
    """Writes the report of ``out_dir`` (a folder or a storage URL) and says
    what it holds; raises a CommandError naming the folder when it cannot."""
    if not is_url(out_dir) and not os.path.isdir(out_dir):
        # a FIFO or a file at that name is there, and not a folder
        raise CommandError("not a folder" if os.path.lexists(out_dir) else "no such folder", "unreadable_input", out_dir)
    try:
        done = write_report(out_dir, storage_options=storage_options)
    except BatchError as e:
        raise CommandError(f"cannot write the report: {e}", e.kind, out_dir) from e
    except NotAnOutputFolder as e:
        raise CommandError(str(e), "unreadable_input", out_dir) from None
    except FileNotFoundError:
        raise CommandError("no such folder", "unreadable_input", out_dir) from None
    except OSError as e:
        raise CommandError(f"cannot write the report: {describe(e)}", "write_failed", out_dir) from e
    videos = f"{done['videos']} video{'s' if done['videos'] != 1 else ''}, " if done.get("videos") else ""
    photos = f"{done['photos']} photo{'s' if done['photos'] != 1 else ''}"
    console.line(f"report: {done['path']} ({photos}, {videos}{done['flagged']} flagged, {done['failed']} failed, "
                 f"{done['thumbnails_written']} thumbnails written, {done['seconds']:.1f} s)")
    for p in done["problems"][:20]:
        console.line(f"  note: {p}")
    return 0


def run(a: argparse.Namespace, console: Console) -> int:
    """``uwhl report``: the exit status."""
    return write(a.out, console, parse_storage_options(a.storage_option) or None)
