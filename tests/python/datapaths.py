"""Where the shared real photographs are: ../shared/data beside the
repository (as in CI); the UWHL_DATA environment variable overrides."""

import os
import pathlib

DATA_ROOT = pathlib.Path(os.environ.get("UWHL_DATA", pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"))
IMAGES_DIR = DATA_ROOT / "images"
RAW_DIR = DATA_ROOT / "raw"
