"""Type stubs of the native module uwhl_rs._core (built from src/python/mod.rs,
src/python/color.rs and, with the Cargo feature ``internals``,
src/python/hooks.rs). tests/python/test_stubs.py checks them against the
built module with mypy's stubtest."""

import os
from pathlib import Path
from collections.abc import Callable
from typing import Any, ClassVar, Literal, Optional, Union, final

import numpy as np
import numpy.typing as npt

_PathArg = Union[str, "os.PathLike[str]"]
_F32 = npt.NDArray[np.float32]
_Bool = npt.NDArray[np.bool_]
_RGB = tuple[float, float, float]

#: every name the module registers, in registration order (the _stage_*
#: names only in a build with the ``internals`` feature)
__all__ = [
    "restore_f32", "transfer_of_tag", "frame_to_linear", "frame_from_linear", "_decode_u16", "_quantize", "_colormap", "_restoration_from_state",
    "_downscale", "_reference_srgb", "_reference_raw", "_decode_png", "_encode_png", "Restoration", "Sequence",
    "Params", "_after_fork", "_stage_stretch", "_stage_guide", "_stage_edge_map", "_stage_veiling",
    "_stage_haze_lines", "_stage_lower_bound", "_stage_matting", "_stage_guided", "_stage_recover",
    "_stage_display_stretch", "_stage_chart_fill", "_stage_sphere", "UwhlError", "ImageError", "ParameterError",
    "output_suffixes", "JERLOV_TABLE", "__version__", "OPTIONS", "FLAGS", "STAGES", "EXIT_CODES", "EXIT_CODES_HELP", "parse_option",
    "options_help", "check_combination", "check_distance", "check_water", "parse_water_types", "unknown_short_said", "depth_to_range", "floor_distance", "floor_for", "collect_jobs", "name_jobs", "remove_stale_temps", "listed_outputs", "is_output_of", "new_run", "nearest_type", "water_writable", "outdir_problem", "raw_problem", "sidecar_names_input", "FileSettings", "decode_file", "decode_mask_file", "read_distance_for", "read_distance_file", "depth_to_range_for", "write_input_outputs",
    "Summary", "summary_cell", "csv_text", "skipped_with_other_options", "progress_said", "water_with_distance_note", "transfer_note", "BALANCED_SHARE", "EARLIER_SUMMARY_BYTES",
    "FLOAT_NOT_PREPROCESSED", "upright_said",
    "name_bases", "MAX_NAMES", "FAMILY_GAP",
    "summary_columns",
    "Claim", "input_plan", "process_base", "default_max_memory", "can_allocate", "claim_outputs", "create_temp",
    "place", "IMAGE_EXTENSIONS", "RAW_EXTENSIONS", "FIT_BETA_GRID", "MAP_PER_PHOTO_PIXEL", "map_cap", "VIDEO_SCENE_CUT", "VIDEO_SMOOTHING", "VIDEO_EXTENSIONS",
]

__version__: str
#: (name, beta_BR, beta_BG) of the ten Jerlov water types (METHOD §4)
JERLOV_TABLE: list[tuple[str, float, float]]
#: the one option table (src/files/options.rs): dicts with key, flag, short, metavar,
#: kind, min/max/gt/choices, default, help, group, faces, method
OPTIONS: list[dict[str, Any]]
#: (code, name, meaning) of both commands' exit codes
EXIT_CODES: list[tuple[int, str, str]]
EXIT_CODES_HELP: str
#: the stable names of Restoration.flags and Restoration.timings (docs/OUTPUTS.md)
FLAGS: list[str]
STAGES: list[str]
#: the file extensions (lower case, no dot) a batch takes as images / as camera raw files
IMAGE_EXTENSIONS: list[str]
RAW_EXTENSIONS: list[str]
#: extensions read as videos by the Python command (refused by uwhl-rs)
VIDEO_EXTENSIONS: list[str]
#: the blue attenuations (1/m) a distance fit searches, smallest and largest (METHOD §13.2)
FIT_BETA_GRID: tuple[float, float]
#: a distance map of more than MAP_PER_PHOTO_PIXEL times its photo's pixels (map_cap) is not read
MAP_PER_PHOTO_PIXEL: int
#: a fallback_share from which a photo's colours are the input's balance throughout
BALANCED_SHARE: float
#: the largest earlier summary.csv read for its failures (a larger one keeps none)
EARLIER_SUMMARY_BYTES: int
#: the note of a float image read with the reference preprocessing (which does not apply to it)
FLOAT_NOT_PREPROCESSED: str
#: the names a claim tries for an input (NAME, NAME_2, ...)
MAX_NAMES: int
#: names in a row without a sidecar after which a rerun stops looking along a sequence for an input's earlier name
FAMILY_GAP: int
#: the scene-cut threshold and A smoothing of videos and raw frames (METHOD §10)
VIDEO_SCENE_CUT: float
VIDEO_SMOOTHING: float

