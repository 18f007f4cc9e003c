"""``uwhl demo``: the built-in synthetic scene rendered, restored and
compared with its truth (nothing is downloaded)."""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import uwhl_rs

from .. import synth
from ..images import colorize_transmission, write_image
from ..console import Console
from ..errors import CommandError

__all__ = ["run"]


def run(a: argparse.Namespace, console: Console) -> int:
    """``uwhl demo``: render, restore and report the built-in scene (``a.size``
    parsed: (height, width))."""
    out_dir, water_type, size, seed = a.out, a.water_type, a.size, a.seed
    h, w = size
    # the folder first: one that cannot be made is said before any work (exit 5, as uwhl-rs)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as e:
        raise CommandError(f"cannot create it: {e.strerror or e}", "write_failed", out_dir) from None
    image, truth = synth.demo_input(h, w, water_type=water_type, seed=seed)
    t0 = time.perf_counter()
    res = uwhl_rs.restore(image)
    dt = time.perf_counter() - t0
    for name, img, enc in (("input.png", image, "linear"), ("restored.png", res.image, "linear"),
                           ("transmission.png", colorize_transmission(res.transmission), "srgb"),
                           ("clean_truth.png", truth["clean"], "linear")):
        try:
            write_image(os.path.join(out_dir, name), img, encoding=enc)
        except OSError as e:
            raise CommandError(e.strerror or f"cannot write {name}: {e}", "write_failed", out_dir) from None
    z = truth["distance"]
    ok = np.isfinite(z)
    rho = float(np.corrcoef(z[ok], -np.log(res.transmission[ok]))[0, 1])
    ranking = sorted(res.scores, key=res.scores.get)
    console.line(f"uwhl_rs {uwhl_rs.__version__}: built-in synthetic scene {h}x{w} (height x width, as --size), seed {seed}")
    console.line(f"true water type:      {truth['water_type']}")
    console.line(f"estimated water type: {res.water_type}   (scores, lowest first: {' '.join(ranking)};"
          f" the default chooses among the three lowest, METHOD §12.2;"
          f" excluded by the t_R rule: {', '.join(res.excluded) or 'none'})")
    console.line(f"veiling light A: true {tuple(round(v, 4) for v in truth['veiling_light'])},"
          f" estimated {tuple(round(v, 4) for v in res.veiling_light)}")
    console.line(f"water region: {res.veiling_mask.mean():.1%} of the image; flags: {res.flags or 'none'}")
    console.line(f"rho(true distance, -ln t_B) = {rho:.3f}")
    console.line(f"restore took {dt:.3f} s; wrote input.png, restored.png, transmission.png, clean_truth.png to {out_dir}")
    return 0
