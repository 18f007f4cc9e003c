"""A hostile pass over the Python API (2026-12-05): what it found, each
against an answer known without the code."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import ParameterError, files, images, synth


@pytest.fixture(scope="module")
def img():
    return synth.demo_input(40, 50, water_type="3C", seed=1)[0]


@pytest.mark.parametrize("kw", [
    {"water_types": [("z", 1e-310, 1.0)]},   # a subnormal ratio: 1 / beta_BR was infinite
    {"water_types": [("z", 1.0, 0.99 / 30)]},
    {"water": {"beta": [1e300, 1.0, 1e-10]}},  # beta_B / beta_R of about 1e-310
])
def test_a_ratio_below_one_thirtieth_is_refused_by_name(img, kw):
    with pytest.raises(ParameterError, match=r"must be a finite number in \[1/30, 30\]"):
        uwhl_rs.restore(img, **kw)


def test_the_smallest_ratio_accepted_restores_to_finite_colours(img):
    r = uwhl_rs.restore(img, water_types=[("z", 1 / 30, 1 / 30)])
    assert np.isfinite(r.image).all() and np.isfinite(r.transmission).all()


def test_a_mask_of_other_bytes_is_the_mask_numpy_sees(img):
    m = np.ones(img.shape[:2], bool)
    m[10:20, 10:30] = False
    odd = (m.astype(np.uint8) * 2).view(bool)  # True to NumPy, bytes of 2
    assert (odd == m).all()
    a, b = uwhl_rs.restore(img, mask=m), uwhl_rs.restore(img, mask=odd)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.transmission, b.transmission)
    # a water mask of every pixel, spelt with bytes of 2, is refused as the plain one is
    every = np.full(img.shape[:2], 2, np.uint8).view(bool)
    with pytest.raises(ParameterError):
        uwhl_rs.restore(img, water_mask=np.ones(img.shape[:2], bool))
    with pytest.raises(ParameterError):
        uwhl_rs.restore(img, water_mask=every)


@pytest.mark.parametrize("name", ["../escape", "a/b", ".", "..", "a\nb", "a\x1b[31m", 3])
def test_restore_file_takes_a_name_never_a_path(tmp_path, img, name):
    src = tmp_path / "in.png"
    images.write_image(src, img, bits=8, encoding="linear")
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(ParameterError, match="name must be a file name"):
        files.restore_file(src, out, name=name)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png", "out"]
    assert list(out.iterdir()) == []


def test_method_steps_records_the_fallback():
    assert uwhl_rs.method_steps(fallback="none")["fallback"] == "none"
    assert uwhl_rs.method_steps()["fallback"] == "input_balance"
    assert uwhl_rs.method_steps(method="paper")["fallback"] == "none"


def test_an_object_is_fetched_a_chunk_at_a_time(tmp_path, monkeypatch):
    """A URL input is copied to scratch in chunks of storage.CHUNK: fsspec's
    get_file held ten parts of 50 MiB of an S3 object in memory at once."""
    fsspec = pytest.importorskip("fsspec")
    from uwhl_rs import storage, tasks

    monkeypatch.setattr(storage, "CHUNK", 1 << 16)
    data = np.random.default_rng(1).integers(0, 256, 5 * (1 << 16) + 123, dtype=np.uint8).tobytes()
    fs = fsspec.filesystem("memory")
    fs.pipe("/s12/big.png", data)
    reads = []
    real_open = type(fs).open

    def watched_open(self, path, mode="rb", **kw):
        f = real_open(self, path, mode, **kw)
        read = f.read

        def counted(n=-1):
            block = read(n)
            reads.append(len(block))
            return block

        f.read = counted
        return f

    monkeypatch.setattr(type(fs), "open", watched_open)
    monkeypatch.setattr(type(fs), "get_file", lambda *a, **k: pytest.fail("the whole object at once"))
    local = tasks.fetch("memory://s12/big.png", str(tmp_path), {})
    assert open(local, "rb").read() == data
    assert max(reads) <= 1 << 16 and sum(reads) == len(data)
    fs.rm("/s12", recursive=True)


def test_a_planted_sidecar_does_not_make_the_report_fetch_other_objects(monkeypatch):
    """A sidecar in the output prefix naming another bucket's database is
    not fetched (the extension rule of local inputs holds for URLs), and a
    missing image key reads as a changed one: the page does not tell the
    planter which keys exist."""
    fsspec = pytest.importorskip("fsspec")
    from uwhl_rs import outdir, report, storage

    fs = fsspec.filesystem("memory")
    fs.pipe("/s12r/other/photo.jpg", b"not what was restored")
    fetched = []
    real = report.spool
    monkeypatch.setattr(report, "spool", lambda src, *a, **k: (fetched.append(src), real(src, *a, **k))[1])
    folder = storage.Folder("memory://s12r/run")

    def why(src):
        p = outdir.Photo("a.json", {"input": src, "metadata": {"input_sha256": "0" * 64}})
        f, reason = report._input_file(p, folder, outdir.Digests())
        assert f is None
        return reason.split(": ", 1)[1]

    assert why("memory://s12r/secret/db.sqlite").startswith("not an image file name")
    assert fetched == []
    assert why("memory://s12r/other/photo.jpg") == why("memory://s12r/other/gone.jpg")
    fs.rm("/s12r", recursive=True)


def test_a_listing_on_storage_skips_an_earlier_runs_output_folder_as_a_walk_does():
    """s3://b/dv restored to s3://b/dv/r2 after s3://b/dv/r1: r1's restored
    photo and maps are not inputs (a local walk skips such a folder with a
    note); a folder whose summary.csv is another program's is searched."""
    fsspec = pytest.importorskip("fsspec")
    from uwhl_rs import batch
    from uwhl_rs.outdir import CSV_COLUMNS

    fs = fsspec.filesystem("memory")
    fs.pipe("/s12w/dv/p.png", b"x")
    fs.pipe("/s12w/dv/r1/summary.csv", (",".join(CSV_COLUMNS) + "\n").encode())
    for f in ("p.jpg", "p_t.png", "p_t_color.png", "p_confidence.png"):
        fs.pipe(f"/s12w/dv/r1/{f}", b"x")
    fs.pipe("/s12w/dv/other/summary.csv", b"name,value\n")
    fs.pipe("/s12w/dv/other/q.png", b"x")
    try:
        plan = batch.plan_batch(["memory://s12w/dv"], "memory://s12w/dv/r2")
        assert sorted(it.input.split("s12w/", 1)[1] for it in plan.items) == ["dv/other/q.png", "dv/p.png"]
        assert any("s12w/dv/r1: an output folder of an earlier restore" in n for n in plan.notes), plan.notes
    finally:
        fs.rm("/s12w", recursive=True)


