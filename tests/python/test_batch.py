"""Batches on a Dask cluster and on object storage (uwhl_rs.batch,
docs/SCALE.md): the outputs equal a local run's, byte for byte; a worker
killed mid-batch loses nothing; an S3-compatible server (moto, started here
on 127.0.0.1) round-trips inputs and outputs; and every way a batch can fail
to start says why, with the exit code of docs/CLI.md."""

import filecmp
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

import uwhl_rs
from datapaths import IMAGES_DIR
from uwhl_rs import batch, storage, synth
from uwhl_rs import cluster as dask_cluster
from uwhl_rs.images import read_image, write_image

distributed = pytest.importorskip("distributed")
pd = pytest.importorskip("pandas")

ENV = {"PYTHONUNBUFFERED": "1"}

#: sidecar keys that differ between runs by nature (timings) or name the
#: resources of the process that ran it (a worker has its own share)
RUN_KEYS = ("seconds",)
RESOURCE_PARAMETERS = ("threads", "max_memory", "max_memory_used")


def run(*args, env=None, timeout=300):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *args], capture_output=True, text=True,
                          env=env or {**os.environ, **ENV}, timeout=timeout)


def make_inputs(folder, n=6, size=(120, 160), bad=True):
    """Renders of three water types (one in a sub-folder) and a corrupt JPEG."""
    os.makedirs(os.path.join(folder, "sub"), exist_ok=True)
    for k in range(n):
        img, _ = synth.demo_input(*size, water_type=["III", "1C", "II"][k % 3], seed=k)
        write_image(os.path.join(folder, "sub" if k >= n - 2 else "", f"f{k:02d}.png"), img, encoding="linear")
    if bad:
        with open(os.path.join(folder, "bad.jpg"), "wb") as f:
            f.write(b"\xff\xd8\xff\xe0 not a jpeg")
    return folder


def tree(root):
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            # summary.csv holds seconds and workers (tests/python/test_summary.py)
            if not f.startswith(".") and f != "summary.csv":
                out[os.path.relpath(os.path.join(d, f), root)] = os.path.join(d, f)
    return out


def sidecar_core(data: bytes, where: bool = True) -> dict:
    """A sidecar less what differs between runs by nature (and, unless
    ``where``, the input's location: a local copy against its URL)."""
    doc = json.loads(data)
    if not where:
        doc.pop("input")
        doc.pop("input_resolved", None)
        doc["source"].pop("path")
    for k in RUN_KEYS:
        doc.pop(k)
    for k in RESOURCE_PARAMETERS:
        doc["parameters"].pop(k)
    return doc


def assert_same_outputs(a, b, fetch=None, where=True):
    """The local run's outputs ``a`` (a folder) equal ``b`` (a folder, or
    keys read through ``fetch``): images byte for byte, sidecars except
    timings and the resource parameters."""
    ta = tree(a)
    if fetch is None:
        tb = tree(b)
        assert sorted(ta) == sorted(tb)
        get = lambda rel: open(tb[rel], "rb").read()  # noqa: E731
    else:
        get = fetch
    for rel, p in ta.items():
        data = get(rel)
        if rel.endswith(".json"):
            assert sidecar_core(open(p, "rb").read(), where) == sidecar_core(data, where), rel
        else:
            assert open(p, "rb").read() == data, rel


@pytest.fixture(scope="module")
def cluster():
    """Two worker processes on loopback, as ``--dask local:2`` makes them."""
    c, cl, threads = dask_cluster.connect(None, "local:2", None)
    yield c, threads
    c.close()
    cl.close()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    return make_inputs(str(tmp_path_factory.mktemp("in")))


@pytest.fixture(scope="module")
def local_run(inputs, tmp_path_factory):
    out = str(tmp_path_factory.mktemp("local"))
    r = run("restore", inputs, "-o", out, "-q")
    assert r.returncode == 3, r.stderr  # the corrupt input
    return out


# ------------------------------------------------------------ equality