class UwhlError(ValueError):
    """Bad input to uwhl_rs (a ValueError)."""

class ImageError(UwhlError):
    """The image is unusable: shape, size, NaN/Inf, range, constant."""

    kind: ClassVar[str]

class ParameterError(UwhlError):
    """A parameter, mask or water type is invalid."""

    kind: ClassVar[str]

def output_suffixes(format: str = "jpg", contact: bool = False) -> list[str]:
    """What follows NAME in the names of an input's outputs, in writing order, without the sidecar's .json."""

# ---- the option table ----

def parse_option(key: str, text: str) -> object:
    """A command-line value of option `key` parsed with the core's rules; ValueError naming the flag."""
def options_help(face: Literal["python", "rust"]) -> str:
    """The `options:` part of a command's --help for `face`."""
def check_combination(
    format: str, bits: Optional[int], reuse_estimates: Optional[int], reuse_water_mask: bool, linear: bool,
    preprocess: str,
) -> None:
    """The checks of several options at once; ValueError with the usage message."""
def unknown_short_said(word: str) -> str:
    """The usage error of an unknown short option that began ``word``, as uwhl-rs says it."""
def parse_water_types(values: list[str]) -> list[Union[str, tuple[str, float, float]]]:
    """--water-type values parsed as the binary parses them: a table type by its name, a custom one as
    (name, beta_br, beta_bg); ParameterError with the binary's message."""
def check_water(water_from: bool, water_types: bool) -> None:
    """A dive's water (--water-from) with water types given; ValueError with the usage message."""
def check_distance(
    distance: bool, altitude: bool, fov: bool, reuse_estimates: bool, depth: bool = False, port: bool = False,
) -> None:
    """The checks of the distance options together (one source, no sequence, --distance-kind depth with
    --distance, --fov and a given --port with --altitude or depth along the axis); ValueError with the usage message."""
def depth_to_range(depth: _F32, fov: float, port: str) -> _F32:
    """Depth along the camera's axis as the range along each pixel's ray (METHOD §13.7)."""
def floor_distance(height: int, width: int, altitude: float, fov: float, pitch: float, roll: float,
                   port: str) -> _F32:
    """Range in metres along each pixel's ray to a flat seabed (METHOD §13.7); NaN where none."""

# ---- batches: jobs, output names, claims, metadata ----

def collect_jobs(
    inputs: list[_PathArg], out_dir: _PathArg, suffixes: list[str]
) -> tuple[list[tuple[Path, Path, str]], list[tuple[Path, str]], list[str]]:
    """The jobs of a batch as (input, output folder, name), the problems as (input, reason), and notes (folders not searched)."""
def name_bases(path: _PathArg) -> tuple[str, str]:
    """The two bases a batch names an input from: its stem S, and S_E with E its extension in ASCII lower case."""
def name_jobs(found: list[tuple[str, str]], suffixes: list[str]) -> list[str]:
    """The output names of (input, relative folder) pairs listed elsewhere, in discovery order."""

def nearest_type(beta: tuple[float, float, float] | list[float]) -> tuple[str, float]:
    """The Jerlov type nearest to a water of attenuations `beta` (1/m, R, G, B) and how near."""
def water_writable(beta: tuple[float, float, float] | list[float]) -> bool:
    """Whether a fit could have written `beta` (1/m, R, G, B): the water `--water-from` takes."""
def new_run() -> None:
    """A new run starts: the `--water-from` folders and `--altitude` navigation logs are read again."""
def remove_stale_temps(dir: _PathArg, gate: Optional[_PathArg] = None) -> int:
    """Removes the temporaries dead processes left in `dir` when no other run holds `gate` (`dir`); returns how many."""
def listed_outputs(name: str, sidecar: bytes) -> list[str]:
    """The outputs an earlier sidecar lists for output name `name` that an --overwrite may remove beside it."""