def test_thread_pools_of_many_thread_counts_are_not_all_kept():
    """Each thread count has its pool; a caller trying 1..40 kept all 40
    (820 threads). At most 8 are kept, the least recently used dropped:
    after 1..9 the pools of 2..9 (44 threads), after 1..40 those of 33..40
    (292). In a process of its own, so that no other test's threads count."""
    import os
    import subprocess
    import sys

    if not os.path.exists("/proc/self/status"):
        pytest.skip("needs /proc")
    script = """
import time, uwhl_rs
from uwhl_rs import synth
img, _ = synth.demo_input(32, 32, water_type="3C", seed=1)
def threads():
    return int(open("/proc/self/status").read().split("Threads:")[1].split()[0])
base = threads()
def settled(most):
    deadline = time.monotonic() + 30
    while threads() > base + most and time.monotonic() < deadline:
        time.sleep(0.05)  # a dropped pool's threads end on their own
    return threads() - base
for n in range(1, 10):
    uwhl_rs.restore(img, threads=n, water_types=["3C"])
print(settled(44))
for n in range(10, 41):
    uwhl_rs.restore(img, threads=n, water_types=["3C"])
print(settled(292))
"""
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert [int(x) for x in r.stdout.split()] == [44, 292], r.stdout


def test_a_given_water_is_named_by_its_beta(img):
    """The sidecar names the type the water was restored with: a water whose
    beta is Jerlov 9C's (0.3 / (2.0708, 1.5942, 1)) is not labelled I."""
    beta = [0.3 / 2.0708, 0.3 / 1.5942, 0.3]
    with pytest.raises(ParameterError, match="nearest_type is I, but its beta is nearest to 9C"):
        uwhl_rs.restore(img, water={"beta": beta, "nearest_type": "I"})
    assert uwhl_rs.restore(img, water={"beta": beta, "nearest_type": "9C"}).water_type == "9C"
    assert uwhl_rs.restore(img, water={"beta": beta}).water_type == "fitted"


