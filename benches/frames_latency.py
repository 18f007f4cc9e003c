"""Per-frame latency of ``uwhl-rs --raw-frames`` (the vehicle case: one
water type and A reused between estimates), at 1080p and 4K, against the
camera's frame time and against the same binary estimating on every frame
(``--reuse-estimates 1``, the baseline, run in the same session):

    cargo build --release --features cli
    python3 benches/frames_latency.py [--binary target/release/uwhl-rs] [--frames 12] [--sizes 1920x1080,3840x2160]

A rendered reef (``uwhl_rs.synth``, METHOD §0) is panned across; frames go
in as rgb24 through a pipe from a writer thread and come out on another;
a frame's latency is the time from the moment its last byte was taken by
the binary to the moment its restored last byte arrived. The first frame
(which estimates, and whose buffers are new) is reported apart; the
others are the steady state (an estimate every 30 frames is outside the
measured frames). Each configuration: ``--guided-subsample 1`` (the exact
guided filter) and ``auto`` (He and Sun's fast guided filter, METHOD §6).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time

import numpy as np

from uwhl_rs import _core, synth


def frames_of(w: int, h: int, n: int, pan: int = 8) -> list[bytes]:
    """``n`` rgb24 frames of a reef panned ``pan`` columns a frame."""
    sc = synth.scene(h, w + pan * n, kind="open_water", seed=3)
    img = synth.render(sc.clean, sc.distance, "3C", beta_b=0.2, noise=0.004, seed=3)
    return [_core.frame_from_linear(np.ascontiguousarray(img[:, k * pan:k * pan + w]), "bt709", 8).tobytes()
            for k in range(n)]


def run(binary: str, frames: list[bytes], w: int, h: int, extra: list[str]) -> list[float]:
    """Each frame's latency in seconds."""
    p = subprocess.Popen([binary, "restore", "--raw-frames", f"{w}x{h}", "-o", "-", "-q", *extra],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    sent: list[float] = []
    size = len(frames[0])

    def feed():
        for f in frames:
            p.stdin.write(f)
            p.stdin.flush()
            sent.append(time.perf_counter())
        p.stdin.close()

    t = threading.Thread(target=feed)
    t.start()
    arrived = []
    for _ in frames:
        got = 0
        while got < size:
            chunk = p.stdout.read1(size - got) if hasattr(p.stdout, "read1") else p.stdout.read(size - got)
            if not chunk:
                raise RuntimeError(p.stderr.read().decode())
            got += len(chunk)
        arrived.append(time.perf_counter())
    t.join()
    p.wait()
    # the pipe holds 64 KiB: a frame's write returns once the binary has taken all but that much of it
    return [a - s for a, s in zip(arrived, sent)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join("target", "release", "uwhl-rs"))
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--sizes", default="1920x1080,3840x2160")
    a = ap.parse_args(argv)
    print("| frames | guided filter | first frame (s) | steady state, median (s) | frames/s | 30 fps frame time x | "
          "estimating every frame (s) | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for size in a.sizes.split(","):
        w, h = (int(v) for v in size.split("x"))
        frames = frames_of(w, h, a.frames)
        for sub in ("1", "auto"):
            lat = run(a.binary, frames, w, h, ["--guided-subsample", sub])
            base = run(a.binary, frames[:4], w, h, ["--guided-subsample", sub, "--reuse-estimates", "1"])
            steady = float(np.median(lat[1:]))
            every = float(np.median(base[1:]))
            print(f"| {w}x{h} | {'exact' if sub == '1' else 'fast (auto)'} | {lat[0]:.2f} | {steady:.3f} | "
                  f"{1 / steady:.1f} | {steady / (1 / 30):.1f} | {every:.3f} | {steady / every:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
