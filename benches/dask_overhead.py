"""What the Dask path costs (docs/SCALE.md): seconds per photo for the same
small photos restored by a local ``uwhl restore`` run, by ``uwhl_rs.batch``
in this process, and on a local Dask cluster of 1 and 2 worker processes;
then one 12 MP photo through the whole file path, and the bytes it reads
and writes, for the projections of docs/SCALE.md.

    python3 benches/dask_overhead.py [--n 50] [--size 480x640] [--repeat 2]

Not a test: numbers depend on the machine; run them side by side here.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

from uwhl_rs import batch, synth
from uwhl_rs import cluster as dask_cluster
from uwhl_rs.images import write_image


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--size", default="480x640")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--big", default="3000x4000", help="HxW of the large photo (12 MP)")
    a = ap.parse_args()
    h, w = (int(v) for v in a.size.split("x"))
    root = tempfile.mkdtemp(prefix="uwhl-bench-")
    src = os.path.join(root, "in")
    os.makedirs(src)
    for k in range(a.n):
        img, _ = synth.demo_input(h, w, water_type=["III", "1C", "II", "3C", "IB"][k % 5], seed=k)
        write_image(os.path.join(src, f"p{k:03d}.jpg"), img, encoding="linear")
    results = {}

    def best(label, fn):
        times = []
        for r in range(a.repeat):
            out = os.path.join(root, f"out-{label}-{r}")
            t = time.perf_counter()
            fn(out)
            times.append(time.perf_counter() - t)
            shutil.rmtree(out, ignore_errors=True)
        results[label] = min(times) / a.n
        print(f"{label:<28} {min(times):7.2f} s  {min(times) / a.n * 1000:8.1f} ms/photo", flush=True)

    def command(out):
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", src, "-o", out, "-q"], capture_output=True)
        assert r.returncode == 0, r.stderr

    def in_process(out):
        res = batch.run_batch([src], out)
        assert all(row["status"] == "done" for row in res.rows)

    best("local uwhl restore", command)
    best("batch in this process", in_process)
    for n in (1, 2):
        t = time.perf_counter()
        client, cluster, threads = dask_cluster.connect(None, f"local:{n}", None)
        start = time.perf_counter() - t
        try:
            # one warm-up photo: the workers import the package once
            batch.run_batch([os.path.join(src, "p000.jpg")], os.path.join(root, "warm"), client=client,
                            options={"threads": threads})

            def on_cluster(out, client=client, threads=threads):
                res = batch.run_batch([src], out, client=client, options={"threads": threads})
                assert all(row["status"] == "done" for row in res.rows)

            best(f"dask local:{n}", on_cluster)
        finally:
            client.close()
            cluster.close()
        print(f"  (cluster start {start:.2f} s, not counted)")
    overhead = results["dask local:1"] - results["batch in this process"]
    print(f"per-photo overhead of the Dask path (1 worker against this process): {overhead * 1000:.1f} ms")
    print(f"2 workers against 1: {results['dask local:1'] / results['dask local:2']:.2f}x the throughput")

    # one 12 MP photo, the whole file path, and its bytes
    bh, bw = (int(v) for v in a.big.split("x"))
    big = os.path.join(root, "big")
    os.makedirs(big)
    img, _ = synth.demo_input(bh, bw, water_type="3C", seed=3)
    write_image(os.path.join(big, "big.jpg"), img, encoding="linear")
    del img
    times = []
    for r in range(a.repeat):
        out = os.path.join(root, f"big-out-{r}")
        t = time.perf_counter()
        res = batch.run_batch([big], out)
        times.append(time.perf_counter() - t)
        assert res.rows[0]["status"] == "done", res.rows[0]
        side = json.load(open(os.path.join(out, "big.json")))
        written = sum(os.path.getsize(os.path.join(out, f)) for f in os.listdir(out))
    read = os.path.getsize(os.path.join(big, "big.jpg"))
    print(f"12 MP photo ({bw}x{bh}): {min(times):.2f} s through the file path "
          f"(restore {side['seconds']['restore']:.2f} s); reads {read / 1e6:.1f} MB, writes {written / 1e6:.1f} MB")
    shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