@pytest.mark.parametrize("call, what", [
    (lambda d: uwhl_rs.Sequence(refresh_every=None), "refresh_every"),
    (lambda d: images.write_image(d / "x.png", np.zeros((4, 4, 3), np.float32), bits=8.0), "bits"),
    (lambda d: images.write_image(d / "x.jpg", np.zeros((4, 4, 3), np.float32), quality=None), "quality"),
    (lambda d: images.write_image(d / "x.jpg", np.zeros((4, 4, 3), np.float32), quality=float("nan")), "quality"),
    (lambda d: images.write_image(d / "x.jpg", np.zeros((4, 4, 3), np.float32), quality=2 ** 70), "quality"),
    (lambda d: images.write_image(d / "x.jpg", np.zeros((4, 4, 3), np.uint16)), "JPEG holds 8 bits"),
    (lambda d: uwhl_rs.read_distance(b"/x.npy"), "path"),
    (lambda d: images.read_image(None), "path"),
    (lambda d: files.restore_file(None, d), "in_path"),
    (lambda d: files.restore_file(d / "p.png", d / "o", contact="yes"), "contact"),
    (lambda d: files.restore_file(d / "p.png", d / "o", format=None), "format"),
    (lambda d: files.restore_file(d / "p.png", d / "o", bits=8.0), "bits"),
    (lambda d: files.restore_file(d / "p.png", d / "o", sequence="x"), "sequence"),
    (lambda d: files.restore_file(d / "p.png", d / "o", water_from=3), "water_from"),
    (lambda d: files.restore_file(d / "p.png", d / "o", mask=3), "mask"),
])
def test_an_argument_of_the_wrong_kind_is_a_parameter_error_naming_it(tmp_path, img, call, what):
    images.write_image(tmp_path / "p.png", img, bits=8, encoding="linear")
    with pytest.raises(ParameterError, match=what):
        call(tmp_path)


def test_sphere_points_out_of_range_is_named_as_such(img):
    """10**12 points is out of 1..1,000,000, said before the memory its index
    would take (a MemoryError named another problem)."""
    with pytest.raises(ParameterError, match="sphere_points"):
        uwhl_rs.restore(img, sphere_points=10 ** 12)


def test_a_mask_that_leaves_only_water_names_the_mask(img):
    """No water_mask given: the refusal names the mask, not a water_mask the
    caller never passed."""
    vl = uwhl_rs.restore(img).veiling_mask
    with pytest.raises(ParameterError, match=r"bad mask: leaves only pixels of the water region"):
        uwhl_rs.restore(img, mask=vl)
    with pytest.raises(ParameterError, match="bad water_mask: covers every pixel"):
        uwhl_rs.restore(img, mask=vl, water_mask=vl)


def test_big_endian_floats_are_the_same_image(img):
    """A big-endian float32 or float64 array (as FITS and some TIFFs store
    them) holds the same numbers: the same restoration, as distance maps
    already were."""
    a = uwhl_rs.restore(img)
    for dt in (">f4", ">f8"):
        b = uwhl_rs.restore(img.astype(dt))
        assert np.array_equal(a.image, b.image) and np.array_equal(a.transmission, b.transmission)


def test_a_restoration_survives_pickling(img):
    """A multiprocessing pool returns restorations by pickling them: every
    field comes back equal, with or without a distance."""
    import pickle

    z = np.full(img.shape[:2], 5.0, np.float32)
    for r in (uwhl_rs.restore(img), uwhl_rs.restore(img, distance=z), uwhl_rs.restore(img, method="paper")):
        b = pickle.loads(pickle.dumps(r))
        for k in ("image", "radiance", "transmission", "veiling_mask"):
            assert np.array_equal(getattr(r, k), getattr(b, k)), k
        assert (r.confidence is None) == (b.confidence is None)
        if r.confidence is not None:
            assert np.array_equal(r.confidence, b.confidence)
        for k in ("water_type", "beta_ratios", "scores", "excluded", "veiling_light", "flags", "veil_excess",
                  "fallback_share", "distance", "guided_radius", "guided_subsample", "timings"):
            assert getattr(r, k) == getattr(b, k), k
        assert np.array_equal(r.channel_transmissions(), b.channel_transmissions())
        assert repr(r) == repr(b)