def test_local_cluster_equals_local_run(cluster, inputs, local_run, tmp_path):
    client, threads = cluster
    out = str(tmp_path / "dask")
    df = batch.restore_many(inputs, out, client=client, threads=threads)
    assert list(df.columns) == batch.COLUMNS
    assert len(df) == 7
    by = dict(zip(df.input.map(os.path.basename), df.status))
    assert by.pop("bad.jpg") == "failed" and set(by.values()) == {"done"}
    bad = df[df.status == "failed"].iloc[0]
    assert bad.error_kind == "unreadable_input" and bad.exit_code == 3 and "cannot decode" in bad.error
    assert_same_outputs(local_run, out)
    done = df[df.status == "done"]
    # the summary says what the sidecars say
    for _, row in done.iterrows():
        side = json.load(open(row.sidecar))
        assert side["water_type"] == row.water_type
        assert [row.A_R, row.A_G, row.A_B] == side["veiling_light"]
        assert (row.veil_excess, row.fallback_share) == (side["veil_excess"], side["fallback_share"])
        assert os.path.exists(row.image) and row.worker.startswith("tcp://127.0.0.1:")
    # rerun: every done input is skipped, the corrupt one fails again
    again = batch.restore_many(inputs, out, client=client)
    assert sorted(again.status) == ["failed"] + ["skipped"] * 6


def test_cli_local_cluster_equals_local_run_and_resumes(inputs, local_run, tmp_path):
    out = str(tmp_path / "cli")
    r = run("restore", inputs, "-o", out, "--dask", "local:2")
    assert r.returncode == 3, r.stderr
    assert "Dask dashboard: http://127.0.0.1:" in r.stderr
    assert "6 done, 0 skipped, 1 failed" in r.stdout
    assert_same_outputs(local_run, out)
    r = run("restore", inputs, "-o", out, "--dask", "local:1")
    assert "0 done, 6 skipped, 1 failed" in r.stdout, r.stdout


@pytest.mark.skipif(not IMAGES_DIR.is_dir(), reason="../shared/data is not here")
def test_shared_photos_on_a_cluster_equal_a_local_run(cluster, tmp_path):
    client, threads = cluster
    photos = [str(IMAGES_DIR / n) for n in ("udc_hazed2.jpg", "uieb_866.png", "lcm_sample_5.jpg")
              if (IMAGES_DIR / n).exists()]
    if not photos:
        pytest.skip("the chosen shared photos are not here")
    local, out = str(tmp_path / "local"), str(tmp_path / "dask")
    r = run("restore", *photos, "-o", local, "-q", "--max-side", "640", "--format", "tiff")
    assert r.returncode == 0, r.stderr
    df = batch.restore_many(photos, out, client=client, threads=threads, max_side=640, format="tiff")
    assert set(df.status) == {"done"}
    assert_same_outputs(local, out)


def test_sequence_chunks_equal_a_local_sequence(cluster, inputs, tmp_path):
    client, threads = cluster
    frames = str(tmp_path / "frames")
    os.makedirs(frames)
    for k in range(7):
        img, _ = synth.demo_input(100, 140, water_type="3C", seed=100 + k)
        write_image(os.path.join(frames, f"frame{k:03d}.png"), img, encoding="linear")
    local, out = str(tmp_path / "local"), str(tmp_path / "dask")
    r = run("restore", frames, "-o", local, "-q", "--reuse-estimates", "3")
    assert r.returncode == 0, r.stderr
    df = batch.restore_many(frames, out, client=client, threads=threads, reuse_estimates=3)
    assert list(df.reused_estimates) == [False, True, True, False, True, True, False]
    assert_same_outputs(local, out)
    # a rerun after losing the middle of a chunk: the chunk's first frame
    # (done) estimates again, unwritten, so frame 4 reuses what it reused
    first = open(os.path.join(out, "frame004.jpg"), "rb").read()
    for suffix in (".json", ".jpg", "_t.png", "_t_color.png", "_confidence.png"):
        os.remove(os.path.join(out, "frame004" + suffix))
    again = batch.restore_many(frames, out, client=client, threads=threads, reuse_estimates=3)
    assert list(again.status) == ["skipped"] * 4 + ["done"] + ["skipped"] * 2
    assert open(os.path.join(out, "frame004.jpg"), "rb").read() == first
    assert json.load(open(os.path.join(out, "frame004.json")))["reused_estimates"] is True


# ------------------------------------------------------------ lost workers


