"""One error model for the package: every failure has a *kind*, the name of
its exit code in the core's table (docs/CLI.md "Exit codes"), set where it
is raised.

All the package's exceptions derive from the core's
:class:`uwhl_rs.UwhlError` (itself a ValueError), and keep their builtin
bases, so ``except ValueError`` keeps catching what it caught. Errors that
do not come from the package (a full disk, a failed allocation, a bug) get
their kind from :func:`kind_of`.
"""

from __future__ import annotations

import math
import numbers
import re

from ._core import EXIT_CODES, ImageError, ParameterError, UwhlError

__all__ = [
    "EXIT",
    "UwhlError",
    "ImageError",
    "ParameterError",
    "CommandError",
    "ImageReadError",
    "ImageTooLargeError",
    "BatchError",
    "IfdoError",
    "ManifestError",
    "kind_of",
    "describe",
    "shown",
    "compact_numbers",
]

#: exit statuses, shared with uwhl-rs (docs/CLI.md): {name: code}
EXIT: dict[str, int] = {name: code for code, name, _ in EXIT_CODES}

class CommandError(UwhlError):
    """A failure that ends a command (or one input of a batch): its
    message, its ``kind`` (an exit-code name) and the input or folder it
    is about, if any."""

    kind = "internal"

    def __init__(self, message: str, kind: str | None = None, input: str | None = None):
        super().__init__(message)
        if kind is not None:
            if kind not in EXIT:
                raise ValueError(f"unknown error kind {kind!r}; the kinds are {', '.join(EXIT)}")
            self.kind = kind
        self.input = input


class ImageReadError(UwhlError):
    """A file could not be read as an image (missing, truncated, corrupt,
    unsupported or too large). The message names the file and the reason."""

    kind = "unreadable_input"


class ImageTooLargeError(ImageReadError):
    """The image is over the pixel budget (``max_pixels``), the memory
    budget, or what the system gives; the commands report it as over
    budget, not as unreadable."""

    kind = "over_budget"


class BatchError(CommandError):
    """The batch could not start: the extra is missing, the scheduler or
    the storage cannot be reached, credentials are refused (``kind``
    ``unreachable`` unless said otherwise)."""

    kind = "unreachable"


class IfdoError(UwhlError):
    """The header cannot make a valid iFDO (a field missing or ill-typed),
    or the folder holds no restored photo."""

    kind = "bad_arguments"


class ManifestError(UwhlError):
    """A manifest entry that cannot be evaluated; the message names it."""

    kind = "unreadable_input"


def kind_of(e: BaseException, writing: bool = False) -> str:
    """The kind of a failure: its own ``kind`` when it has one (every
    exception of the package, and the core's ImageError and ParameterError,
    whose kinds the core sets), else what its builtin class says (a
    MemoryError is over budget, an OSError a failed write while ``writing``
    and an unreadable input before); anything else is a bug."""
    kind = getattr(e, "kind", None)
    if isinstance(kind, str) and kind in EXIT:
        return kind
    if isinstance(e, MemoryError):
        return "over_budget"
    if isinstance(e, OSError):
        return "write_failed" if writing else "unreadable_input"
    if isinstance(e, KeyboardInterrupt):
        return "interrupted"
    return "internal"


def describe(e: BaseException, path: str | None = None) -> str:
    """The message of a failure; the input's path is said once, by the
    line that reports it, so a leading ``path: `` is left out."""
    if isinstance(e, MemoryError):
        return f"over the memory budget: {e}"
    if isinstance(e, OSError) and e.strerror:
        return f"{e.strerror}" + (f": {e.filename}" if e.filename else "")
    text = str(e) or type(e).__name__
    if path is not None and text.startswith(f"{path}: "):
        text = text[len(path) + 2:]
    return text


#: the longest repr a message shows of a value it refuses
_SHOWN_CHARS = 80


def shown(value) -> str:
    """``value`` as a message about it shows it: a number compactly
    (``1e+308``, not its 309 digits; an integer too large for a float too:
    ``1e+400``), a list or tuple by its first items, anything else by its
    repr cut to 80 characters."""
    if isinstance(value, bool) or type(value).__name__ in ("bool", "bool_"):  # numpy 1 and 2 call theirs so
        return repr(bool(value))
    if isinstance(value, numbers.Integral):
        v = int(value)
        if abs(v) < 10**15:
            return str(v)
        try:
            return f"{float(v):g}"
        except OverflowError:
            # beyond a float: its logarithm still is one (Python will not print the digits past 4300)
            lg = math.log10(abs(v))
            e = math.floor(lg)
            return f"{'-' if v < 0 else ''}{10 ** (lg - e):g}e+{e}"
    if isinstance(value, numbers.Real):
        return f"{float(value):g}"
    if isinstance(value, (list, tuple)):
        items = ", ".join(shown(x) for x in value[:4]) + (", ..." if len(value) > 4 else "")
        return f"[{items}]" if isinstance(value, list) else f"({items}{',' if len(value) == 1 else ''})"
    try:
        text = repr(value)
    except Exception:  # a repr that fails (an integer of too many digits inside, a hostile object)
        text = f"<{type(value).__name__}>"
    return text if len(text) <= _SHOWN_CHARS else text[:_SHOWN_CHARS - 3] + "..."


def compact_numbers(text: str) -> str:
    """``text`` with each number of 20 characters or more (the core prints
    some floats in full: 1e308 as 309 digits) and each in the core's
    scientific form (``1.000000e308``) written as ``{:g}``."""

    def short(m: re.Match) -> str:
        try:
            return f"{float(m.group()):g}"
        except (ValueError, OverflowError):
            return m.group()

    return re.sub(r"-?\d\.\d{6}e-?\d+|-?\d[\d.]{19,}", short, text)
