"""The arguments of ``uwhl``: every subcommand's parser, the options of
the method and of ``restore`` built from the core's one option table
(``_core.OPTIONS``, the table uwhl-rs parses from too), and what the
parsed flags become (the keywords of ``restore`` and ``restore_file``).
"""

from __future__ import annotations

import argparse
import sys

import uwhl_rs

from .. import _core
from ..errors import CommandError, UwhlError
from ..sidecars import printable

__all__ = ["build_parser", "water_types", "method_kwargs", "file_kwargs", "usage_errors_as_json"]

#: every option's default in the table
_DEFAULTS = {o["key"]: o["default"] for o in _core.OPTIONS}

_EPILOG_RESTORE = _core.EXIT_CODES_HELP + """

outputs (per input NAME, in OUTDIR, mirroring sub-folders of folder inputs):
  NAME.jpg|.tif|.png   the corrected photo (sRGB)
  NAME_t.png           transmission t_B, 16-bit gray (-ln t_B is a distance proxy)
  NAME_t_color.png     transmission, colour-mapped (dark = far, yellow = near)
  NAME_confidence.png  how far the colours can be trusted, 16-bit gray (1 = fully);
                       not with --fallback none or --method paper
  NAME_sheet.png       with --contact-sheet: every water type side by side
  NAME.json            sidecar: water type, scores, A, VL size, flags, parameters,
                       version, timings; written last, it marks the input as done
Inputs whose sidecar exists are skipped unless --overwrite, so an interrupted
run resumes where it stopped. Every file is written atomically.

examples:
  uwhl restore dive_042/ -o corrected/ --jobs 2
  uwhl restore 'dive_*/**/*.NEF' -o out --format tiff --max-side 3000
  uwhl restore IMG_1620.CR2 -o out --water-type 3C --contact-sheet
"""


def _utf8(text: str) -> bool:
    """Whether ``text`` is UTF-8 (no lone surrogate: a file name's bytes that are not)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _option_type(key: str):
    """An argparse type: the core's parser of option ``key`` (the one uwhl-rs uses)."""

    def parse(text: str):
        if not _utf8(text):
            # a name of undecodable bytes (surrogates here): named with its bytes, as the binary does
            shown = "".join(f"\\x{ord(c) - 0xDC00:02X}" if 0xDC80 <= ord(c) <= 0xDCFF else c for c in text)
            raise argparse.ArgumentTypeError(f'"{printable(shown)}" is not valid UTF-8')
        try:
            return _core.parse_option(key, text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e).split(": ", 1)[-1]) from None

    return parse


#: options whose table default is applied after parsing, so that the command can tell one given
GIVEN_ONLY = ("port",)


def _add_options(parser: argparse.ArgumentParser, method_only: bool = False) -> None:
    """The options of the core's table that the Python command takes,
    grouped (``method_only``: those of the method, for ``uwhl evaluate``)."""
    groups: dict[str, argparse._ArgumentGroup] = {}
    for o in _core.OPTIONS:
        if o["faces"] == "rust" or (method_only and not o["method"]):
            continue
        g = groups.get(o["group"]) or groups.setdefault(o["group"], parser.add_argument_group(o["group"]))
        names = [o["flag"]] + ([o["short"]] if o["short"] else [])
        kw = dict(dest=o["key"], help=o["help"].replace("%", "%%"))
        if o["kind"] == "flag":
            kw["action"] = "store_true"
        elif o["kind"] == "water_types":
            kw.update(action="append", metavar=o["metavar"])
        elif o["kind"] == "key_value":
            kw.update(action="append", metavar=o["metavar"], type=_option_type(o["key"]))
        else:
            # --port's default is applied later: only a port given can be one that nothing uses (as uwhl-rs)
            default = None if o["key"] in GIVEN_ONLY else o["default"]
            kw.update(type=_option_type(o["key"]), metavar=o["metavar"], default=default)
        g.add_argument(*names, **kw)