def _kill_a_busy_worker(client, stop: threading.Event, killed: list):
    """SIGKILLs the process of a worker while it runs a restore task."""
    pids = client.run(os.getpid)
    while not stop.is_set():
        busy = {w: ts for w, ts in client.processing().items() if any("uwhl-restore" in str(t) for t in ts)}
        if busy:
            w = sorted(busy)[0]
            time.sleep(0.15)  # inside the task, past its start
            os.kill(pids[w], signal.SIGKILL)
            killed.append(w)
            return
        time.sleep(0.02)


def _batch_with_a_kill(c, src, out, threads):
    """Runs the batch while one busy worker is SIGKILLed; its rows."""
    stop, killed = threading.Event(), []
    killer = threading.Thread(target=_kill_a_busy_worker, args=(c, stop, killed))
    killer.start()
    try:
        df = batch.restore_many(src, out, client=c, threads=threads)
    finally:
        stop.set()
        killer.join()
    assert killed, "no worker was busy long enough to be killed"
    return df


def test_a_worker_killed_mid_batch_loses_nothing(tmp_path):
    src = make_inputs(str(tmp_path / "in"), n=10, size=(360, 480), bad=False)
    local = str(tmp_path / "local")
    assert run("restore", src, "-o", local, "-q").returncode == 0
    c, cl, threads = dask_cluster.connect(None, "local:2", None)
    try:
        out = str(tmp_path / "dask")
        df = _batch_with_a_kill(c, src, out, threads)
        # every input ends done: the killed worker's task ran again elsewhere, or,
        # when the kill landed after its outputs were committed (a task can end
        # within the killer's 0.15 s on a quick machine), the retry found them
        # whole and skipped it; either way the outputs are checked below
        st = list(df.status)
        assert set(st) <= {"done", "skipped"} and st.count("skipped") <= 1, df[["input", "status", "error"]]
        # ... with complete outputs that decode and equal the local run's
        assert_same_outputs(local, out)
        for p in tree(out).values():
            if p.endswith((".jpg", ".png")):
                assert read_image(p)[0].size > 0
        again = batch.restore_many(src, out, client=c)
        assert set(again.status) == {"skipped"}
        # what the killed worker left (its temporaries) went at the rerun's start
        assert not [f for f in os.listdir(out) if f.startswith(".uwhl-")]
    finally:
        c.close()
        cl.close()


def test_a_task_that_keeps_killing_workers_is_reported_failed(tmp_path):
    """With the scheduler allowing no failures, one kill fails the input:
    reported with the reason, the others done, nothing half-written."""
    import dask

    src = make_inputs(str(tmp_path / "in"), n=6, size=(360, 480), bad=False)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        c, cl, threads = dask_cluster.connect(None, "local:2", None)
    try:
        out = str(tmp_path / "dask")
        df = _batch_with_a_kill(c, src, out, threads)
        failed = df[df.status == "failed"]
        # an input the killed worker had finished is "skipped" when Dask runs it again for the result
        # that died with the worker: the rerun finds its outputs committed (whether a task ends before
        # the killer's 0.15 s depends on the machine); its outputs are whole
        assert len(failed) >= 1 and set(df.status) <= {"done", "failed", "skipped"}, df[["input", "status"]]
        for _, row in df[df.status == "skipped"].iterrows():
            name = os.path.splitext(os.path.basename(row.input))[0]
            assert read_image(os.path.join(out, name + ".jpg"))[0].size > 0
            assert os.path.exists(os.path.join(out, name + ".json"))
        for _, row in failed.iterrows():
            assert row.error_kind == "internal" and "died" in row.error and row.exit_code == 6
            name = os.path.splitext(os.path.basename(row.input))[0]
            assert not os.path.exists(os.path.join(out, name + ".json"))
        # the rerun does the failed ones only
        again = batch.restore_many(src, out, client=c, threads=threads)
        assert sorted(again.status) == sorted(["done"] * len(failed) + ["skipped"] * (6 - len(failed)))
    finally:
        c.close()
        cl.close()


# ------------------------------------------------------------ memory


