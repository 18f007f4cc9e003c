#!/usr/bin/env python3
"""uwhl_rs against the NumPy/SciPy reference implementation, side by side.

Run from the repository root with the package importable::

    python3 benches/compare.py            # 1, 2.7 and 12 MP (the reference runs in full at 2.7 MP)
    python3 benches/compare.py --quick    # 0.25 and 1 MP
    PYTHONPATH=python python3 benches/compare.py --quick     # a development build
    python3 benches/compare.py --package DIR                 # import uwhl_rs from DIR (e.g. an older build)

On the same rendered inputs (``uwhl_rs.synth.demo_input``), in one run:

* ``restore``: ``uwhl_rs.restore`` with all ten water types (best of a
  few calls), ``selection="fast"`` where the package has it, and the
  sequence mode (one type and the veiling light of a previous call) at
  1920x1080; both also with ``guided_subsample="auto"`` (METHOD §6, subsampled guided filter);
  and the frames of a ``uwhl_rs.Sequence`` (METHOD §10, sequence mode) where the
  package has it;
* ``reference``: ``tests/python/reference.py``'s ``restore`` (imported by path).
  It runs in full where the table says "full"; where it says "scaled from
  HxW", it ran on a crop of that size and its time is scaled by the pixel
  count (it is linear in the pixel count);
* ``floor``: reading the input and writing the outputs (image, radiance,
  transmission) once with NumPy: the memory traffic no implementation can
  avoid;
* peak resident memory of one call, measured in a fresh subprocess
  (``VmHWM``: includes the input array, the outputs and the interpreter
  with NumPy), also as a multiple of the float32 input;
* ``python -X importtime -c "import uwhl_rs"``: the package's own import
  time (its modules' self times) and what it adds beyond NumPy;
* ``selection="fast"`` against the exhaustive mode: the chosen water type on
  every shared photo (``../shared/data/images``, when present) and on renders
  of the ten types;
* the commands on a folder of 20 panning 1080p JPEG frames (sequence mode:
  ``--reuse-estimates``, ``--guided-subsample auto``), reading, restoring
  and writing every output: ``uwhl restore`` and, where built,
  ``uwhl-rs --stream`` (``--binary``); with ``--baseline`` /
  ``--baseline-binary`` the older build's commands on the same frames,
  alternating;
* with ``--baseline DIR``: this build and the one in DIR, each timed in
  fresh processes by the same harness (an untimed warm-up call, then a
  timed one), alternating; their ratio is the speed-up over the baseline.
  (Timing one build cold, as a first call, against warm calls of the other
  overstates the ratio by 15-20%: both are timed the same way.)

Timings on a shared machine are noisy: compare rows of the same run.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import pathlib
import re
import subprocess
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _import_package(pkg_dir: str | None):
    if pkg_dir:
        sys.path.insert(0, str(pathlib.Path(pkg_dir).resolve()))
    try:
        import uwhl_rs  # noqa: F401
        from uwhl_rs import synth  # noqa: F401
    except ImportError as exc:  # pragma: no cover - a clear message for a missing build
        sys.exit(f"cannot import uwhl_rs ({exc}); install it or run with PYTHONPATH=python")
    return sys.modules["uwhl_rs"]


def _reference():
    spec = importlib.util.spec_from_file_location("uwhl_reference", ROOT / "tests" / "python" / "reference.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def floor_time(img: np.ndarray, best_of, n: int = 5) -> float:
    """Read the input once and write the three outputs once (float32)."""
    h, w = img.shape[:2]
    out_image = np.empty_like(img)
    out_radiance = np.empty_like(img)
    out_t = np.empty((h, w), dtype=np.float32)

    def run():
        np.multiply(img, np.float32(1.0), out=out_image)
        np.copyto(out_radiance, out_image)
        np.copyto(out_t, out_image[..., 2])

    return best_of(run, n)


_TIME = r"""
import sys, time, numpy as np
sys.path.insert(0, {pkg!r})
import uwhl_rs
img = np.load({path!r})
uwhl_rs.restore(img)  # warm-up: thread pool, sphere index, heap
best = float("inf")
for _ in range({reps}):
    t = time.perf_counter()
    uwhl_rs.restore(img)
    best = min(best, time.perf_counter() - t)
