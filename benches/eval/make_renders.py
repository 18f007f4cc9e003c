"""Writes the rendered half of the evaluation benchmark (docs/EVALUATE.md):
three kinds of scene in all ten Jerlov types at two noise levels, each with
a six-patch gray chart in the clean radiance, its distance map and its true
type, and the manifest `renders.json` beside them.

    python3 benches/eval/make_renders.py OUTDIR [--size 240x320]
    uwhl evaluate OUTDIR/renders.json -o OUTDIR/results --mask-charts
    uwhl evaluate OUTDIR/renders_given.json -o OUTDIR/results_given --mask-charts

`renders.json` leaves the water region and the veiling light to the
method; `renders_given.json` gives the true water region where the scene
has one (open water, as a mask image) and the true veiling light where it
has none (the looking-down kinds), so the type choice is measured apart
from the veiling-light estimate.

Kinds: `open_water` (a seabed receding to the horizon under open water),
`looking_down` (a seabed from above) and `depth_steps` (the looking-down
radiance over a distance map with real depth structure: a floor sloping
from 2 to 9 m with boulders standing 1-3 m proud of it and a cliff edge
that drops 4 m), all from `uwhl_rs.synth`, so nothing large is committed.
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

import uwhl_rs
from uwhl_rs import synth

#: Reflectances of a chart's six gray patches (white to black, as on a
#: 24-patch checker's last row).
GRAYS = (0.90, 0.59, 0.36, 0.19, 0.09, 0.03)
NOISE = (0.003, 0.02)


def depth_steps(h: int, w: int, seed: int) -> np.ndarray:
    """A distance map with structure: a slope, boulders, a cliff edge."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    d = 9.0 - 7.0 * yy / (h - 1)  # 9 m at the top row to 2 m at the bottom
    d = np.where(xx > w * rng.uniform(0.55, 0.75), d + 4.0, d)  # a drop-off on the right
    for _ in range(6):
        cy, cx = rng.uniform(0.15, 0.7) * h, rng.uniform(0.05, 0.95) * w
        r = rng.uniform(0.05, 0.12) * min(h, w)
        inside = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
        d = np.where(inside, np.maximum(d - rng.uniform(1.0, 3.0), 1.0), d)
    return d.astype(np.float32)


def paint_chart(clean: np.ndarray, h: int, w: int) -> tuple[list, list]:
    """Six gray patches in a row near the bottom centre; (patch boxes, region box)."""
    side = max(6, w // 20)
    gap = max(2, side // 4)
    x0 = (w - 6 * side - 5 * gap) // 2
    y0 = h - 2 * side
    boxes = []
    for k, g in enumerate(GRAYS):
        x = x0 + k * (side + gap)
        clean[y0:y0 + side, x:x + side] = g
        boxes.append([x + 1, y0 + 1, x + side - 1, y0 + side - 1])
    region = [x0 - gap, y0 - gap, x0 + 6 * side + 5 * gap + gap, y0 + side + gap]
    clean[region[1]:region[3], region[0]:x0] = 0.02  # the chart's black frame
    return boxes, [region]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--size", default="240x320")
    a = ap.parse_args()
    h, w = (int(v) for v in a.size.split("x"))
    os.makedirs(a.out, exist_ok=True)
    images, given = [], []
    for kind in ("open_water", "looking_down", "depth_steps"):
        for t, (name, _, _) in enumerate(uwhl_rs._core.JERLOV_TABLE):
            seed = 100 + t
            sc = synth.scene(h, w, kind="looking_down" if kind == "depth_steps" else kind, seed=seed)
            clean = sc.clean.copy()
            distance = depth_steps(h, w, seed) if kind == "depth_steps" else sc.distance.copy()
            boxes, region = paint_chart(clean, h, w)
            for n, noise in enumerate(NOISE):
                img = synth.render(clean, distance, name, beta_b=0.2, noise=noise, seed=seed * 10 + n)
                stem = f"{kind}_{name}_n{n}"
                uwhl_rs.images.write_image(os.path.join(a.out, stem + ".png"), img, bits=16, encoding="linear")
                d = np.where(np.isfinite(distance), distance, 0).astype(np.float32)
                np.save(os.path.join(a.out, stem + ".npy"), d)
                images.append({"path": stem + ".png", "distance": stem + ".npy", "water_type": name,
                               "charts": [{"name": "gray chart", "gray_patches": boxes, "region": region}]})
                entry = dict(images[-1])
                water = ~np.isfinite(distance)
                if water.any():
                    uwhl_rs.images.write_image(os.path.join(a.out, stem + "_water.png"),
                                           np.repeat(water[:, :, None], 3, axis=2).astype(np.float32), bits=8,
                                           encoding="linear")
                    entry["water_mask"] = stem + "_water.png"
                else:
                    entry["restore"] = {"veiling_light": [float(v) for v in synth.default_veiling_light(name)]}
                given.append(entry)
    with open(os.path.join(a.out, "renders.json"), "w") as f:
        json.dump({"images": images}, f, indent=1)
    with open(os.path.join(a.out, "renders_given.json"), "w") as f:
        json.dump({"images": given}, f, indent=1)
    print(f"{len(images)} renders, renders.json and renders_given.json in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