def _huge_png_header(path, w, h):
    """A PNG whose header says ``w`` x ``h`` (no pixel data)."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) + chunk(b"IEND", b""))


def test_a_photo_over_every_workers_memory_fails_over_budget(cluster, inputs, tmp_path):
    client, threads = cluster
    src = str(tmp_path / "in")
    os.makedirs(src)
    _huge_png_header(os.path.join(src, "huge.png"), 16000, 16000)  # under max_pixels
    img, _ = synth.demo_input(80, 100)
    write_image(os.path.join(src, "small.png"), img, encoding="linear")
    df = batch.restore_many(src, str(tmp_path / "out"), client=client, threads=threads)
    huge, small = df.iloc[0], df.iloc[1]
    assert small.status == "done"
    assert huge.status == "failed" and huge.error_kind == "over_budget" and huge.exit_code == 4
    assert "every worker's memory" in huge.error
    # both workers are the ones the batch started with: none died on it
    assert len(client.scheduler_info()["workers"]) == 2


# ------------------------------------------------------------ object storage


@pytest.fixture(scope="module")
def s3(moto_s3):
    """moto's S3 server (conftest) with the bucket "survey"."""
    fs, endpoint = moto_s3
    fs.mkdir("survey")
    return fs, endpoint


def test_s3_round_trip_on_a_cluster(s3, cluster, inputs, local_run):
    fs, endpoint = s3
    client, threads = cluster
    fs.put(inputs + "/", "survey/dive_a/", recursive=True)
    so = {"endpoint_url": endpoint}
    # the workers started before the server's credentials were set: they get them as storage options
    df = batch.restore_many("s3://survey/dive_a/", "s3://survey/restored/dive_a/", client=client,
                            storage_options={**so, "key": "testing", "secret": "testing"}, threads=threads)
    assert sorted(df.status) == ["done"] * 6 + ["failed"]
    assert set(df[df.status == "done"].image.str.slice(0, 27)) == {"s3://survey/restored/dive_a"}
    assert_same_outputs(local_run, None, fetch=lambda rel: fs.cat(f"survey/restored/dive_a/{rel}"),
                        where=False)
    side = json.loads(fs.cat("survey/restored/dive_a/f00.json"))
    assert side["input"] == side["source"]["path"] == "s3://survey/dive_a/f00.png"
    # S3 -> local folder, through the command, in this process: the same files
    out = os.path.join(os.path.dirname(local_run), "from_s3")
    r = run("restore", "s3://survey/dive_a/", "-o", out, "--storage-option", f"endpoint_url={endpoint}", "-q")
    assert r.returncode == 3, r.stderr
    for rel, p in tree(local_run).items():
        if not rel.endswith(".json"):
            assert filecmp.cmp(p, os.path.join(out, rel), shallow=False), rel


def test_s3_outputs_get_an_ifdo_with_their_urls(s3, inputs, tmp_path):
    """``restore --ifdo`` with an object-storage OUTDIR: the iFDO is stored
    beside the photos, its handles are their s3:// URLs and its hashes those
    of the stored objects; it passes the standard's schema."""
    import hashlib

    import yaml
    from test_ifdo import HEADER, POSITION, validator

    fs, endpoint = s3
    fs.put(inputs + "/f00.png", "survey/dive_i/f00.png")
    fs.put(inputs + "/f01.png", "survey/dive_i/f01.png")
    head = tmp_path / "header.yaml"
    # renders have no EXIF time: the header gives the set's
    head.write_text(yaml.safe_dump({**HEADER, **POSITION, "image-datetime": "2026-11-30 09:00:00.000"}))
    r = run("restore", "s3://survey/dive_i/", "-o", "s3://survey/restored/dive_i/", "--storage-option",
            f"endpoint_url={endpoint}", "--ifdo", str(head), "-q")
    assert r.returncode == 0, r.stderr
    doc = yaml.safe_load(fs.cat("survey/restored/dive_i/ifdo.yaml"))
    validator().validate(doc)
    assert sorted(doc["image-set-items"]) == ["f00.jpg", "f01.jpg"]
    for name, item in doc["image-set-items"].items():
        assert item["image-handle"] == f"s3://survey/restored/dive_i/{name}"
        assert item["image-hash-sha256"] == hashlib.sha256(fs.cat(f"survey/restored/dive_i/{name}")).hexdigest()
    assert doc["image-set-header"]["image-set-name"] == "dive_i"
    # an unreachable store: named, exit 7, nothing claimed written
    r = run("ifdo", "s3://survey/restored/dive_i/", "--header", str(head), "--storage-option",
            f"endpoint_url=http://127.0.0.1:{_free_port()}")
    assert r.returncode == 7 and "cannot reach the storage" in r.stderr and "ifdo:" not in r.stdout, r.stderr