print(best)
"""


def time_in_process(pkg: str, img: np.ndarray, tmp: pathlib.Path, reps: int = 1) -> float:
    """Best of `reps` all-ten-types calls of the package in `pkg`, in a fresh
    process, after one untimed warm-up call (the same harness for the
    current build and the baseline, so that neither is timed cold)."""
    path = tmp / "baseline_input.npy"
    np.save(path, img)
    code = _TIME.format(pkg=str(pathlib.Path(pkg).resolve()), path=str(path), reps=reps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


# VmHWM (this process image's peak RSS): ru_maxrss would include the
# parent's peak, which Linux carries over a fork + exec.
_PEAK = r"""
import sys, json, numpy as np
sys.path[:0] = {paths!r}
def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
import uwhl_rs
img = np.load({path!r})
before = hwm()
res = uwhl_rs.restore(img, **{kw!r})
peak = hwm()
print(json.dumps({{"before_kb": before, "peak_kb": peak}}))
"""


def peak_rss(img: np.ndarray, kw: dict, tmp: pathlib.Path) -> dict:
    """Peak RSS of a fresh interpreter that loads `img` and restores it once."""
    path = tmp / f"peak_{img.shape[0]}x{img.shape[1]}.npy"
    np.save(path, img)
    paths = [p for p in sys.path if p]
    code = _PEAK.format(paths=paths, path=str(path), kw=kw)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    path.unlink()
    return json.loads(out.stdout.strip().splitlines()[-1])


def import_times(n: int = 7) -> dict:
    """Best of n `python -X importtime -c "import uwhl_rs"`: the package's
    modules' self time, NumPy's cumulative time, and the package's
    cumulative time beyond NumPy (all in ms)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    best = None
    for _ in range(n):
        out = subprocess.run(
            [sys.executable, "-X", "importtime", "-c", "import uwhl_rs"],
            capture_output=True, text=True, env=env, check=True,
        ).stderr
        own = numpy_cum = pkg_cum = 0.0
        for line in out.splitlines():
            m = re.match(r"import time:\s+(\d+)\s+\|\s+(\d+)\s+\|(\s*)(\S+)", line)
            if not m:
                continue
            self_us, cum_us, name = int(m.group(1)), int(m.group(2)), m.group(4)
            if name == "uwhl_rs" or name.startswith("uwhl_rs."):
                own += self_us
            if name == "numpy" and len(m.group(3)) <= 3:
                numpy_cum = max(numpy_cum, cum_us)
            if name == "uwhl_rs":
                pkg_cum = cum_us
        rec = {"self_ms": own / 1e3, "numpy_ms": numpy_cum / 1e3, "beyond_numpy_ms": (pkg_cum - numpy_cum) / 1e3}
        if best is None or rec["beyond_numpy_ms"] < best["beyond_numpy_ms"]:
            best = rec
    return best


def fast_agreement(uw, synth, quick: bool, best_of) -> list[str]:
    """selection="fast" vs "exhaustive": the chosen type on every shared
    photo (sRGB decoded to linear, full size) and on renders of all ten
    types (540x1100, the copy is 270x550); returns the report lines."""
    import quality  # DATA_DIR, sRGB decoding

    import inspect

    has_sub = "guided_subsample" in inspect.signature(uw.restore).parameters
    rows, agree = [], {"photos": [0, 0, 0], "renders": [0, 0, 0]}

    def compare(kind, name, img):
        img = np.ascontiguousarray(img, dtype=np.float32)
        ex = uw.restore(img)
        fa = uw.restore(img, selection="fast")
        fs = uw.restore(img, selection="fast", guided_subsample="auto").water_type if has_sub else "-"
        same = ex.water_type == fa.water_type
        agree[kind][0] += same
        agree[kind][1] += 1
        agree[kind][2] += fs == ex.water_type
        t_ex = best_of(lambda: uw.restore(img), 1)
        t_fa = best_of(lambda: uw.restore(img, selection="fast"), 1)
        rows.append([kind[:-1], name, f"{img.shape[1]}x{img.shape[0]}", ex.water_type, fa.water_type,
                     "yes" if same else "NO", fs, f"{t_ex:.2f}", f"{t_fa:.2f}"])

    if quality.DATA_DIR.is_dir():
        import imageio.v3 as iio

        for p in sorted(quality.DATA_DIR.iterdir()):
            if p.suffix.lower() in (".jpg", ".jpeg", ".png"):
                compare("photos", p.name, quality.srgb_to_linear(quality.to_unit_float(iio.imread(p))))
    for water in (["III", "5C"] if quick else list(synth.JERLOV)):
        for seed in ((1,) if quick else (1, 2)):
            img, _ = synth.demo_input(540, 1100, water_type=water, seed=seed)
            compare("renders", f"{water} seed {seed}", img)
    out = [table(["kind", "input", "WxH", "exhaustive", "fast", "same", "fast + subsampled GF", "t exh s", "t fast s"],
                 rows)]
    out.append(f"agreement: shared photos {agree['photos'][0]}/{agree['photos'][1]}, "
               f"renders {agree['renders'][0]}/{agree['renders'][1]}")
    if has_sub:
        out.append(f"fast + guided_subsample='auto': shared photos {agree['photos'][2]}/{agree['photos'][1]}, "
                   f"renders {agree['renders'][2]}/{agree['renders'][1]}")
    return out