def water_types(values: list[str] | None):
    """--water-type values: names (comma lists allowed) or NAME:BETA_BR:BETA_BG."""
    if not values:
        return None
    # the binary's parser (numbers as Rust reads them, names checked by the core, an empty list refused)
    try:
        return _core.parse_water_types(list(values))
    except UwhlError as e:
        raise CommandError(str(e), "bad_arguments") from None


def _folder(value: str) -> str:
    """An output folder's name as given: an empty one would be taken as the
    current folder, never what was meant (an unset shell variable), and
    ``-`` is stdout's name."""
    if not value:
        raise argparse.ArgumentTypeError("the output folder's name is empty (give a folder; '.' for the current one)")
    if value == "-":
        # as uwhl-rs says: a folder named "-" is never what was meant
        raise argparse.ArgumentTypeError("- (stdout) is for uwhl-rs --raw-frames; give an output folder (./- for one named so)")
    return value


def _folder_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of the subcommands that read an output folder (report, ifdo)."""
    p.add_argument("out", metavar="OUTDIR", type=_folder, help="an output folder (or URL) of uwhl restore or uwhl-rs restore")
    p.add_argument("--storage-option", action="append", default=[], metavar="KEY=VALUE",
                   help="an fsspec option for a URL OUTDIR, as for restore")
    p.add_argument("--json-errors", action="store_true", help="each error as one JSON object on stderr")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def usage_errors_as_json(args: list[str]) -> None:
    """Makes the parsers write their usage errors as JSON objects when the
    command line ``args`` holds ``--json-errors`` before any ``--``."""
    options = args[:args.index("--")] if "--" in args else args
    _Parser.json_errors = "--json-errors" in options


class _Parser(argparse.ArgumentParser):
    """argparse's parser whose usage errors go through ``printable``: they
    quote the words they do not know (a file named like an option, expanded
    by a shell glob), which must not drive the terminal or reorder the line,
    as in the binary's. Subcommands' parsers are of the same class."""

    #: set by the command line when it holds --json-errors (before any "--"): a usage error is then
    #: one JSON object, as every other error of the run and as uwhl-rs writes it
    json_errors = False

    def error(self, message):
        if _Parser.json_errors:
            import json

            obj = {"error": "bad_arguments", "input": None, "message": message, "exit_code": 2}
            self.exit(2, json.dumps(obj, ensure_ascii=True) + "\n")
        # one line and where to look, as the binary's: the usage of a command of thirty options would bury it
        self.exit(2, f"{self.prog}: error: {printable(message)}\nTry '{self.prog} --help'.\n")

    def parse_known_args(self, args=None, namespace=None):
        # A command's parser names an option it does not know first, as the
        # binary does, and takes no abbreviation of one (the binary takes
        # none): argparse would first say that -o is missing when the slip
        # is in "--output-dir" or "-x", read "--water" as one of three
        # options, take "-5" for an input, and, for an unknown word after an
        # input, say "unrecognized arguments" as the top-level "uwhl".
        if args is not None and not any(isinstance(a, argparse._SubParsersAction) for a in self._actions):
            args = self._options_first(list(args))
        return super().parse_known_args(args, namespace)

    def _options_first(self, args: list) -> list:
        """``args`` checked for options this parser does not know (a usage
        error naming the first), then reordered: the options with their
        values, then ``--`` and the positional words. argparse takes the
        inputs of ``restore`` in one run, so without it "a.jpg -o out b.jpg"
        and "a.jpg -o out -- -b.jpg" would leave b unread; uwhl-rs takes
        inputs anywhere, and everything after ``--`` as inputs."""
        options: list = []
        words: list = []
        i = 0
        while i < len(args):
            tok = args[i]
            i += 1
            if not isinstance(tok, str) or tok == "-" or not tok.startswith("-"):
                words.append(tok)
                continue
            if tok == "--":
                words.extend(args[i:])
                break
            if tok.startswith("--"):
                name = tok.split("=", 1)[0]
                action = self._option_string_actions.get(name)
                if action is None:
                    self.error(f"invalid option '{name}'")
                options.append(tok)
                if "=" not in tok and action.nargs != 0 and i < len(args):
                    options.append(args[i])
                    i += 1
                continue
            # single-dash: a cluster of short options (-qo OUT, -j4), read as uwhl-rs reads one
            for k, c in enumerate(tok[1:], start=1):
                action = self._option_string_actions.get("-" + c)
                if action is None:
                    self.error(self._unknown_short("-" + c, tok if k == 1 else None))
                if action.nargs != 0:
                    # the rest of the cluster is the value, else the next word
                    if k + 1 == len(tok) and i < len(args):
                        options.append(tok)
                        options.append(args[i])
                        i += 1
                        break
                    options.append(tok)
                    break
            else:
                options.append(tok)
        return options + (["--", *words] if words else [])

    @staticmethod
    def _unknown_short(flag: str, word: str | None) -> str:
        """The usage error of an unknown short option ``flag`` in uwhl-rs's
        words (``_core.unknown_short_said``): the whole ``word`` when the
        flag is its first letter (``-dash.mp4``, not ``-d``; ``None`` when
        it is not)."""
        return _core.unknown_short_said(flag if word is None else word)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``uwhl`` (all subcommands)."""
    p = _Parser(
        prog="uwhl",
        description="Underwater single-image color restoration with haze-lines "
        "(Berman, Levy, Avidan & Treibitz, TPAMI 2020): corrected colors, a transmission "
        "(distance proxy) map and the Jerlov water type from a raw or JPEG photograph.",
        epilog="Run 'uwhl COMMAND --help' for a command's options.",
    )
    p.add_argument("--version", action="version", version=f"uwhl_rs {uwhl_rs.__version__}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")

    r = sub.add_parser(
        "restore",
        help="restore photographs (files, folders, globs) into an output folder",
        description="Restore underwater photographs: raw (NEF, CR2, ARW, DNG, ... anything LibRaw reads), "
        "JPEG, PNG or TIFF. Folders are searched recursively; quote globs to let uwhl expand them.",
        epilog=_EPILOG_RESTORE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    r.add_argument("inputs", nargs="+", metavar="INPUT", help="image files, folders or glob patterns")
    r.add_argument("-o", "--out", "--output", dest="out", required=True, metavar="OUTDIR", type=_folder,
                   help="output folder (created if needed)")
    _add_options(r)

    d = sub.add_parser(
        "demo",
        help="restore the built-in synthetic scene and print the true vs estimated water type",
        description="Render the package's synthetic underwater scene (nothing is downloaded), restore it, "
        "write input/restored/transmission/clean_truth PNGs and report true vs estimated water type and A.",
    )
    d.add_argument("-o", "--out", "--output", dest="out", default="uwhl_demo", type=_folder, help="output folder (default: ./uwhl_demo)")
    d.add_argument("--water-type", default="III", choices=list(uwhl_rs.WATER_TYPES), help="water type to render (default III)")
    d.add_argument("--size", default="480x640", help="HxW of the scene (default 480x640)")
    d.add_argument("--seed", type=int, default=7, help="scene seed (default 7)")

    rp = sub.add_parser(
        "report",
        help="one page for a batch: thumbnails, water types, the sequence, flagged photos first",
        description="Write OUTDIR/report/index.html from the sidecars under OUTDIR (docs/REPORT.md): the "
        "flagged photos first, a histogram of the water types, water type, A and score over the sequence, and a "
        "paginated grid of before/after thumbnails (written once into OUTDIR/report/thumbs) that open the "
        "full-size photo and its transmission map.",
    )
    _folder_arguments(rp)

    fd = sub.add_parser(
        "ifdo",
        help="the iFDO file of a batch (image FAIR Digital Objects) for marine imaging platforms",
        description="Write OUTDIR/ifdo.yaml from the sidecars under OUTDIR (docs/OUTPUTS.md \"iFDO\"): the set's "
        "header (the fields of --header, the rest derived), one item per corrected photo (its image UUID, "
        "SHA-256, handle, UTC time and GPS position) and the restoration as the set's provenance.",
    )
    fd.add_argument("--header", required=True, metavar="HEADER",
                    help="YAML or JSON file of the set's iFDO fields: image-project, image-event, image-platform, "
                    "image-sensor, image-pi, image-creators, image-license, image-copyright, image-abstract, "
                    "image-context, image-coordinate-uncertainty-meters (and any other header field)")
    fd.add_argument("--handle-base", metavar="URL",
                    help="the URL the folder is published under: each photo's image-handle is it joined with "
                    "the photo's path (default: the photos' own file:// or object-storage URLs)")
    fd.add_argument("--format", choices=("yaml", "json"), default=None,
                    help="ifdo.yaml or ifdo.json (default: the kind of the header file)")
    _folder_arguments(fd)

    e = sub.add_parser(
        "evaluate",
        help="the paper's colour and distance metrics on annotated photos, beside baselines",
        description="Evaluate the method on the photos of a manifest (docs/EVALUATE.md): the mean angle of "
        "chart gray patches from gray (psi-bar), rho of -ln t against distance maps, the water type against "
        "a known one; beside every other profile (--method), the input, a contrast stretch, gray world and "
        "every candidate type. Writes "
        "results.json, results.csv and report.html.",
    )
    e.add_argument("manifest", metavar="MANIFEST", help="the manifest (JSON; paths relative to it)")
    e.add_argument("-o", "--out", "--output", dest="out", required=True, metavar="OUTDIR", type=_folder,
                   help="output folder (created if needed)")
    e.add_argument("--mask-charts", action="store_true",
                   help="exclude the charts' regions from estimation (the mask of restore), as the paper does")
    e.add_argument("--json-errors", action="store_true", help="each error as one JSON object on stderr")
    e.add_argument("-q", "--quiet", action="store_true", help="no progress lines and no summary")
    _add_options(e, method_only=True)
    return p


def file_kwargs(a: argparse.Namespace, water_types) -> dict:
    """The keywords of ``files.restore_file`` that ``uwhl restore``'s flags
    give (``max_memory`` only when given: the default follows the machine
    that restores)."""
    kw = dict(format=a.format, bits=a.bits, quality=a.quality, preprocess=a.preprocess, half_size=a.half_size,
              max_side=a.max_side, max_pixels=a.max_pixels, mask=a.mask, water_mask=a.water_mask,
              distance=a.distance, altitude=a.altitude, fov=a.fov, port=a.port, water_from=a.water_from,
              distance_kind=a.distance_kind,
              contact=a.contact_sheet, water_types=water_types, **method_kwargs(a, skip=("max_memory",)))
    # videos (uwhl_rs.videofiles): set only when given, so that photos see none of them
    for key in ("every", "video_codec", "video_quality", "transfer", "scene_cut", "smoothing"):
        v = getattr(a, key, None)
        if v is not None and v != _DEFAULTS.get(key):
            kw[key] = v
    if a.max_memory is not None:
        kw["max_memory"] = a.max_memory
    return kw


def method_kwargs(a: argparse.Namespace, skip=()) -> dict:
    """The method's keywords of ``restore`` as parsed from the option
    table's flags (``water_types`` is parsed apart), less those in ``skip``."""
    return {o["key"]: getattr(a, o["key"]) for o in _core.OPTIONS
            if o["method"] and o["faces"] != "rust" and o["key"] not in ("water_types", *skip)}


def attach_values(argv: list[str]) -> list[str]:
    """``--flag VALUE`` as ``--flag=VALUE`` for every option of the table
    that takes a value, so that a value beginning with ``-`` (``--max-memory
    -5M``, ``-o -out``) reaches the option's own check, as in ``uwhl-rs``,
    instead of being taken by argparse for an unknown flag."""
    valued = [o for o in _core.OPTIONS if o["kind"] != "flag"]
    takes = {o["flag"] for o in valued} | {o["short"] for o in valued if o["short"]} | {"-o", "--out", "--output"}
    out, i = [], 0
    while i < len(argv):
        tok = argv[i]
        if tok == "--":
            out.extend(argv[i:])
            break
        if tok in takes and i + 1 < len(argv) and argv[i + 1].startswith("-") and argv[i + 1] != "--":
            out.append(f"{tok}={argv[i + 1]}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out

