"""``uwhl ifdo OUTDIR`` (and ``restore --ifdo``): the batch's iFDO file
(``uwhl_rs.ifdo``, docs/OUTPUTS.md "iFDO")."""

from __future__ import annotations

import argparse
import os

from ..errors import BatchError, CommandError, IfdoError, describe
from ..ifdo import load_header, write_ifdo
from ..ifdocheck import uri_problem
from ..storage import is_url, parse_storage_options
from ..console import Console

__all__ = ["run", "write", "file_format"]


def file_format(header_path: str) -> str:
    """ifdo.json beside a JSON header file, ifdo.yaml otherwise."""
    return "json" if header_path.lower().endswith(".json") else "yaml"


def write(out_dir: str, header: dict, console: Console, *, handle_base: str | None = None,
          file_format: str | None = None, storage_options: dict | None = None,
          refused: str = "bad_arguments") -> int:
    """Writes the iFDO of ``out_dir`` (a folder or a storage URL) with the
    ``header`` fields and says what it holds; raises a CommandError naming
    the folder when it cannot, of kind ``refused`` when the header and the
    photos lack a field (``write_failed`` after a batch, whose photos are
    written: docs/CLI.md exit codes)."""
    if not is_url(out_dir) and not os.path.isdir(out_dir):
        raise CommandError("no such folder", "unreadable_input", out_dir)
    try:
        done = write_ifdo(out_dir, header, handle_base=handle_base, file_format=file_format,
                          storage_options=storage_options)
    except IfdoError as e:
        raise CommandError(f"no iFDO written: {e}", refused, out_dir) from e
    except BatchError as e:
        raise CommandError(f"cannot write the iFDO: {e}", e.kind, out_dir) from e
    except OSError as e:
        raise CommandError(f"cannot write the iFDO: {describe(e)}", "write_failed", out_dir) from e
    console.line(f"ifdo: {done['path']} ({done['items']} photos)")
    for n in done["notes"][:20]:
        console.line(f"  note: {n}")
    if len(done["notes"]) > 20:
        console.line(f"  ... and {len(done['notes']) - 20} more notes")
    return 0


def run(a: argparse.Namespace, console: Console) -> int:
    """``uwhl ifdo``: the exit status."""
    so = parse_storage_options(a.storage_option)
    # every item's image-handle is this base and a path: a bad base is the command's, said once
    bad = None if a.handle_base is None else uri_problem(a.handle_base + "x")
    if bad:
        raise CommandError(f"--handle-base {a.handle_base}: {bad}", "bad_arguments")
    header = load_header(a.header)
    return write(a.out, header, console, handle_base=a.handle_base, file_format=a.format or file_format(a.header),
                 storage_options=so or None)
