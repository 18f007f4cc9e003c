"""kill -9 at random moments, then check what a reader finds (docs/OUTPUTS.md,
"What a reader may find"). Not in CI: run it by hand after changing how
outputs are written.

    python3 benches/kill_loop.py [--face rust|python|both] [--kills 60] [--frames 12]

For each face: renders frames, then repeatedly starts `restore` (a batch,
or the binary's stream mode on every other round) on one output folder and
kills it with SIGKILL after a random delay. After every kill, every sidecar
in the folder must list outputs that exist, decode and have the sidecar's
processed size, and must name an input of the batch under that input's
name. A last run without kills must then complete every input, and leave no
temporary or claim behind. Prints one line per face: kills, sidecars seen,
violations (0 expected).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time

from PIL import Image

import uwhl_rs
from uwhl_rs import synth

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def binary() -> str:
    env = os.environ.get("UWHL_RS_BIN")
    if env:
        return env
    subprocess.run(["cargo", "build", "--release", "--features", "cli", "--bin", "uwhl-rs"], cwd=ROOT, check=True)
    return os.path.join(ROOT, "target", "release", "uwhl-rs")


def check(out: str, inputs: dict[str, str]) -> tuple[int, list[str]]:
    """(sidecars seen, violations) in the output folder."""
    bad = []
    seen = 0
    for f in sorted(os.listdir(out)):
        if not f.endswith(".json"):
            continue
        seen += 1
        try:
            side = json.load(open(os.path.join(out, f)))
        except Exception as e:
            bad.append(f"{f}: unreadable sidecar ({e})")
            continue
        name = os.path.basename(side.get("input", ""))
        if name not in inputs:
            bad.append(f"{f}: names an unknown input {side.get('input')!r}")
        h, w = side["source"]["processed_height"], side["source"]["processed_width"]
        for role, rel in side["outputs"].items():
            p = os.path.join(out, rel)
            try:
                with Image.open(p) as im:
                    im.load()
                    if im.size != (w, h):
                        bad.append(f"{f}: {role} {rel} is {im.size}, not {(w, h)}")
            except Exception as e:
                bad.append(f"{f}: {role} {rel} missing or broken ({type(e).__name__}: {e})")
    return seen, bad


def run_face(face: str, kills: int, frames: int, seed: int) -> tuple[int, int, list[str]]:
    rng = random.Random(seed)
    work = tempfile.mkdtemp(prefix=f"uwhl-kill-{face}-")
    src = os.path.join(work, "in")
    out = os.path.join(work, "out")
    os.makedirs(src)
    inputs = {}
    for k in range(frames):
        img, _ = synth.demo_input(360, 480, water_type=["II", "3C", "7C"][k % 3], seed=k)
        name = f"frame{k:03d}.png"
        uwhl_rs.images.write_image(os.path.join(src, name), img, bits=8, encoding="linear")
        inputs[name] = os.path.join(src, name)
    exe = binary()
    env = dict(os.environ)
    violations: list[str] = []
    seen_total = 0
    for i in range(kills):
        stream = face == "rust" and i % 2 == 1
        if face == "rust":
            cmd = [exe, "restore", "--format", "png", "-o", out] + (["--stream"] if stream else [src])
        else:
            cmd = [sys.executable, "-m", "uwhl_rs", "restore", src, "-o", out, "--format", "png"]
        if rng.random() < 0.3:
            cmd.append("--overwrite")
        p = subprocess.Popen(cmd, stdin=subprocess.PIPE if stream else subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, text=True)
        if stream:
            p.stdin.write("".join(f"{v}\n" for v in inputs.values()))
            p.stdin.close()
        time.sleep(rng.uniform(0.0, 2.5 if face == "rust" else 4.0))
        p.send_signal(signal.SIGKILL)
        p.wait()
        seen, bad = check(out, inputs)
        seen_total += seen
        violations += [f"kill {i}: {b}" for b in bad]
    final = [exe, "restore", src, "-o", out, "--format", "png"] if face == "rust" else \
        [sys.executable, "-m", "uwhl_rs", "restore", src, "-o", out, "--format", "png"]
    r = subprocess.run(final, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        violations.append(f"final run: exit {r.returncode}: {r.stderr[-500:]}")
    seen, bad = check(out, inputs)
    violations += [f"final: {b}" for b in bad]
    names = {os.path.basename(json.load(open(os.path.join(out, f)))["input"])
             for f in os.listdir(out) if f.endswith(".json")}
    if names != set(inputs):
        violations.append(f"final: inputs without a sidecar: {sorted(set(inputs) - names)}")
    left = [f for f in os.listdir(out) if f.startswith(".uwhl-")]
    if left:
        violations.append(f"final: left behind {left}")
    return kills, seen_total, violations


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--face", choices=["rust", "python", "both"], default="both")
    ap.add_argument("--kills", type=int, default=60)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    faces = ["rust", "python"] if a.face == "both" else [a.face]
    total_bad = 0
    for face in faces:
        kills, seen, bad = run_face(face, a.kills, a.frames, a.seed)
        total_bad += len(bad)
        print(f"{face}: {kills} kills, {seen} sidecars checked after kills, {len(bad)} violations")
        for b in bad[:20]:
            print("   ", b)
    return 1 if total_bad else 0


if __name__ == "__main__":
    sys.exit(main())