def _page_data(html_text: str) -> dict:
    start = html_text.index('<script id="data" type="application/json">') + len('<script id="data" type="application/json">')
    return json.loads(html_text[start:html_text.index("</script>", start)].replace("<\\/", "</"))


def test_s3_outputs_get_a_report_that_resolves_on_the_store(s3, inputs, tmp_path):
    """``restore --report`` and ``uwhl report`` with an object-storage
    OUTDIR: the page and its thumbnails are stored beside the photos, every
    link of the page resolves to a stored object, the thumbnails show the
    stored photos, a rerun writes none, and the page equals the one made
    from a local copy of the same outputs."""
    import posixpath

    import numpy as np
    from PIL import Image

    from uwhl_rs import report

    fs, endpoint = s3
    for name in ("f00.png", "f01.png", "bad.jpg", "sub/f04.png"):
        fs.put(f"{inputs}/{name}", f"survey/dive_r/{name}")
    dest = "s3://survey/restored/dive_r/"
    r = run("restore", "s3://survey/dive_r/", "-o", dest, "--storage-option", f"endpoint_url={endpoint}",
            "--report", "-q")
    assert r.returncode == 3, r.stderr  # bad.jpg
    page = fs.cat("survey/restored/dive_r/report/index.html").decode()
    assert "3 photos restored, 0 flagged, 1 failed" in page and "bad.jpg" in page and dest.rstrip("/") in page
    data = _page_data(page)["photos"]
    assert [d["name"] for d in data] == ["f00", "f01", "sub/f04"]
    base = "survey/restored/dive_r/report"
    for d in data:
        for key in ("ti", "to", "full", "t", "side"):
            assert d[key] and fs.exists(posixpath.normpath(posixpath.join(base, d[key]))), (d["name"], key, d[key])
        side = json.loads(fs.cat(posixpath.normpath(posixpath.join(base, d["side"]))))
        assert d["wt"] == side["water_type"] and d["A"] == side["veiling_light"]
        # the restored thumbnail is the stored photo made small: its mean colour matches
        thumb = np.asarray(Image.open(fs.open(posixpath.normpath(posixpath.join(base, d["to"])))), dtype=float)
        full = np.asarray(Image.open(fs.open(posixpath.normpath(posixpath.join(base, d["full"])))).convert("RGB"),
                          dtype=float)
        assert max(thumb.shape[:2]) <= report.THUMB_SIDE
        assert np.abs(thumb.mean(axis=(0, 1)) - full.mean(axis=(0, 1))).max() < 3.0
    assert len(fs.find("survey/restored/dive_r/report/thumbs")) == 6
    # a rerun keeps every thumbnail
    r = run("report", dest, "--storage-option", f"endpoint_url={endpoint}")
    assert r.returncode == 0 and "3 photos, 0 flagged, 1 failed, 0 thumbnails written" in r.stdout, r.stdout + r.stderr
    # a local copy of the outputs gives the same page data (its thumbnails kept)
    local = tmp_path / "copy"
    fs.get("survey/restored/dive_r/", str(local), recursive=True)
    # (a download stamps each file with its own arrival: the thumbnails are
    # made newer than the copied photos again, as they are on the store)
    later = time.time() + 5
    for f in (local / "report" / "thumbs").iterdir():
        os.utime(f, (later, later))
    assert report.write_report(str(local))["thumbnails_written"] == 0
    assert _page_data((local / "report" / "index.html").read_text())["photos"] == data
    # an unreachable store: named, exit 7, no report claimed
    r = run("report", dest, "--storage-option", f"endpoint_url=http://127.0.0.1:{_free_port()}")
    assert r.returncode == 7 and "cannot reach the storage" in r.stderr and "report:" not in r.stdout, r.stderr
    # an empty prefix of the store is no output folder
    r = run("report", "s3://survey/nothing_here/", "--storage-option", f"endpoint_url={endpoint}")
    assert r.returncode == 3 and "no such folder" in r.stderr, r.stderr