def is_output_of(name: str, file: str) -> bool:
    """Whether `file` is `name` and a suffix the commands write."""
def outdir_problem(dir: _PathArg) -> Optional[str]:
    """Why the output folder cannot take outputs (a file is at its name), or None."""
def sidecar_names_input(given: _PathArg, resolved: Optional[_PathArg], hashed: bool, input: _PathArg) -> bool:
    """Whether a sidecar's recorded input names the local input by name (the rule of a folder's claims)."""
def raw_problem(path: _PathArg) -> Optional[str]:
    """Why a TIFF-based raw file cannot be handed to LibRaw (a strip or tile table short of its image), or None."""

@final
class Claim:
    """An input's claimed output names: temporaries, then one commit, sidecar last."""
    @property
    def name(self) -> str:
        """The name the outputs are written under."""
    @property
    def paths(self) -> list[Path]:
        """The output paths in the order of the suffixes, the sidecar last."""
    def temp(self, index: int) -> Path:
        """A new empty temporary file (created exclusively) for output `index`."""
    def omit(self, index: int) -> None:
        """Output index is not written this time: the commit removes an earlier run's file there."""
    def commit(self, temps: list[_PathArg]) -> None:
        """Puts the written temporaries (one per path) in place, sidecar last."""
    def release(self) -> None:
        """Gives the names up: removes the temporaries and the claim file."""

def claim_outputs(
    dir: _PathArg, base: str, input: _PathArg, suffixes: list[str], overwrite: bool, rename: bool
) -> tuple[Literal["claimed", "done", "busy", "in_flight"], Path, Optional[str], Optional[Claim]]:
    """Claims an input's output names: (status, sidecar, reason of a skip, claim if "claimed")."""
def create_temp(path: _PathArg) -> Path:
    """A new empty temporary file in `path`'s folder, with `path`'s extension."""
def place(tmp: _PathArg, path: _PathArg) -> None:
    """Puts a written temporary in place of `path` durably."""

# ---- one input's path (src/files/pipeline.rs) ----

@final
class FileSettings:
    """The settings of one input's processing: method and file keywords, checked by the option table."""
    def __new__(cls, **kwargs: object) -> "FileSettings": ...
    @property
    def max_memory(self) -> int:
        """The memory budget in bytes."""
    @property
    def parameters(self) -> str:
        """The sidecar's parameters of these settings, as JSON text."""
    @property
    def dive_water_type(self) -> Optional[tuple[str, float, float]]:
        """With water_from: the dive's water type (name, beta_BR, beta_BG); else None."""
    @property
    def dive_water_notes(self) -> list[str]:
        """With water_from: the notes on the folder's sidecars that gave no fit; else []."""
    @property
    def altitude(self) -> Optional[str]:
        """With altitude: what the sidecar's distance.source says of it; else None."""
    @property
    def depth_along_axis(self) -> bool:
        """Whether the distance maps hold depth along the camera's axis (distance_kind="depth")."""

def decode_file(
    path: _PathArg, linearize: bool, max_pixels: int, max_memory: int,
    on_header: Optional[Callable[[int, int, int, bool], object]] = None,
) -> tuple[_F32, dict[str, Any]]:
    """A PNG, JPEG or TIFF decoded by the binary's decoder: (image, info)."""
def decode_mask_file(path: _PathArg, what: str, max_pixels: int, max_memory: int) -> _Bool:
    """A mask file as H x W bools (nonzero = True), read by the binary's mask reader."""
def read_distance_for(
    template: str, input: _PathArg, max_pixels: int, max_memory: int, photo: Optional[tuple[int, int]] = None,
) -> tuple[str, Optional[_F32], Optional[str], int]:
    """An input's distance map for a --distance template: (path, H x W metres or None, why not or None,
    how many distances beyond float32 were read as unknown);
    with photo (height, width), a map of more than 16 times its pixels is refused from its header."""
def map_cap(height: int, width: int) -> int:
    """The most pixels a distance map of a photo of height x width pixels may have (4 Mpx at least)."""
def read_distance_file(path: _PathArg, max_pixels: int, max_memory: int,
                       photo: Optional[tuple[int, int]] = None) -> _F32:
    """A distance map file as H x W metres (NaN = unknown), read by the binary's reader (npy, 16-bit PNG,
    TIFF, OpenEXR, COLMAP); ImageError names what is wrong, MemoryError a map over the limits."""