def command_throughput(uw, synth, tmp: pathlib.Path, args) -> list[list[str]]:
    """Times the commands on a folder of panning 1080p JPEG frames (best of
    two runs each, builds alternating)."""
    import imageio.v3 as iio

    frames = tmp / "frames"
    frames.mkdir(exist_ok=True)
    n = args.frames
    wide, _ = synth.demo_input(1080, 1920 + 8 * n, water_type="III", seed=13)
    for k in range(n):
        fr = np.clip(wide[:, 8 * k:8 * k + 1920], 0, 1)
        srgb = np.where(fr <= 0.0031308, 12.92 * fr, 1.055 * np.power(fr, 1 / 2.4) - 0.055)
        iio.imwrite(frames / f"f{k:03d}.jpg", (srgb * 255 + 0.5).astype(np.uint8), quality=95)
    paths = "".join(f"{frames / f'f{k:03d}.jpg'}\n" for k in range(n))
    here = str(pathlib.Path(uw.__file__).resolve().parent.parent)
    runs = [("uwhl restore", "this", here, None)]
    if args.baseline:
        runs.append(("uwhl restore", "baseline", args.baseline, None))
    if args.binary and os.path.exists(args.binary):
        runs.append(("uwhl-rs --stream", "this", None, args.binary))
    if args.baseline_binary:
        runs.append(("uwhl-rs --stream", "baseline", None, args.baseline_binary))
    best = {k: float("inf") for k in range(len(runs))}
    failed: dict[int, str] = {}
    for _ in range(2):
        for k, (_, _, pkg, binary) in enumerate(runs):
            if k in failed:
                continue
            out = tmp / f"frames_out_{k}"
            subprocess.run(["rm", "-rf", str(out)], check=True)
            t0 = time.perf_counter()
            if binary:
                r = subprocess.run([binary, "--stream", "--reuse-estimates", "1000", "--guided-subsample", "auto",
                                    "-o", str(out)], input=paths, capture_output=True, text=True)
            else:
                env = dict(os.environ, PYTHONPATH=pkg)
                r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(frames), "-o", str(out),
                                    "--reuse-estimates", "1000", "--guided-subsample", "auto", "-q"],
                                   env=env, capture_output=True, text=True)
            dt = time.perf_counter() - t0
            written = len(list(out.glob("*.json")))
            if r.returncode != 0 or written != n:
                # an older build without the command or its options
                failed[k] = f"not run: exit {r.returncode}, {written} of {n} sidecars"
                continue
            best[k] = min(best[k], dt)
    return [[cmd, build, failed[k], "-"] if k in failed else [cmd, build, f"{best[k]:.2f}", f"{n / best[k]:.1f}"]
            for k, (cmd, build, _, _) in enumerate(runs)]