def test_s3_interrupted_outputs_without_sidecar_are_repaired(s3, inputs, local_run, monkeypatch):
    fs, endpoint = s3
    fs.put(inputs + "/", "survey/dive_b/", recursive=True)
    so = {"endpoint_url": endpoint}
    dest = "s3://survey/restored/dive_b"
    # an attempt that died after storing the photo, before the sidecar
    used = storage.filesystem(dest, so)[0]
    assert storage.filesystem(dest, so)[0] is used  # fsspec's one instance for these options
    real_put = used.put_file

    def dying_put(lpath, rpath, *a, **kw):
        if rpath.endswith("f01_t.png"):
            raise ConnectionError("the connection dropped")
        return real_put(lpath, rpath, *a, **kw)

    monkeypatch.setattr(used, "put_file", dying_put)
    df = batch.restore_many(["s3://survey/dive_b/f01.png", "s3://survey/dive_b/f02.png"], dest, storage_options=so)
    monkeypatch.undo()
    assert list(df.status) == ["failed", "done"]
    assert df.iloc[0].error_kind == "write_failed" and "connection dropped" in df.iloc[0].error
    assert fs.exists("survey/restored/dive_b/f01.jpg") and not fs.exists("survey/restored/dive_b/f01.json")
    # and a stale, wrong photo left by some earlier attempt
    fs.pipe("survey/restored/dive_b/f03.jpg", b"half an old jpeg")
    df = batch.restore_many("s3://survey/dive_b/", dest, storage_options=so)
    by = dict(zip(df.input.map(os.path.basename), df.status))
    assert by["f01.png"] == by["f03.png"] == "done" and by["f02.png"] == "skipped"
    for n in ("f01", "f03"):
        for suffix in (".jpg", "_t.png", "_t_color.png"):
            assert fs.cat(f"survey/restored/dive_b/{n}{suffix}") == open(os.path.join(local_run, n + suffix), "rb").read()
        assert fs.exists(f"survey/restored/dive_b/{n}.json")


def test_s3_through_the_command_on_a_cluster_and_missing_inputs(s3, inputs):
    fs, endpoint = s3
    fs.put(inputs + "/", "survey/dive_c/", recursive=True)
    so = ["--storage-option", f"endpoint_url={endpoint}"]
    r = run("restore", "s3://survey/dive_c/", "s3://survey/nothing_here.jpg", "-o", "s3://survey/restored/dive_c/",
            "--dask", "local:2", *so)
    assert r.returncode == 3, r.stderr
    assert "s3://survey/nothing_here.jpg: no such file or folder" in r.stderr
    assert "6 done, 0 skipped, 2 failed" in r.stdout
    assert len(fs.glob("survey/restored/dive_c/**/*.json")) == 6
    # the summary, written locally as the batch went, is uploaded at its end
    import csv
    import io

    rows = list(csv.DictReader(io.StringIO(fs.cat("survey/restored/dive_c/summary.csv").decode())))
    assert sorted(r["status"] for r in rows) == ["done"] * 6 + ["failed"] * 2


def test_s3_missing_credentials_are_named(s3):
    _, endpoint = s3
    env = {k: v for k, v in os.environ.items() if not k.startswith("AWS_")}
    env.update(AWS_SHARED_CREDENTIALS_FILE="/nonexistent", AWS_CONFIG_FILE="/nonexistent",
               AWS_EC2_METADATA_DISABLED="true")
    r = run("restore", "s3://survey/dive_a/", "-o", "s3://survey/out/", "--storage-option",
            f"endpoint_url={endpoint}", env=env)
    assert r.returncode == 7, r.stderr
    assert "no credentials" in r.stderr and "--storage-option key=" in r.stderr


def test_unreachable_storage_is_named(tmp_path):
    pytest.importorskip("s3fs")
    r = run("restore", "s3://survey/dive/", "-o", str(tmp_path / "o"), "--storage-option",
            f"endpoint_url=http://127.0.0.1:{_free_port()}", "--storage-option", "key=a", "--storage-option",
            "secret=b", "--json-errors")
    assert r.returncode == 7, r.stderr
    err = json.loads(r.stderr.strip().splitlines()[-1])
    assert err["error"] == "unreachable" and "cannot reach the storage" in err["message"]
    assert not os.listdir(tmp_path / "o")