def depth_to_range_for(
    settings: FileSettings, input: _PathArg, depth: _F32, height: int, width: int,
) -> tuple[Optional[_F32], Optional[str], Optional[str]]:
    """Depth along the camera's axis turned into ranges with the photo's lens (--fov or EXIF) and --port:
    (ranges or None, the sidecar's distance.depth as JSON or None, why not or None)."""
def floor_for(
    settings: FileSettings, input: _PathArg, height: int, width: int, processed_height: int, processed_width: int,
) -> tuple[str, Optional[_F32], Optional[str], Optional[str]]:
    """An input's distance from --altitude at the processed size: (source, map or None, why not or None,
    the sidecar's distance.floor as JSON or None)."""
def write_input_outputs(
    claim: Claim, res: Restoration, image: _F32, source: dict[str, Any], settings: FileSettings, input: Optional[_PathArg],
    label: str, contact_sheet: Optional[bytes], reused: Optional[bool], read: float, restore: float,
    sheet_seconds: Optional[float], elapsed: float, distance_source: Optional[str] = None,
    distance_missing: Optional[str] = None, distance_floor: Optional[str] = None,
    distance_depth: Optional[str] = None, distance_out_of_range: int = 0,
) -> str:
    """Writes one input's outputs through its claim (encodes, metadata, sidecar, commit): the sidecar as JSON."""

# ---- summary.csv (src/files/summary.rs) ----

@final
class Summary:
    """OUTDIR/summary.csv, written by the binary's writer: one locked append per row."""
    def __new__(cls, out_dir: _PathArg, waiting: Optional[Callable[[str], Any]] = None) -> "Summary": ...
    @property
    def path(self) -> Path:
        """The file's path."""
    @property
    def notes(self) -> list[str]:
        """What the run tells the user about the file (an earlier summary's failures not listed again, and why)."""
    @property
    def error(self) -> Optional[str]:
        """Why the file cannot be written, or None."""
    @property
    def read_only(self) -> bool:
        """Whether it cannot be written because the folder is read-only."""
    def given(self, inputs: list[_PathArg]) -> None:
        """This run's inputs as its rows name them: a run that starts the file afresh keeps the earlier failed rows of others."""
    def add(self, row: dict[str, Any]) -> None:
        """Appends one row (a dict of columns; `scores` a dict), in one locked write."""
    def close(self) -> None:
        """Closes the file (and lets the folder's lock go)."""

def upright_said(orientation: int) -> str:
    """What a mask's size error adds for an input its EXIF orientation turned ('' for 1)."""
def summary_cell(cell: str) -> str:
    """A summary.csv cell's text as it was before a formula was neutralised."""
def csv_text(cell: str) -> str:
    """A text cell as summary.csv writes it: a spreadsheet formula gets a quote in front."""
def skipped_with_other_options(sidecar: _PathArg, current: str) -> str:
    """'; restored with another --flag, ...: --overwrite redoes it' when the sidecar's options differ from `current` (FileSettings.parameters), else ''."""
def progress_said(fallback_share: Optional[float], flags: list[str]) -> str:
    """What an input's progress line says after its water type: a distance
    asked for and not used, colours that are the input's balance throughout."""

def transfer_note(transfer: bool, videos: bool) -> Optional[str]:
    """The note said once when `--transfer` is given to a run that may hold no video."""
def water_with_distance_note(water_from: bool, water_type: bool, distance: bool, altitude: bool) -> Optional[str]:
    """The note printed once before the inputs when a water is given with a
    source of distance (each argument: that option was given); None otherwise."""
def summary_columns() -> list[str]:
    """The columns of summary.csv, in order."""

# ---- memory budget ----

def input_plan(
    height: int, width: int, decoded_bpp: int, decoded_is_rgb: bool, oriented: bool, factor: int, reference: bool,
    masks: int, write_extra: int = 0, sphere_points: Optional[int] = None,
) -> int:
    """The bytes the whole input needs at its peak (decoding, max_side, restore with the sphere index of
    sphere_points, by default the method's, the outputs)."""
def process_base() -> int:
    """What the process holds before its first input plus a margin, measured at the first call."""
def default_max_memory() -> int:
    """The default memory budget in bytes."""
def can_allocate(bytes: int) -> bool:
    """Whether the system would give `bytes` now."""

# ---- pixel conventions (docs/OUTPUTS.md) ----