def table(header, rows) -> str:
    cols = [header] + rows
    wid = [max(len(str(r[i])) for r in cols) for i in range(len(header))]
    line = lambda r: "  ".join(str(v).ljust(wid[i]) for i, v in enumerate(r))
    return "\n".join([line(header), line(["-" * w for w in wid])] + [line(r) for r in rows])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="0.25 and 1 MP only (minutes, not tens of minutes)")
    ap.add_argument("--package", help="import uwhl_rs from this directory (before/after comparisons)")
    ap.add_argument("--reference-crop", type=int, default=1000,
                    help="side of the square crop the reference runs on where it is scaled (default 1000)")
    ap.add_argument("--tmp", default=None, help="directory for the subprocess inputs (default: a temporary one)")
    ap.add_argument("--baseline", help="also time uwhl_rs from this directory (an older build); both builds are then "
                    "timed in fresh subprocesses (warm-up call, then timed calls), alternating, so both see the "
                    "same harness and machine load")
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "uwhl-rs"),
                    help="the uwhl-rs binary timed on the frame folder (default target/release/uwhl-rs, if built)")
    ap.add_argument("--baseline-binary", help="an older uwhl-rs timed on the same frames")
    ap.add_argument("--frames", type=int, default=20, help="frames in the command benchmark (default 20)")
    args = ap.parse_args(argv)

    uw = _import_package(args.package)
    from uwhl_rs import synth
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from quality import best_of  # one timing helper for both bench scripts

    ref = _reference()
    import inspect
    import tempfile

    has_fast = "selection" in inspect.signature(uw.restore).parameters
    has_sub = "guided_subsample" in inspect.signature(uw.restore).parameters
    print(f"uwhl_rs {uw.__version__} from {pathlib.Path(uw.__file__).parent}")
    print(f"cores: {os.cpu_count()}, numpy {np.__version__}, fast selection: {'yes' if has_fast else 'no'}")

    if args.quick:
        sizes = [("0.25MP", 500, 500, "full"), ("1MP", 1000, 1000, "scaled")]
        crop = 500
    else:
        sizes = [("1MP", 1000, 1000, "full"), ("2.7MP", 1340, 2010, "full"), ("12MP", 3000, 4000, "scaled")]
        crop = args.reference_crop

    rows, mem_rows = [], []
    tmpdir = tempfile.TemporaryDirectory() if args.tmp is None else None
    tmp = pathlib.Path(args.tmp or tmpdir.name)
    tmp.mkdir(parents=True, exist_ok=True)
    for label, h, w, ref_mode in sizes:
        img, _ = synth.demo_input(h, w, water_type="III", seed=11)
        img = np.ascontiguousarray(img, dtype=np.float32)
        reps = 3 if h * w <= 3_000_000 else 2
        res = uw.restore(img)  # warm-up (and the sphere index)
        t_all = best_of(lambda: uw.restore(img), reps)
        t_cur = t_base = float("nan")
        if args.baseline:
            # both builds in fresh processes with the same harness (warm-up,
            # then a timed call), alternating so that both see the same load
            here = str(pathlib.Path(uw.__file__).resolve().parent.parent)
            t_cur = t_base = float("inf")
            for _ in range(reps):
                t_cur = min(t_cur, time_in_process(here, img, tmp))
                t_base = min(t_base, time_in_process(args.baseline, img, tmp))
        t_fast = best_of(lambda: uw.restore(img, selection="fast"), reps) if has_fast else float("nan")
        fast_type = uw.restore(img, selection="fast").water_type if has_fast else "-"
        fast_sub_kw = {"selection": "fast", "guided_subsample": "auto"}
        t_fast_sub = best_of(lambda: uw.restore(img, **fast_sub_kw), reps) if has_sub else float("nan")
        t_floor = floor_time(img, best_of)
        if ref_mode == "full":
            t0 = time.perf_counter()
            rr = ref.restore(img)
            t_ref = time.perf_counter() - t0
            ref_note = "full"
            same = "yes" if rr["water_type"] == res.water_type else f"no ({rr['water_type']})"
        else:
            c = min(crop, h, w)
            sub = np.ascontiguousarray(img[:c, :c])
            t0 = time.perf_counter()
            ref.restore(sub)
            t_ref = (time.perf_counter() - t0) * (h * w) / (c * c)
            ref_note = f"scaled from {c}x{c}"
            same = "-"
        rows.append([
            label, f"{w}x{h}", f"{t_all:.3f}", f"{t_fast:.3f}" if has_fast else "-",
            f"{t_fast_sub:.3f}" if has_sub else "-",
            f"{t_cur:.3f} / {t_base:.3f} ({t_base / t_cur:.2f}x)" if args.baseline else "-",
            f"{t_ref:.1f}", ref_note, f"{t_ref / t_all:.0f}x", f"{t_floor * 1e3:.1f}",
            f"{t_all / t_floor:.0f}x", res.water_type, fast_type, same,
        ])
        for mode, kw in [("all ten types", {})] + ([("fast", {"selection": "fast"})] if has_fast else []):
            p = peak_rss(img, kw, tmp)
            mem_rows.append([
                label, mode, f"{img.nbytes / 2**20:.0f}", f"{p['before_kb'] / 1024:.0f}",
                f"{p['peak_kb'] / 1024:.0f}", f"{p['peak_kb'] * 1024 / img.nbytes:.1f}x",
                f"{(p['peak_kb'] - p['before_kb']) * 1024 / img.nbytes:.1f}x",
            ])
        print(f"  {label} done", flush=True)

    # sequence mode: the water type and veiling light of a previous frame
    img, _ = synth.demo_input(1080, 1920, water_type="III", seed=12)
    img = np.ascontiguousarray(img, dtype=np.float32)
    first = uw.restore(img)
    seq_kw = {"water_types": [first.water_type], "veiling_light": first.veiling_light}
    uw.restore(img, **seq_kw)
    t_seq = best_of(lambda: uw.restore(img, **seq_kw), 5)
    t_seq_sub = best_of(lambda: uw.restore(img, guided_subsample="auto", **seq_kw), 5) if has_sub else float("nan")
    t_seq_floor = floor_time(img, best_of)
    # the same frames through uwhl_rs.Sequence (work buffers kept between
    # frames; with reuse_water_mask the water detection is skipped too)
    seq_rows = []
    if hasattr(uw, "Sequence"):
        for label, kw in [("exact", {}), ("auto", {"guided_subsample": "auto"}),
                          ("auto, water region reused", {"guided_subsample": "auto", "reuse_water_mask": True})]:
            seq = uw.Sequence(**kw)
            seq.restore(img)  # estimates, untimed
            seq.restore(img)
            seq_rows.append((label, best_of(lambda: seq.restore(img), 5)))

    print()
    print("Whole restore (seconds; reference = tests/python/reference.py, NumPy/SciPy):")
    print(table(["size", "WxH", "uwhl_rs all 10", "uwhl_rs fast", "fast + subsampled GF", "this build / baseline, fresh processes", "reference", "reference run",
                 "speed-up", "floor ms", "x floor", "type", "fast type", "ref type same"], rows))
    print()
    print(f"Sequence mode (1920x1080, water_types=[{first.water_type!r}], veiling_light given): "
          f"{t_seq * 1e3:.1f} ms, {t_seq / t_seq_floor:.0f}x the floor ({t_seq_floor * 1e3:.1f} ms)")
    if has_sub:
        print(f"  with guided_subsample='auto': {t_seq_sub * 1e3:.1f} ms")
    for label, t in seq_rows:
        print(f"  uwhl_rs.Sequence frames ({label}): {t * 1e3:.1f} ms")
    frame_rows = command_throughput(uw, synth, tmp, args)

    print()
    print(f"Commands on {args.frames} panning 1920x1080 JPEG frames (--reuse-estimates, --guided-subsample auto; "
          "read, restore, write every output):")
    print(table(["command", "build", "seconds", "frames/s"], frame_rows))
    print()
    print("Peak resident memory of one call (fresh process; MiB; includes input, outputs, interpreter):")
    print(table(["size", "mode", "input", "before call", "peak", "peak / input", "(peak - before) / input"], mem_rows))
    if has_fast:
        print()
        print('selection="fast" vs exhaustive (water type chosen; one call each):')
        for line in fast_agreement(uw, synth, args.quick, best_of):
            print(line)
    it = import_times()
    print()
    print(f"import uwhl_rs: package self time {it['self_ms']:.1f} ms; numpy {it['numpy_ms']:.1f} ms; "
          f"added beyond numpy {it['beyond_numpy_ms']:.1f} ms (best of 7, -X importtime)")
    if tmpdir is not None:
        tmpdir.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