# ------------------------------------------------------------ refusals


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_is_named(inputs, tmp_path):
    address = f"tcp://127.0.0.1:{_free_port()}"
    t = time.perf_counter()
    r = run("restore", inputs, "-o", str(tmp_path / "o"), "--dask", address, env={**os.environ, "UWHL_DASK_TIMEOUT": "2"})
    assert r.returncode == 7, r.stderr
    assert f"--dask {address}: cannot reach the Dask scheduler" in r.stderr
    assert time.perf_counter() - t < 60
    assert not [f for f in os.listdir(tmp_path / "o")]


@pytest.mark.parametrize("args, says", [
    (["--dask", "local:0"], "--dask"),
    (["--dask", "tcp://host"], "--dask"),
    (["--storage-option", "anon"], "KEY=VALUE"),
    (["--storage-option", "anon=true"], "--storage-option is for URL"),
    (["--dask", "local:2", "--jobs", "2"], "--jobs is for runs in this process"),
])
def test_bad_batch_arguments(inputs, tmp_path, args, says):
    r = run("restore", inputs, "-o", str(tmp_path / "o"), *args)
    assert r.returncode == 2 and says in r.stderr, r.stderr
    assert not os.path.exists(tmp_path / "o") or not os.listdir(tmp_path / "o")


def test_storage_options_are_parsed():
    assert batch.parse_storage_options(["anon=true", "endpoint_url=http://h:9000", "client_kwargs.region_name=eu",
                                        "default_block_size=1048576", "profile=null", "key=a=b"]) == {
        "anon": True, "endpoint_url": "http://h:9000", "client_kwargs": {"region_name": "eu"},
        "default_block_size": 1048576, "profile": None, "key": "a=b"}
    with pytest.raises(ValueError, match="KEY=VALUE"):
        batch.parse_storage_options(["=x"])
    with pytest.raises(ValueError, match="both as a value and as a group"):
        batch.parse_storage_options(["a=1", "a.b=2"])


def test_names_of_listed_inputs_follow_the_local_rules():
    """The naming the core gives folder walks, for listings from object
    storage (docs/OUTPUTS.md): stems shared in one folder take their
    extension; a name whose outputs another's would overwrite takes _2."""
    sfx = [".png", "_t.png", "_t_color.png"]
    found = [("s3://b/a.jpg", ""), ("s3://b/a.png", ""), ("s3://b/a_t.jpg", ""), ("s3://b/s/a.jpg", "s")]
    assert uwhl_rs._core.name_jobs(found, sfx) == ["a_jpg", "a_png", "a_t", "a"]
    assert uwhl_rs._core.name_jobs([("x/a.jpg", ""), ("x/a_t.jpg", "")], sfx) == ["a", "a_t_2"]


def test_without_the_extra_the_error_says_what_to_install(inputs, tmp_path):
    code = ("import sys; sys.modules['distributed'] = None; sys.modules['fsspec'] = None\n"
            "from uwhl_rs.cli import main\n"
            f"sys.exit(main(['restore', {inputs!r}, '-o', {str(tmp_path / 'o')!r}, '--dask', 'local:2']))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert 'pip install "uwhl_rs[dask]"' in r.stderr
    # importing the package (and this module) needs none of them
    code = ("import sys\nimport uwhl_rs, uwhl_rs.batch, uwhl_rs.cli\n"
            "print(sorted(m for m in ('dask', 'distributed', 'fsspec', 's3fs', 'pandas') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "[]", r.stdout + r.stderr


def test_workers_without_this_uwhl_rs_are_refused(inputs, tmp_path):
    """A worker that cannot import uwhl_rs (or has another version) would
    fail or change every task: the batch does not start."""
    import importlib.metadata

    c, cl, _ = dask_cluster.connect(None, "local:1", None)
    try:
        def hide():  # on the worker: its package metadata now says another version
            importlib.metadata.version = lambda name: "0.0.0-other"

        c.run(hide)
        with pytest.raises(batch.BatchError, match=r"1 of 1 Dask workers do not run uwhl_rs .*0\.0\.0-other"):
            batch.restore_many(inputs, str(tmp_path / "o"), client=c)
        assert not os.listdir(tmp_path / "o")
    finally:
        c.close()
        cl.close()
