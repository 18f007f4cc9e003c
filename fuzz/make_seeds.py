"""Writes the fuzz seeds (committed; rerun to regenerate): small valid
PNG/JPEG/TIFF files of a rendered scene in every sample layout the binary
reads, plus the small hostile files. The first byte of each seed is the
option selector of `uwhl::cli::run::fuzz_one`."""

import io
import os

import numpy as np
import tifffile
from PIL import Image

from uwhl_rs import _core, synth

FUZZ = os.path.dirname(os.path.abspath(__file__))
HERE = os.path.join(FUZZ, "seeds")
HOSTILE = os.path.join(FUZZ, "..", "tests", "data", "hostile")


def save(name: str, sel: int, data: bytes) -> None:
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(bytes([sel]) + data)


def pil(img: Image.Image, fmt: str, **kw) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format=fmt, **kw)
    return buf.getvalue()


def tif(a: np.ndarray, **kw) -> bytes:
    buf = io.BytesIO()
    tifffile.imwrite(buf, a, **kw)
    return buf.getvalue()


lin, _ = synth.demo_input(20, 24, water_type="5C", seed=1)
lin = np.ascontiguousarray(lin, dtype=np.float32)
c8 = _core._quantize(lin, 8, True)
c16 = _core._quantize(lin, 16, True)
rgb = Image.fromarray(c8)
save("rgb8.png", 0, pil(rgb, "PNG"))
save("gray8_reference.png", 1, pil(rgb.convert("L"), "PNG"))
save("rgba8_two_types.png", 8, pil(rgb.convert("RGBA"), "PNG"))
save("rgb8_small_side.jpg", 4, pil(rgb, "JPEG", quality=90))
exif = Image.Exif()
exif[0x0112] = 6
save("rgb8_exif6.jpg", 5, pil(rgb, "JPEG", quality=80, exif=exif))
save("rgb8.tif", 0, tif(c8, photometric="rgb"))
save("rgb16_deflate_linear.tif", 2, tif(c16, photometric="rgb", compression="zlib"))
save("rgb32f.tif", 0, tif(lin, photometric="rgb"))
# a 16-bit PNG: the package's writer (Pillow cannot write 16-bit RGB)
from uwhl_rs import _core  # noqa: E402

save("rgb16.png", 4, _core._encode_png(np.ascontiguousarray(c16)))
for name in ["huge_header.png", "truncated.jpg", "bad_offsets.tif"]:
    with open(os.path.join(HOSTILE, name), "rb") as f:
        save("hostile_" + name, 0, f.read())
print(sorted(os.listdir(HERE)))