def test_a_web_server_that_ignores_ranges_still_gives_a_large_input(tmp_path):
    """http.server answers every request whole (no ranges): a URL input of
    more than one chunk is fetched all the same."""
    pytest.importorskip("fsspec")
    pytest.importorskip("aiohttp")
    import functools
    import http.server
    import threading

    from uwhl_rs import storage, tasks

    data = np.random.default_rng(2).integers(0, 256, storage.CHUNK * 2 + 77, dtype=np.uint8).tobytes()
    (tmp_path / "srv").mkdir()
    (tmp_path / "srv" / "big.tif").write_bytes(data)
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(tmp_path / "srv"))
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    srv.daemon_threads = True
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        (tmp_path / "got").mkdir()
        local = tasks.fetch(f"http://127.0.0.1:{srv.server_address[1]}/big.tif", str(tmp_path / "got"), {})
        assert open(local, "rb").read() == data
    finally:
        srv.shutdown()
        srv.server_close()


def test_an_input_whose_own_name_holds_a_tab_is_restored(tmp_path, img):
    """The name check is for a caller's ``name``: an input's own stem (a tab
    in it) is a file name already, and restored as the commands restore it."""
    src = tmp_path / "tab\tx.png"
    images.write_image(src, img, bits=8, encoding="linear")
    r = files.restore_file(src, tmp_path / "o")
    assert os.path.basename(r.paths["image"]) == "tab\tx.jpg"


def test_restore_video_takes_a_name_never_a_path(tmp_path):
    pytest.importorskip("av")
    from uwhl_rs import clip, videofiles

    c = clip.clip(frames=3, height=32, width=48, seed=2)
    clip.write_clip(tmp_path / "v.mkv", c, codec="ffv1")
    (tmp_path / "out").mkdir()
    with pytest.raises(ParameterError, match="name must be a file name"):
        videofiles.restore_video(tmp_path / "v.mkv", tmp_path / "out", name="../escaped")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "v.mkv"]


def test_a_rerun_on_storage_does_not_call_its_own_output_folder_an_earlier_runs():
    fsspec = pytest.importorskip("fsspec")
    from uwhl_rs import batch
    from uwhl_rs.outdir import CSV_COLUMNS

    fs = fsspec.filesystem("memory")
    fs.pipe("/s12o/dv/p.png", b"x")
    fs.pipe("/s12o/dv/r1/summary.csv", (",".join(CSV_COLUMNS) + "\n").encode())
    fs.pipe("/s12o/dv/r1/p.jpg", b"x")
    try:
        plan = batch.plan_batch(["memory://s12o/dv"], "memory://s12o/dv/r1")
        assert [it.input.split("s12o/", 1)[1] for it in plan.items] == ["dv/p.png"]
        assert plan.notes == []
    finally:
        fs.rm("/s12o", recursive=True)


def test_an_overwrite_on_object_storage_in_another_format_leaves_no_earlier_image(tmp_path):
    """As in a folder (docs/OUTPUTS.md): the earlier sidecar's image of
    another --format goes with it; another input's object named like an
    output of this one stays."""
    import fsspec
    from uwhl_rs.batch import restore_many
    fs = fsspec.filesystem("memory")
    src = tmp_path / "x00.png"
    im, _ = synth.demo_input(48, 64, water_type="II", seed=0)
    images.write_image(src, im, bits=8, encoding="linear")
    restore_many([str(src)], "memory://s13ow/out", format="jpg")
    assert fs.exists("/s13ow/out/x00.jpg")
    # another input's outputs under a name an output of x00 could have
    fs.pipe("/s13ow/out/x00_sheet.png", b"another input's image")
    fs.pipe("/s13ow/out/x00_sheet.json", b"{}")
    restore_many([str(src)], "memory://s13ow/out", format="png", overwrite=True)
    names = {os.path.basename(p) for p in fs.ls("/s13ow/out", detail=False)}
    assert "x00.png" in names and "x00.jpg" not in names, names
    assert fs.cat("/s13ow/out/x00_sheet.png") == b"another input's image"
    fs.rm("/s13ow", recursive=True)


