"""Type stubs of the native module uwhl_rs._core (built from src/python.rs)."""

from typing import Any, Literal, Optional, Union
from typing import Sequence as _Seq

import numpy as np
import numpy.typing as npt

__version__: str
JERLOV_TABLE: list[tuple[str, float, float]]
#: the one option table (src/options.rs): dicts with key, flag, short, metavar,
#: kind, min/max/gt/choices, default, help, group, faces, method
OPTIONS: list[dict]
#: (code, name, meaning) of both commands' exit codes
EXIT_CODES: list[tuple[int, str, str]]
EXIT_CODES_HELP: str
#: the stable names of Restoration.flags and Restoration.timings (docs/OUTPUTS.md)
FLAGS: list[str]
STAGES: list[str]

def parse_option(key: str, text: str) -> object: ...
def options_help(face: Literal["python", "rust"]) -> str: ...
IMAGE_EXTENSIONS: list[str]
RAW_EXTENSIONS: list[str]

def collect_jobs(
    inputs: list[str], out_dir: str, suffixes: list[str]
) -> tuple[list[tuple[str, str, str]], list[tuple[str, str]]]: ...
def carry_metadata(encoded_path: str, input_path: str, sidecar_json: str, sidecar_name: str, width: int,
                   height: int) -> str: ...
def _icc_classify(icc: bytes) -> tuple[str, str]: ...
def _icc_convert(values: Any, icc: bytes, linear: bool) -> Any: ...
def name_jobs(found: list[tuple[str, str]], suffixes: list[str]) -> list[str]: ...
def remove_stale_temps(dir: str) -> int: ...
class Claim:
    @property
    def name(self) -> str: ...
    @property
    def paths(self) -> list[str]: ...
    def temp(self, index: int) -> str: ...
    def commit(self, temps: list[str]) -> None: ...
    def release(self) -> None: ...
def claim_outputs(
    dir: str, base: str, input: str, suffixes: list[str], overwrite: bool, rename: bool
) -> tuple[str, str, Optional[str], Optional[Claim]]: ...
def create_temp(path: str) -> str: ...
def input_plan(
    height: int, width: int, decoded_bpp: int, decoded_is_rgb: bool, oriented: bool, factor: int, reference: bool,
    masks: int, write_extra: int = 0,
) -> int: ...
def process_base() -> int: ...
def default_max_memory() -> int: ...
def can_allocate(bytes: int) -> bool: ...
def place(tmp: str, path: str) -> None: ...
def check_combination(
    format: str, bits: Optional[int], reuse_estimates: Optional[int], reuse_water_mask: bool, linear: bool,
    preprocess: str,
) -> None: ...

class UwhlError(ValueError): ...
class ImageError(UwhlError): ...
class ParameterError(UwhlError): ...

class Restoration:
    image: npt.NDArray[np.float32]
    radiance: npt.NDArray[np.float32]
    transmission: npt.NDArray[np.float32]
    water_type: str
    beta_ratios: tuple[float, float]
    scores: dict[str, float]
    excluded: list[str]
    veiling_light: tuple[float, float, float]
    veiling_mask: npt.NDArray[np.bool_]
    flags: list[str]
    guided_radius: int
    guided_subsample: int
    timings: dict[str, float]
    def channel_transmissions(self) -> npt.NDArray[np.float32]: ...

WaterTypeSpec = Union[str, tuple[str, float, float]]

class Params:
    """The method's keywords: the rows of OPTIONS with "method" true
    (water_types, veiling_light, guided_radius, guided_eps, sphere_points,
    threads, max_memory, selection, guided_subsample, method,
    white_balance, type_choice, haze_floor); None = default."""
    def __init__(self, **kwargs: object) -> None: ...
    def steps(self) -> list[tuple[str, str]]: ...

def restore_f32(
    image: npt.NDArray[np.float32],
    params: Params,
    *,
    water_mask: Optional[npt.NDArray[np.bool_]] = None,
    mask: Optional[npt.NDArray[np.bool_]] = None,
) -> Restoration: ...

class Sequence:
    def __init__(self, params: Params, *, refresh_every: int = 0, reuse_water_mask: bool = False) -> None: ...
    def restore(
        self,
        image: npt.NDArray[np.float32],
        *,
        mask: Optional[npt.NDArray[np.bool_]] = None,
        water_mask: Optional[npt.NDArray[np.bool_]] = None,
    ) -> Restoration: ...
    def reset(self) -> None: ...
    water_type: Optional[str]
    veiling_light: Optional[tuple[float, float, float]]
    estimates_next: bool
    buffer_bytes: int
    refresh_every: int
    reuse_water_mask: bool
