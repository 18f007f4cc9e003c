"""``python -m uwhl_rs`` / ``uwhl``: command-line entry point.

For now one subcommand, ``demo``: render the built-in synthetic underwater
scene (made by :mod:`uwhl_rs.synth`, nothing downloaded), restore it, write
before/after/transmission PNGs, and print the true and estimated water type.
"""

from __future__ import annotations

import argparse
import os
import struct
import sys
import time
import zlib

import numpy as np


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> sRGB-encoded [0, 1] (IEC 61966-2-1 transfer curve)."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def write_png(path: str, img: np.ndarray) -> None:
    """Write an 8-bit PNG (H x W gray or H x W x 3 RGB, values in [0, 1])
    atomically: a temporary file in the same folder, then a rename."""
    a = np.clip(np.round(np.asarray(img, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
    if a.ndim == 2:
        color = 0
    elif a.ndim == 3 and a.shape[2] == 3:
        color = 2
    else:
        raise ValueError(f"cannot write an array of shape {a.shape} as PNG")
    h, w = a.shape[:2]
    raw = b"".join(b"\x00" + a[y].tobytes() for y in range(h))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, color, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            f.write(png)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def demo(out_dir: str, water_type: str, size: tuple[int, int], seed: int) -> int:
    """Render, restore and report the built-in scene; returns an exit code."""
    import uwhl_rs
    from uwhl_rs import synth

    h, w = size
    image, truth = synth.demo_input(h, w, water_type=water_type, seed=seed)
    t0 = time.perf_counter()
    res = uwhl_rs.restore(image)
    dt = time.perf_counter() - t0
    os.makedirs(out_dir, exist_ok=True)
    write_png(os.path.join(out_dir, "input.png"), srgb_encode(image))
    write_png(os.path.join(out_dir, "restored.png"), srgb_encode(res.image))
    write_png(os.path.join(out_dir, "transmission.png"), res.transmission)
    write_png(os.path.join(out_dir, "clean_truth.png"), srgb_encode(truth["clean"]))
    z = truth["distance"]
    ok = np.isfinite(z)
    rho = float(np.corrcoef(z[ok], -np.log(res.transmission[ok]))[0, 1])
    ranking = sorted(res.scores, key=res.scores.get)
    print(f"uwhl_rs {uwhl_rs.__version__}: built-in synthetic scene {w}x{h}, seed {seed}")
    print(f"true water type:      {truth['water_type']}")
    print(f"estimated water type: {res.water_type}   (types by gray-world score: {' '.join(ranking)};"
          f" excluded by the t_R rule: {', '.join(res.excluded) or 'none'})")
    print(f"veiling light A: true {tuple(round(v, 4) for v in truth['veiling_light'])},"
          f" estimated {tuple(round(v, 4) for v in res.veiling_light)}")
    print(f"water region: {res.veiling_mask.mean():.1%} of the image; flags: {res.flags or 'none'}")
    print(f"rho(true distance, -ln t_B) = {rho:.3f}")
    print(f"restore took {dt:.3f} s; wrote input.png, restored.png, transmission.png, clean_truth.png to {out_dir}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``uwhl`` command."""
    import uwhl_rs

    p = argparse.ArgumentParser(prog="uwhl", description="Underwater color restoration with haze-lines.")
    p.add_argument("--version", action="version", version=f"uwhl_rs {uwhl_rs.__version__}")
    sub = p.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("demo", help="restore the built-in synthetic scene and report true vs estimated water type")
    d.add_argument("-o", "--out", default="uwhl_demo", help="output folder (default: ./uwhl_demo)")
    d.add_argument("--water-type", default="III", choices=list(uwhl_rs.WATER_TYPES), help="water type to render (default III)")
    d.add_argument("--size", default="480x640", help="HxW of the scene (default 480x640)")
    d.add_argument("--seed", type=int, default=7, help="scene seed (default 7)")
    a = p.parse_args(argv)
    if a.cmd == "demo":
        try:
            h, w = (int(v) for v in a.size.lower().split("x"))
        except ValueError:
            p.error(f"--size must look like 480x640, not {a.size!r}")
        return demo(a.out, a.water_type, (h, w), a.seed)
    return 2


if __name__ == "__main__":
    sys.exit(main())