def test_another_inputs_sidecar_on_object_storage_is_neither_done_nor_written_over(tmp_path):
    """Two dives into one prefix: dive2/a.png was skipped as done because
    dive1's a.json was there (any object at NAME.json counted). As in a
    folder (docs/OUTPUTS.md "Names already in use"), a sidecar counts only
    if it records this input (by its name, or by the hash of its bytes);
    else the input takes the next free name and the other's outputs stay."""
    import fsspec
    from uwhl_rs.batch import restore_many
    fs = fsspec.filesystem("memory")
    out = "memory://s14n/out"
    for k, d in enumerate(["dive1", "dive2", "dive4"]):
        (tmp_path / d).mkdir()
        im, _ = synth.demo_input(48, 64, water_type="II", seed=k)
        images.write_image(tmp_path / d / "a.png", im, bits=8, encoding="linear")
    (tmp_path / "copy").mkdir()
    (tmp_path / "copy" / "a.png").write_bytes((tmp_path / "dive2" / "a.png").read_bytes())

    def run(d, **kw):
        rows = restore_many([str(tmp_path / d)], out, **kw)
        assert len(rows) == 1
        r = rows.iloc[0]
        return r["status"], os.path.basename(r["sidecar"] or "")

    try:
        assert run("dive1") == ("done", "a.json")
        first = fs.cat("/s14n/out/a.jpg")
        assert run("dive2") == ("done", "a_2.json")
        assert fs.cat("/s14n/out/a.jpg") == first
        # reruns find their own, under either name; the same bytes elsewhere are the same input
        assert run("dive1")[0] == "skipped" and run("dive2") == ("skipped", "a_2.json")
        assert run("copy") == ("skipped", "a_2.json")
        # an overwrite redoes its own name only
        assert run("dive2", overwrite=True) == ("done", "a_2.json")
        assert fs.cat("/s14n/out/a.jpg") == first
        # a planted object that is no sidecar of this input is passed by
        fs.pipe("/s14n/out/a_3.json", b"not json")
        assert run("dive4") == ("done", "a_4.json")
        assert fs.cat("/s14n/out/a_3.json") == b"not json"
    finally:
        fs.rm("/s14n", recursive=True)


def test_a_stored_input_named_another_way_recognises_its_sidecar(tmp_path):
    """A rerun that spells the input's URL otherwise (``memory:///x`` and
    ``memory://x``) finds the sidecar of the first run as its own."""
    import fsspec
    from uwhl_rs.batch import restore_many
    fs = fsspec.filesystem("memory")
    im, _ = synth.demo_input(48, 64, water_type="II", seed=3)
    images.write_image(tmp_path / "a.png", im, bits=8, encoding="linear")
    fs.put(str(tmp_path / "a.png"), "/s14u/in/a.png")
    try:
        assert restore_many(["memory:///s14u/in/a.png"], "memory://s14u/out").iloc[0]["status"] == "done"
        again = restore_many(["memory://s14u/in/a.png"], "memory://s14u/out").iloc[0]
        assert again["status"] == "skipped" and again["sidecar"].endswith("/a.json")
    finally:
        fs.rm("/s14u", recursive=True)


def test_two_dives_named_relatively_from_their_own_folders_into_one_prefix(tmp_path, monkeypatch):
    """``cd dive1 && uwhl restore a.png -o s3://...`` then the same in dive2:
    both sidecars say ``input: a.png``. The second photo is another input
    (its resolved path, else the hash of its bytes, decides), restored as
    a_2; each dive's rerun finds its own."""
    import fsspec
    from uwhl_rs.batch import restore_many
    fs = fsspec.filesystem("memory")
    for k, d in enumerate(["dive1", "dive2"]):
        (tmp_path / d).mkdir()
        im, _ = synth.demo_input(48, 64, water_type="II", seed=10 + k)
        images.write_image(tmp_path / d / "a.png", im, bits=8, encoding="linear")

    def run(d):
        monkeypatch.chdir(tmp_path / d)
        r = restore_many(["a.png"], "memory://s14r/out").iloc[0]
        return r["status"], os.path.basename(r["sidecar"] or "")

    try:
        assert run("dive1") == ("done", "a.json")
        assert run("dive2") == ("done", "a_2.json")
        assert run("dive1") == ("skipped", "a.json") and run("dive2") == ("skipped", "a_2.json")
        # a sidecar of an earlier build (no input_resolved): the hash decides
        doc = json.loads(fs.cat("/s14r/out/a.json"))
        doc.pop("input_resolved", None)
        fs.pipe("/s14r/out/a.json", json.dumps(doc).encode())
        assert run("dive2") == ("skipped", "a_2.json") and run("dive1") == ("skipped", "a.json")
    finally:
        fs.rm("/s14r", recursive=True)