def transfer_of_tag(tag: str) -> Optional[str]:
    """The --transfer name of a video stream's transfer tag (None: unspecified); ValueError for HDR/log."""
def frame_to_linear(codes: Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]], transfer: str) -> _F32:
    """8- or 16-bit frame codes (H, W, 3) to linear light through the inverse of the curve."""
def frame_from_linear(
    image: _F32, transfer: str, bits: Literal[8, 16]
) -> Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]:
    """Linear light (H, W, 3) to 8- or 16-bit codes through the curve."""
def _decode_u16(codes: npt.NDArray[np.uint16], linearize: bool) -> _F32:
    """16-bit codes (any shape) to float32 in [0, 1], through the inverse sRGB curve when `linearize`."""
def _quantize(data: _F32, bits: Literal[8, 16], srgb: bool) -> Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]:
    """float32 values (any shape) to uint8 or uint16 codes, through the sRGB curve when `srgb`."""
def _restoration_from_state(state: dict[str, Any]) -> Restoration:
    """A Restoration from the state its __reduce__ gave (unpickling)."""
def _colormap(t: _F32) -> npt.NDArray[np.uint8]:
    """A transmission map (H, W) to its colour-mapped uint8 image (H, W, 3)."""
def _downscale(image: _F32, factor: int) -> _F32:
    """Block-average downscale of an (H, W, C) float32 image by an integer factor."""
def _reference_srgb(image: _F32) -> _F32:
    """METHOD §2 reference preprocessing of a non-linearised sRGB image (H, W, 3)."""
def _reference_raw(image: _F32) -> _F32:
    """METHOD §2 reference preprocessing of a white-balanced linear raw image (H, W, 3)."""
def _decode_png(data: bytes, max_pixels: int) -> Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]:
    """A PNG file's bytes to (H, W, 3) uint8 or uint16 codes; ValueError over `max_pixels` pixels."""
def _encode_png(a: Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]) -> bytes:
    """PNG bytes of a C-contiguous (H, W) or (H, W, 3) uint8 or uint16 array."""
def _after_fork() -> None:
    """Called in a forked child (os.register_at_fork): later calls use fresh thread pools."""

# ---- the method ----

@final
class Restoration:
    """The result of restore_f32 / Sequence.restore (fields: docs/OUTPUTS.md)."""
    @property
    def image(self) -> _F32: ...
    @property
    def radiance(self) -> _F32: ...
    @property
    def transmission(self) -> _F32: ...
    @property
    def water_type(self) -> str: ...
    @property
    def beta_ratios(self) -> tuple[float, float]: ...
    @property
    def scores(self) -> dict[str, float]: ...
    @property
    def excluded(self) -> list[str]: ...
    @property
    def veiling_light(self) -> _RGB: ...
    @property
    def veiling_mask(self) -> _Bool: ...
    @property
    def flags(self) -> list[str]: ...
    @property
    def confidence(self) -> Optional[_F32]:
        """H x W in [0, 1]: how far each displayed colour can be trusted (METHOD §12.5); None without a fallback."""
    @property
    def veil_excess(self) -> Optional[float]:
        """Share of object pixels whose estimated veil exceeds the light (METHOD §12.5); None without a fallback."""
    @property
    def fallback_share(self) -> Optional[float]:
        """Share of the shown colour that is the input's own balance, 0 to 1 (METHOD §12.5); None when nothing is blended."""
    @property
    def distance(self) -> Optional[dict[str, Any]]:
        """With a distance: what became of it (docs/OUTPUTS.md "Distance", METHOD §13)."""
    @property
    def water(self) -> Optional[dict[str, Any]]:
        """With a distance: the fitted water (beta per channel in 1/m, A, nearest type)."""
    @property
    def guided_radius(self) -> int: ...
    @property
    def guided_subsample(self) -> int: ...
    @property
    def timings(self) -> dict[str, float]: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...
    def channel_transmissions(self) -> _F32:
        """Per-channel transmissions (t_R, t_G, t_B) of the chosen type, (H, W, 3) float32 (METHOD §7)."""

@final
class Params:
    """The method's keywords: the rows of OPTIONS with "method" true
    (water_types, veiling_light, guided_radius, guided_eps, sphere_points,
    threads, max_memory, selection, guided_subsample, method,
    white_balance, type_choice, haze_floor, t_scale); None = default."""
    def __new__(cls, **kwargs: object) -> "Params": ...
    def steps(self) -> list[tuple[str, str]]:
        """The profile and the steps used, as (keyword, name) pairs (METHOD §12)."""
    def budget(self, h: int, w: int) -> tuple[int, int]:
        """(needed, max_memory): the working memory of an h x w restoration and its limit (the values that need no image checked first)."""

