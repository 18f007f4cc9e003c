"""How long ``uwhl report`` takes for a large batch (docs/REPORT.md):
restores N rendered photos (not timed), then times the report's first run
(every thumbnail written) and a second run (thumbnails kept), and the
page's size; then the batch's iFDO (``uwhl ifdo``, docs/OUTPUTS.md) and
its size; with ``--s3``, the outputs copied into moto's S3 server on
127.0.0.1 and the report and iFDO timed again on their URL (the
object-storage path of docs/REPORT.md; loopback, so it measures the
requests' count and the code, not a network).

    python3 benches/report_scale.py [--n 1000] [--size 480x640] [--s3]
"""

import argparse
import os
import shutil
import tempfile
import time

from uwhl_rs import batch, ifdo, report, synth
from uwhl_rs.images import write_image


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--size", default="480x640")
    ap.add_argument("--s3", action="store_true", help="also time the report and iFDO on moto's S3 server")
    a = ap.parse_args()
    h, w = (int(v) for v in a.size.split("x"))
    root = tempfile.mkdtemp(prefix="uwhl-report-bench-")
    src, out = os.path.join(root, "in"), os.path.join(root, "out")
    os.makedirs(src)
    for k in range(a.n):
        img, _ = synth.demo_input(h, w, water_type=["III", "1C", "II", "3C", "IB"][k % 5], seed=k % 25)
        write_image(os.path.join(src, f"p{k:05d}.jpg"), img, encoding="linear")
    t = time.perf_counter()
    batch.run_batch([src], out, options={"selection": "fast"})
    print(f"{a.n} photos of {w}x{h} restored in {time.perf_counter() - t:.0f} s (not the report's time)")
    for label in ("first run (thumbnails written)", "second run (thumbnails kept)"):
        done = report.write_report(out)
        print(f"report, {label}: {done['seconds']:.2f} s for {done['photos']} photos, "
              f"{done['thumbnails_written']} thumbnails written")
    page = os.path.getsize(done["path"])
    thumbs = sum(os.path.getsize(os.path.join(out, "report", "thumbs", f))
                 for f in os.listdir(os.path.join(out, "report", "thumbs")))
    print(f"index.html {page / 1e6:.2f} MB; thumbnails {thumbs / 1e6:.1f} MB in all")
    header = {"image-context": {"name": "bench"}, "image-project": {"name": "bench"}, "image-event": {"name": "bench"},
              "image-platform": {"name": "bench"}, "image-sensor": {"name": "bench"}, "image-pi": {"name": "bench"},
              "image-creators": [{"name": "bench"}], "image-license": {"name": "CC-BY-4.0"},
              "image-copyright": "bench", "image-abstract": "bench", "image-coordinate-uncertainty-meters": 1,
              "image-datetime": "2026-12-01 00:00:00.000", "image-latitude": 0.0, "image-longitude": 0.0,
              "image-altitude-meters": -10.0}
    t = time.perf_counter()
    done = ifdo.write_ifdo(out, header)
    print(f"ifdo.yaml: {time.perf_counter() - t:.2f} s for {done['items']} photos, "
          f"{os.path.getsize(done['path']) / 1e6:.2f} MB")
    if a.s3:
        _on_s3(out, header)
    shutil.rmtree(root, ignore_errors=True)


def _on_s3(out: str, header: dict) -> None:
    """The report (first run and rerun) and the iFDO of ``out``'s photos and
    sidecars (the local report left out) on a moto S3 server."""
    import logging

    import s3fs
    from moto.server import ThreadedMotoServer

    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # moto's server logs every request

    os.environ.update(AWS_ACCESS_KEY_ID="bench", AWS_SECRET_ACCESS_KEY="bench", AWS_DEFAULT_REGION="us-east-1",
                      AWS_EC2_METADATA_DISABLED="true")
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    try:
        host, port = server.get_host_and_port()
        so = {"endpoint_url": f"http://{host}:{port}"}
        fs = s3fs.S3FileSystem(**so)
        fs.mkdir("bench")
        shutil.rmtree(os.path.join(out, "report"))
        t = time.perf_counter()
        fs.put(out + "/", "bench/out/", recursive=True)
        print(f"S3: outputs uploaded in {time.perf_counter() - t:.0f} s (not timed below)")
        url = "s3://bench/out"
        for label in ("first run", "second run"):
            done = report.write_report(url, storage_options=so)
            print(f"S3 report, {label}: {done['seconds']:.2f} s for {done['photos']} photos, "
                  f"{done['thumbnails_written']} thumbnails written")
        t = time.perf_counter()
        done = ifdo.write_ifdo(url, header, storage_options=so)
        print(f"S3 ifdo.yaml: {time.perf_counter() - t:.2f} s for {done['items']} photos")
    finally:
        server.stop()


if __name__ == "__main__":
    main()