def test_a_planted_sidecars_recorded_url_is_never_opened(tmp_path, monkeypatch):
    """The recorded input of a sidecar at the destination is text, compared
    with the input's URL: no file system is made from it (a chained URL such
    as ``zip://a::http://host/x.zip`` would fetch from that host while the
    batch is only being planned)."""
    import fsspec
    from uwhl_rs import batch, outdir
    fs = fsspec.filesystem("memory")
    im, _ = synth.demo_input(48, 64, water_type="II", seed=4)
    images.write_image(tmp_path / "a.png", im, bits=8, encoding="linear")
    fs.put(str(tmp_path / "a.png"), "/s14p/in/a.png")
    planted = ["zip://a.png::http://127.0.0.1:9/evil.zip", "http://127.0.0.1:9/a.png", "file:///etc/passwd",
               "memory://s14p/in/a.png::http://127.0.0.1:9/x"]
    for k, given in enumerate(planted):
        name = "a" if k == 0 else f"a_{k + 1}"
        fs.pipe(f"/s14p/out/{name}.json", json.dumps({"input": given, "metadata": {"input_sha256": "0" * 64}}).encode())
    seen = []
    real = outdir.filesystem

    def watched(url, so=None):
        seen.append(url)
        return real(url, so)

    monkeypatch.setattr(outdir, "filesystem", watched)
    try:
        plan = batch.plan_batch(["memory://s14p/in/a.png"], "memory://s14p/out")
        assert [it.name for it in plan.items] == ["a_5"] and plan.done == set()
        assert not [u for u in seen if u in planted or "127.0.0.1" in u or u.startswith("file:")], seen
    finally:
        fs.rm("/s14p", recursive=True)


def test_a_stored_input_restored_into_a_folder_is_skipped_at_rerun(tmp_path):
    """The sidecar of a URL input names it by its URL, which the hash rule
    for relative paths must not judge as a local file: a rerun skips it
    (it was restored again as a_2, a_3, ... each time)."""
    import fsspec
    from uwhl_rs.batch import restore_many
    fs = fsspec.filesystem("memory")
    im, _ = synth.demo_input(48, 64, water_type="II", seed=5)
    images.write_image(tmp_path / "a.png", im, bits=8, encoding="linear")
    fs.put(str(tmp_path / "a.png"), "/s14l/in/a.png")
    out = tmp_path / "out"
    try:
        assert restore_many(["memory://s14l/in/a.png"], str(out)).iloc[0]["status"] == "done"
        again = restore_many(["memory://s14l/in/a.png"], str(out)).iloc[0]
        assert again["status"] == "skipped" and again["sidecar"].endswith("a.json"), again.to_dict()
        assert not (out / "a_2.json").exists()
    finally:
        fs.rm("/s14l", recursive=True)


def test_two_dives_videos_of_one_name_are_two_inputs(tmp_path, monkeypatch):
    """A video's sidecar records its resolved path as a photo's does:
    ``cd dive2 && uwhl restore v.mkv`` into dive1's folder restores dive2's
    video as v_2 (it was skipped as done), and each rerun skips its own."""
    pytest.importorskip("av")
    from uwhl_rs import clip
    from uwhl_rs.batch import restore_many
    for k, d in enumerate(["dive1", "dive2"]):
        (tmp_path / d).mkdir()
        clip.write_clip(tmp_path / d / "v.mkv", clip.clip(frames=4, height=40, width=56, seed=k), codec="ffv1")
    out = tmp_path / "out"

    def run(d):
        monkeypatch.chdir(tmp_path / d)
        r = restore_many(["v.mkv"], str(out)).iloc[0]
        return r["status"], os.path.basename(r["sidecar"] or "")

    assert run("dive1") == ("done", "v.json")
    assert run("dive2") == ("done", "v_2.json")
    assert run("dive1") == ("skipped", "v.json") and run("dive2") == ("skipped", "v_2.json")