def restore_f32(
    image: _F32,
    params: Params,
    *,
    water_mask: Optional[_Bool] = None,
    mask: Optional[_Bool] = None,
    distance: Optional[_F32] = None,
) -> Restoration:
    """Restores a C-contiguous float32 (H, W, 3) image, the GIL released."""

@final
class Sequence:
    """Restores the frames of one sequence, reusing the water type and A between estimates."""
    def __new__(
        cls,
        params: Params,
        *,
        refresh_every: int = 0,
        reuse_water_mask: bool = False,
        scene_cut: float = 0.0,
        smoothing: float = 1.0,
    ) -> "Sequence": ...
    def restore(
        self,
        image: _F32,
        *,
        mask: Optional[_Bool] = None,
        water_mask: Optional[_Bool] = None,
    ) -> Restoration:
        """Restores the next frame (float32 (H, W, 3), C-contiguous)."""
    def reset(self) -> None:
        """Forgets the estimates and frees the kept buffers."""
    @property
    def water_type(self) -> Optional[str]:
        """The water type the next frame reuses (None before the first frame)."""
    @property
    def veiling_light(self) -> Optional[_RGB]:
        """The veiling light A the next frame reuses (None before the first frame)."""
    @property
    def last_decision(self) -> tuple[str, float]:
        """Why the last frame estimated or reused, and its colour change (METHOD §10)."""
    @property
    def estimates_next(self) -> bool:
        """Whether the next frame runs the estimation (water type and A)."""
    @property
    def buffer_bytes(self) -> int:
        """Bytes of work buffers kept between frames."""
    @property
    def refresh_every(self) -> int: ...
    @property
    def reuse_water_mask(self) -> bool: ...

# ---- the stage entry points: only in a build with the Cargo feature
# ``internals`` (the test builds; release wheels lack them), for the
# cross-checks of tests/python/test_crosscheck.py ----

def _stage_stretch(image: _F32, mask: Optional[_Bool] = None) -> _F32:
    """METHOD §3.1 contrast stretch (statistics over masked-in pixels)."""
def _stage_guide(image: _F32, mask: Optional[_Bool] = None) -> _F32:
    """METHOD §6 guide image."""
def _stage_edge_map(image: _F32) -> tuple[_F32, float, int, float]:
    """Edge map: (E at working size, tau, scale, sigma)."""
def _stage_veiling(
    image: _F32, mask: Optional[_Bool] = None, water_mask: Optional[_Bool] = None,
    veiling_light: Optional[_RGB] = None,
) -> tuple[_RGB, _Bool, list[str]]:
    """Veiling light and water region: (A, VL, flags)."""
def _stage_haze_lines(
    image: _F32, a: _RGB, beta_br: float, beta_bg: float, n_points: int = 500, mask: Optional[_Bool] = None
) -> _F32:
    """Initial transmission t~ (METHOD §4, after fill and x0.9)."""
def _stage_lower_bound(image: _F32, a: _RGB, beta_br: float, beta_bg: float) -> _F32:
    """Lower bound t_LB (METHOD §5)."""
def _stage_matting(image: _F32, vl: _Bool) -> Optional[tuple[_F32, _F32]]:
    """Squared Mahalanobis distances and matting weights (METHOD §5), or None."""
def _stage_guided(guide: _F32, p: _F32, r: int, eps: float) -> _F32:
    """Color guided filter (METHOD §6)."""
def _stage_recover(
    image: _F32, a: _RGB, t: _F32, beta_br: float, beta_bg: float, mask: Optional[_Bool] = None
) -> tuple[_F32, _F32]:
    """Recovery (METHOD §7): (J after the artifact clamp, clamped t_B)."""
def _stage_display_stretch(j: _F32, mask: Optional[_Bool] = None) -> _F32:
    """Display stretch (METHOD §8), limits from masked-in pixels."""
def _stage_chart_fill(q: _F32, mask: _Bool) -> _F32:
    """Chart fill (METHOD §6, last paragraph)."""
def _stage_sphere(n: int, u: _F32) -> tuple[_F32, list[int]]:
    """Fibonacci sphere points (n, 3) as stored and the nearest point's index per row of u."""
