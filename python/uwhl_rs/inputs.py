"""A batch's inputs: the files, folders and glob patterns given, expanded
into jobs (input, output folder, output name) by the rules both commands
share (docs/OUTPUTS.md "Names"); the naming itself is the core's
(``_core.collect_jobs``, ``_core.name_jobs``)."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from . import _core
from .files import output_suffixes
from .images import IMAGE_EXTENSIONS, RAW_EXTENSIONS
from .video import VIDEO_EXTENSIONS

__all__ = ["Job", "GLOB_CHARS", "supported", "collect_inputs"]

#: what makes an input a glob pattern (when no file has that name)
GLOB_CHARS = re.compile(r"[*?\[]")


@dataclass
class Job:
    """One input and where its outputs go."""

    path: str
    out_dir: str
    name: str


def supported(path: str) -> bool:
    """Whether ``path``'s extension is one a folder walk or a glob takes
    (an image, a raw file or a video)."""
    ext = os.path.splitext(path)[1].lower()
    return ext in IMAGE_EXTENSIONS or ext in RAW_EXTENSIONS or ext in VIDEO_EXTENSIONS


def _glob(pattern: str) -> list[str]:
    """The paths ``pattern`` matches, as :func:`glob.glob` gives them
    (``**`` any depth, files and folders; a name starting with a dot only
    when the pattern spells one; the pattern's own leading part kept as
    written, ``./`` too), but ``**`` never descends through a link to a
    folder: two links back to a parent made the search grow without end,
    and a link out of the tree took files a walk of the same folder does
    not."""
    parts = pattern.split(os.sep)
    first = next((k for k, p in enumerate(parts) if GLOB_CHARS.search(p)), len(parts))
    anchor = os.sep.join(parts[:first]) or ("" if parts[0] else os.sep)
    rest = parts[first:]
    if not rest:
        return [pattern] if os.path.lexists(pattern) else []
    if rest[-1] == "**":
        # glob.glob's trailing ** gives the files as well as the folders; pathlib's the folders only
        rest = [*rest, "*"]
    spelled = any(q.startswith(".") and q not in (".", "..") for q in rest)
    base = Path(anchor or ".")
    out = []
    for p in base.glob(os.sep.join(rest)):
        rel = p.relative_to(base).parts
        if not spelled and any(r.startswith(".") and r not in (".", "..") for r in rel):
            continue
        out.append(os.path.join(anchor, *rel) if anchor else os.path.join(*rel))
    return out


def collect_inputs(inputs: list[str], out_dir: str, fmt: str = "jpg",
                   contact: bool = False) -> tuple[list[Job], list[tuple[str, str]], list[str]]:
    """Expand files, folders (recursive) and globs into jobs.

    Glob patterns are expanded here; the rest is the core's one discovery
    and naming, which uwhl-rs uses too (``_core.collect_jobs``): files under
    ``out_dir`` are never taken as inputs, the same file named twice is
    processed once, and two inputs that would share an output name get
    ``NAME_ext`` (then ``NAME_ext_2``, ... if still shared), and no output
    file of one input (``fmt``, ``contact``) is another's; an earlier run's
    output folder met in a walk is not searched. Returns (jobs, problems,
    notes): problems are (input, reason) for inputs that match nothing,
    notes the folders not searched.
    """
    items: list[str] = []
    problems: list[tuple[str, str]] = []
    for item in inputs:
        if not os.path.exists(item) and GLOB_CHARS.search(item):
            hits = sorted(h for h in _glob(item) if os.path.isfile(h) and supported(h))
            if not hits:
                problems.append((item, "pattern matches no image file"))
            items.extend(hits)
        else:
            items.append(item)
    found, missing, notes = _core.collect_jobs(items, out_dir, output_suffixes(fmt, contact))
    problems += [(str(p), why) for p, why in missing]
    return [Job(str(p), str(d), name) for p, d, name in found], problems, notes