def _dives_of_one_stem(tmp_path, dives, seed, out):
    """A different photo ``a.png`` in each of ``dives`` under ``tmp_path``;
    returns run(*dives): restore_many of those photos into ``out``, as
    {dive: (status, sidecar name)}."""
    from uwhl_rs.batch import restore_many
    for k, d in enumerate(dives):
        (tmp_path / d).mkdir()
        im, _ = synth.demo_input(48, 64, water_type="II", seed=seed + k)
        images.write_image(tmp_path / d / "a.png", im, bits=8, encoding="linear")

    def run(*ds):
        rows = restore_many([str(tmp_path / d / "a.png") for d in ds], out)
        return {os.path.basename(os.path.dirname(r["input"])): (r["status"], os.path.basename(r["sidecar"]))
                for _, r in rows.iterrows()}

    return run


@pytest.mark.parametrize("dest", ["folder", "memory"])
def test_a_rerun_with_the_inputs_of_one_stem_in_another_order_skips_them(tmp_path, dest):
    """``uwhl restore d1/a.png d2/a.png`` names them a_png and a_png_2; a
    rerun given d2 first (or with a new d0 among them) named d2 a_png, found
    d1's sidecar there, and restored it again as a_png_2_2. The names a
    batch may have given an input (its stem, stem_ext, and their _2, _3,
    ...) are looked at for its own sidecar first."""
    import fsspec
    fs = fsspec.filesystem("memory")
    out = str(tmp_path / "out") if dest == "folder" else "memory://s14o/out"
    run = _dives_of_one_stem(tmp_path, ["d0", "d1", "d2"], 20, out)
    try:
        assert run("d1", "d2") == {"d1": ("done", "a_png.json"), "d2": ("done", "a_png_2.json")}
        assert run("d2", "d1") == {"d1": ("skipped", "a_png.json"), "d2": ("skipped", "a_png_2.json")}
        got = run("d0", "d1", "d2")
        assert got["d1"] == ("skipped", "a_png.json") and got["d2"] == ("skipped", "a_png_2.json")
        assert got["d0"][0] == "done" and got["d0"][1] not in ("a_png.json", "a_png_2.json")
        # alone, each is found under the name a batch of several gave it
        assert run("d2") == {"d2": ("skipped", "a_png_2.json")}
    finally:
        if dest == "memory":
            fs.rm("/s14o", recursive=True)


@pytest.mark.parametrize("dest", ["folder", "memory"])
def test_a_hole_among_the_names_of_a_stem_is_looked_past(tmp_path, dest):
    """d1 alone is ``a``; then d1 d2 d3 together: d1 is found at ``a``, d2
    and d3 take ``a_png_2`` and ``a_png_3``, and ``a_png`` stays empty. A
    look that stopped at the first name without a sidecar restored d3 again
    when it came alone."""
    import fsspec
    fs = fsspec.filesystem("memory")
    out = str(tmp_path / "out") if dest == "folder" else "memory://s14g/out"
    run = _dives_of_one_stem(tmp_path, ["d1", "d2", "d3"], 30, out)
    try:
        assert run("d1") == {"d1": ("done", "a.json")}
        got = run("d1", "d2", "d3")
        assert got["d1"] == ("skipped", "a.json") and got["d2"][0] == got["d3"][0] == "done"
        assert run("d3") == {"d3": ("skipped", got["d3"][1])}
        assert run("d2") == {"d2": ("skipped", got["d2"][1])}
    finally:
        if dest == "memory":
            fs.rm("/s14g", recursive=True)


def test_a_cluster_batch_into_a_folder_settles_as_done_only_the_inputs_own_sidecars(tmp_path):
    """A batch on a cluster settles what its plan finds done without a
    task. Into a local folder, any NAME.json counted, so dive2/a.png was
    skipped as done behind dive1's a.json (the claims, which tell them
    apart, never ran). The plan now takes a sidecar only if it records the
    input."""
    from uwhl_rs import batch
    out = str(tmp_path / "out")
    run = _dives_of_one_stem(tmp_path, ["dive1", "dive2"], 40, out)
    assert run("dive1") == {"dive1": ("done", "a.json")}
    assert batch.plan_batch([str(tmp_path / "dive2" / "a.png")], out).done == set()
    assert batch.plan_batch([str(tmp_path / "dive1" / "a.png")], out).done == {0}
    # a planted file at the name is no sidecar of anything
    (tmp_path / "out" / "b.json").write_text("{not json")
    (tmp_path / "dive1" / "b.png").write_bytes((tmp_path / "dive1" / "a.png").read_bytes())
    assert batch.plan_batch([str(tmp_path / "dive1" / "b.png")], out).done == set()
