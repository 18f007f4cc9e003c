"""Fingerprints of restore's outputs on a fixed set of cases, to prove that a
refactoring changed nothing.

    python3 benches/golden.py record golden.json   # before the change
    python3 benches/golden.py check golden.json    # after: exit 1 on any difference
    python3 benches/golden.py check golden.json --method paper   # one profile (METHOD §12)

With `--method M`, every call and command runs with that profile: a
record made before the profiles existed is checked against
`--method paper`, which must reproduce it bit for bit (the sidecars then
also list the profile's steps and `t_scale`, which the check ignores).

Each case records sha256 digests of the image, radiance and transmission
arrays (float32 bytes), the veiling mask, the exact scores (repr of the
floats), the excluded types, flags, chosen type, A, radius and subsampling
factor; the command cases record the digest of every output's decoded samples
(so the photo's metadata, docs/OUTPUTS.md "Metadata", does not count) and
the sidecar with its timings, version and metadata summary removed. Cases that need
`../shared/data` are skipped when it is absent; cases that need the
`uwhl-rs` binary are skipped when `target/release/uwhl-rs` is absent.
The fingerprints are machine-specific (CPU dispatch): record and check on
the same machine.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

import uwhl_rs
from uwhl_rs import images as uio
from uwhl_rs import synth

#: keywords added to every restore call and flags to every command (--method)
_EXTRA: dict = {}
_FLAGS: list = []
#: sidecar parameters that a record from before the profiles lacks
_NEW_PARAMETERS = {"method", "white_balance", "type_choice", "haze_floor", "t_scale"}

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "..", "shared", "data")
BINARY = os.path.join(ROOT, "target", "release", "uwhl-rs")


def _digest(a) -> str:
    a = np.ascontiguousarray(a)
    return hashlib.sha256(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes()).hexdigest()[:24]


def _fingerprint(res) -> dict:
    return {
        "image": _digest(res.image),
        "radiance": _digest(res.radiance),
        "transmission": _digest(res.transmission),
        "veiling_mask": _digest(res.veiling_mask),
        "water_type": res.water_type,
        "scores": {k: repr(float(v)) for k, v in res.scores.items()},
        "excluded": list(res.excluded),
        "flags": list(res.flags),
        "veiling_light": [repr(float(v)) for v in res.veiling_light],
        "guided_radius": int(res.guided_radius),
        "guided_subsample": int(res.guided_subsample),
    }


def _restore(*a, **kw):
    return uwhl_rs.restore(*a, **{**_EXTRA, **kw})


def _photo(name: str, max_side: int | None = None):
    path = os.path.join(DATA, "images", name)
    if not os.path.exists(path):
        return None
    img, _ = uio.read_image(path)
    if max_side:
        s = -(-max(img.shape[:2]) // max_side)
        if s > 1:
            h, w = img.shape[0] // s * s, img.shape[1] // s * s
            img = img[:h, :w].reshape(h // s, s, w // s, s, 3).mean(axis=(1, 3)).astype(np.float32)
    return np.ascontiguousarray(img, dtype=np.float32)


def _render(kind: str, wt: str, h: int, w: int, seed: int, noise: float = 0.003):
    sc = synth.scene(h, w, kind=kind, seed=seed)
    img = synth.render(sc.clean, sc.distance, wt, beta_b=0.2, noise=noise, seed=seed)
    return img, sc


def api_cases():
    """(name, thunk) pairs; a thunk returns a fingerprint dict or None (skip)."""
    cases = []

    def add(name):
        def deco(f):
            cases.append((name, f))
            return f
        return deco

    @add("demo_III_default")
    def _():
        img, _ = synth.demo_input()
        return _fingerprint(_restore(img))

    @add("render_open_1C_threads1")
    def _():
        img, _ = _render("open_water", "1C", 200, 260, 3)
        return _fingerprint(_restore(img, threads=1))

    @add("render_looking_down_II")
    def _():
        img, _ = _render("looking_down", "II", 180, 240, 5)
        return _fingerprint(_restore(img))

    @add("render_open_7C_water_mask_given")
    def _():
        img, sc = _render("open_water", "7C", 200, 240, 11)
        return _fingerprint(_restore(img, water_mask=sc.water))

    @add("render_open_3C_chart_mask")
    def _():
        img, _ = _render("open_water", "3C", 200, 240, 13)
        m = np.ones(img.shape[:2], bool)
        m[120:170, 40:100] = False
        img[120:170, 40:100] = np.float32(0.4)
        return _fingerprint(_restore(img, mask=m))

    @add("render_open_IB_fast_selection_1500")
    def _():
        img, _ = _render("open_water", "IB", 1100, 1500, 17)
        return _fingerprint(_restore(img, selection="fast"))

    @add("render_open_II_subsample_auto")
    def _():
        img, _ = _render("open_water", "II", 540, 720, 19)
        return _fingerprint(_restore(img, guided_subsample="auto"))

    @add("render_open_5C_subsample3_params")
    def _():
        img, _ = _render("open_water", "5C", 240, 300, 23)
        return _fingerprint(_restore(img, guided_subsample=3, guided_radius=20, guided_eps=5e-3,
                                            sphere_points=300))

    @add("render_custom_types_given_A")
    def _():
        img, _ = _render("open_water", "III", 200, 240, 29)
        return _fingerprint(_restore(img, water_types=["II", ("mine", 3.1, 1.7), "9C"],
                                            veiling_light=(0.05, 0.3, 0.45)))

    @add("sequence_3_frames_refresh2_reuse_mask")
    def _():
        seq = uwhl_rs.Sequence(**_EXTRA, refresh_every=2, reuse_water_mask=True, guided_subsample="auto")
        out = {}
        sc = synth.scene(240, 320, kind="open_water", seed=31)
        for k in range(3):
            img = synth.render(np.roll(sc.clean, 4 * k, axis=1), np.roll(sc.distance, 4 * k, axis=1), "IA",
                               beta_b=0.2, noise=0.003, seed=k)
            out[f"frame{k}"] = _fingerprint(seq.restore(img))
        return out

    for name, extra in [
        ("udc_hazed5.jpg", {}),
        ("uwhl_galdran1_input.jpg", {}),
        ("euvp_13.jpg", {}),
        ("uieb_866.png", {"max_side": 700}),
        ("chart_calib_2_under.jpg", {"max_side": 900, "selection": "fast"}),
        ("uwhl_ship_highres_input.jpg", {"guided_subsample": 2}),
    ]:
        def thunk(name=name, extra=dict(extra)):
            ms = extra.pop("max_side", None)
            img = _photo(name, ms)
            if img is None:
                return None
            return _fingerprint(_restore(img, **extra))
        cases.append((f"photo_{name}", thunk))
    return cases


_VOLATILE = {"seconds", "uwhl_version", "timings", "metadata"}


def _sidecar(path: str) -> dict:
    with open(path) as f:
        d = json.load(f)
    if _EXTRA and isinstance(d.get("parameters"), dict):
        d["parameters"] = {k: v for k, v in d["parameters"].items() if k not in _NEW_PARAMETERS}
    if isinstance(d.get("source"), dict):
        d["source"].pop("icc_profile", None)  # recorded since 079fa6a; its effect is in the pixels
    return {k: v for k, v in d.items() if k not in _VOLATILE}


def _tree(out: str) -> dict:
    res = {}
    for dp, _, fs in os.walk(out):
        for f in sorted(fs):
            if f == "summary.csv":  # seconds per input: checked by the tests, not a fingerprint
                continue
            p = os.path.join(dp, f)
            rel = os.path.relpath(p, out)
            if f.endswith(".json"):
                res[rel] = _sidecar(p)
            elif f.endswith((".tif", ".tiff")):
                import tifffile

                res[rel] = _digest(tifffile.imread(p))
            elif f.endswith(".png"):
                with open(p, "rb") as fh:  # the core's decoder: every bit of 16-bit samples
                    res[rel] = _digest(uwhl_rs._core._decode_png(fh.read(), 1 << 40))
            elif f.endswith(".jpg"):
                from PIL import Image

                with Image.open(p) as im:
                    res[rel] = _digest(np.asarray(im))
            else:
                with open(p, "rb") as fh:
                    res[rel] = hashlib.sha256(fh.read()).hexdigest()[:24]
    return dict(sorted(res.items()))


def command_cases():
    names = ["udc_hazed5.jpg", "euvp_13.jpg", "uieb_616.png"]
    srcs = [os.path.join(DATA, "images", n) for n in names]
    raw = os.path.join(DATA, "raw", "canon_eos_6d.dng")
    if not all(os.path.exists(s) for s in srcs):
        return []
    cases = []
    variants = [
        ("png16", ["--format", "png", "--bits", "16", "--max-side", "640"]),
        ("tiff_fast", ["--format", "tiff", "--selection", "fast", "--max-side", "800"]),
        ("png_types_subsample", ["--format", "png", "--water-type", "II", "--water-type", "3C",
                                 "--guided-subsample", "auto", "--max-side", "500"]),
    ]
    for tag, flags in variants:
        def py(flags=flags):
            with tempfile.TemporaryDirectory() as d:
                out = os.path.join(d, "out")
                r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", *srcs, "-o", out, "-q", *flags, *_FLAGS],
                                   capture_output=True, text=True)
                return {"exit": r.returncode, "files": _tree(out)}
        cases.append((f"uwhl_{tag}", py))

        def rs(flags=flags):
            if not os.path.exists(BINARY):
                return None
            with tempfile.TemporaryDirectory() as d:
                out = os.path.join(d, "out")
                r = subprocess.run([BINARY, *srcs, "-o", out, "-q", *flags, *_FLAGS], capture_output=True, text=True)
                return {"exit": r.returncode, "files": _tree(out)}
        cases.append((f"uwhl-rs_{tag}", rs))

    def seq_rs():
        if not os.path.exists(BINARY):
            return None
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out")
            lines = "".join(s + "\n" for s in srcs)
            r = subprocess.run([BINARY, "--stream", "--reuse-estimates", "2", "-o", out, "--max-side", "400",
                                "--format", "png", *_FLAGS], input=lines, capture_output=True, text=True)
            return {"exit": r.returncode, "files": _tree(out)}
    cases.append(("uwhl-rs_stream_reuse2", seq_rs))

    def seq_py():
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out")
            r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", *srcs, "-o", out, "-q",
                                "--reuse-estimates", "2", "--max-side", "400", "--format", "png", *_FLAGS],
                               capture_output=True, text=True)
            return {"exit": r.returncode, "files": _tree(out)}
    cases.append(("uwhl_reuse2", seq_py))

    if os.path.exists(raw):
        def raw_py():
            with tempfile.TemporaryDirectory() as d:
                out = os.path.join(d, "out")
                r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", raw, "-o", out, "-q",
                                    "--format", "png", "--max-side", "600", *_FLAGS], capture_output=True, text=True)
                return {"exit": r.returncode, "files": _tree(out)}
        cases.append(("uwhl_raw_dng", raw_py))
    return cases


def _normalise(obj, srcs_prefix: str):
    """Sidecars name the input path and outputs in temp folders: keep the
    base names only."""
    if isinstance(obj, dict):
        return {k: _normalise(v, srcs_prefix) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_normalise(v, srcs_prefix) for v in obj]
    if isinstance(obj, str) and os.sep in obj and (obj.startswith("/") or obj.startswith(".")):
        return os.path.basename(obj)
    return obj


def run_all() -> dict:
    out = {}
    for name, thunk in api_cases() + command_cases():
        fp = thunk()
        if fp is None:
            print(f"  skip  {name}", file=sys.stderr)
            continue
        out[name] = _normalise(fp, DATA)
        print(f"  done  {name}", file=sys.stderr)
    return out


def _diff(a, b, path=""):
    if type(a) is not type(b):
        yield f"{path}: {a!r} != {b!r}"
    elif isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                yield f"{path}/{k}: only in {'recorded' if k in a else 'current'}"
            else:
                yield from _diff(a[k], b[k], f"{path}/{k}")
    elif a != b:
        yield f"{path}: {a!r} != {b!r}"


def main(argv: list[str]) -> int:
    if len(argv) == 4 and argv[2] == "--method":
        _EXTRA["method"] = argv[3]
        _FLAGS.extend(["--method", argv[3]])
        argv = argv[:2]
    if len(argv) != 2 or argv[0] not in ("record", "check"):
        print(__doc__, file=sys.stderr)
        return 2
    mode, path = argv
    current = run_all()
    if mode == "record":
        with open(path, "w") as f:
            json.dump(current, f, indent=1, sort_keys=True)
        print(f"recorded {len(current)} cases in {path}")
        return 0
    with open(path) as f:
        recorded = json.load(f)
    bad = 0
    for name in sorted(set(recorded) | set(current)):
        if name not in current:
            print(f"MISSING {name} (skipped in this run)")
            bad += 1
            continue
        if name not in recorded:
            print(f"NEW     {name}")
            continue
        diffs = list(_diff(recorded[name], current[name]))
        print(f"{'same   ' if not diffs else 'DIFFERS'} {name}")
        for d in diffs[:10]:
            print(f"          {d}")
        bad += bool(diffs)
    print(f"{len(current)} cases, {bad} different or missing")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
