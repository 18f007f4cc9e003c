"""What the report and evaluate read, planted (a hostile review): a file
many sidecars name is hashed once a run; sidecars are read one at a time
and their nesting measured without a byte loop; a thumbnail's source is
refused by its header's size and decoded only from an image format; the
rows of summary.csv read before a bad one are kept, and the page says
where the reading stopped; evaluate reads one page of a truth mask,
refuses a .mat whose arrays inflate past its map, a manifest that gives a
key twice, and writes results.csv's names as the console shows them."""

import json
import os
import subprocess
import sys
import zlib

import numpy as np
import pytest
from PIL import Image

import uwhl_rs
from uwhl_rs import outdir, report, sidecars, synth
from uwhl_rs.errors import ManifestError


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """One photo restored by the command: a sidecar of ours to plant copies of."""
    d = tmp_path_factory.mktemp("s15")
    (d / "in").mkdir()
    img, _ = synth.demo_input(48, 64, water_type="3C", seed=2)
    uwhl_rs.images.write_image(d / "in" / "a.png", img, bits=8, encoding="linear")
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "in", "-o", "out", "-q"], cwd=d,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return d


def test_a_file_many_sidecars_name_is_hashed_once_a_run(batch, tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    big = tmp_path / "big.tif"
    with open(big, "wb") as f:
        f.truncate(8 << 20)  # sparse: no image, and no sidecar's hash
    doc = json.loads((batch / "out" / "a.json").read_text())
    doc["input"], doc["outputs"] = str(big), {}
    doc.setdefault("metadata", {})["input_sha256"] = "0" * 64
    for k in range(10):
        (out / f"p{k}.json").write_text(json.dumps(doc))
    sizes = []
    real = outdir.sha256_of

    def counted(f):
        sizes.append(os.fstat(f.fileno()).st_size)
        return real(f)
    monkeypatch.setattr(outdir, "sha256_of", counted)
    done = report.write_report(out, workers=4)
    assert done["photos"] == 10
    assert sizes.count(8 << 20) == 1  # the other workers wait for the first one's answer
    assert sum("no file there has the SHA-256" in p for p in done["problems"]) == 10


def test_digests_tell_a_rewritten_file_from_the_one_hashed(tmp_path):
    p = tmp_path / "x.bin"
    p.write_bytes(b"one")
    d = outdir.Digests()
    with open(p, "rb") as f:
        first = d.of_file(f)
    p.write_bytes(b"two, longer")
    with open(p, "rb") as f:
        assert d.of_file(f) != first  # another size: another identity, hashed again
    assert d.of_url("s3://b/x.png") is None
    d.fetched("s3://b/x.png", "ab" * 32)
    assert d.of_url("s3://b/x.png") == "ab" * 32


def test_sidecars_of_a_folder_are_read_one_at_a_time(batch, tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    for k in range(5):
        (out / f"j{k}.json").write_bytes(b"\0" * 1000)
    reads = []
    real = uwhl_rs.storage.Folder.read
    monkeypatch.setattr(uwhl_rs.storage.Folder, "read", lambda self, rel, limit: reads.append(rel) or real(self, rel, limit))
    folder = uwhl_rs.storage.Folder(str(out))
    each = outdir._read_each(folder, [(f"j{k}.json", None) for k in range(5)])
    next(each)
    assert len(reads) == 1  # the next is read when asked for, not before
    photos, problems = outdir.collect_sidecars(str(out))
    assert not photos and len(problems) == 5 and all("not JSON" in p for p in problems), problems


@pytest.mark.parametrize("data,deepest", [
    (b"", 0), (b"]]]", 0), (b'{"a": [1, {"b": "[[[{{"}]}', 3), (b"[[]][[[ ]]]", 3),
    (b'{"k": "\\"[[["}', 1), (b"{" * 17 + b"}" * 17, 17),
])
def test_the_nesting_of_a_sidecar_is_counted_outside_strings(data, deepest):
    assert sidecars.json_depth(data) == deepest


def _png_claiming(path, w, h):
    """A small PNG whose header says w x h (its data is that of 8 x 8): what
    a thumbnail must refuse from its header, before decoding."""
    Image.new("RGB", (8, 8), (10, 20, 30)).save(path)
    b = bytearray(path.read_bytes())
    b[16:24] = w.to_bytes(4, "big") + h.to_bytes(4, "big")
    b[29:33] = zlib.crc32(bytes(b[12:29])).to_bytes(4, "big")
    path.write_bytes(bytes(b))


def test_a_thumbnail_is_refused_by_its_headers_size_and_made_only_of_image_formats(tmp_path):
    _png_claiming(tmp_path / "bomb.png", 12000, 12000)
    with open(tmp_path / "bomb.png", "rb") as f, pytest.raises(ValueError, match="12000x12000 pixels"):
        report._open_small(f, ".png", 160)
    _png_claiming(tmp_path / "ok.png", 8, 8)
    with open(tmp_path / "ok.png", "rb") as f:
        assert report._open_small(f, ".png", 160).size == (8, 8)
    # PostScript named .jpg: Pillow would hand it to Ghostscript; a fake one on PATH says if it ran
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "gs").write_text(f"#!/bin/sh\ntouch {tmp_path / 'ran'}\nexit 1\n")
    (fake / "gs").chmod(0o755)
    (tmp_path / "ps.jpg").write_bytes(b"%!PS-Adobe-3.0 EPSF-3.0\n%%BoundingBox: 0 0 10 10\nshowpage\n")
    old = os.environ["PATH"]
    os.environ["PATH"] = f"{fake}{os.pathsep}{old}"
    try:
        with open(tmp_path / "ps.jpg", "rb") as f, pytest.raises(Exception):
            report._open_small(f, ".jpg", 160)
    finally:
        os.environ["PATH"] = old
    assert not (tmp_path / "ran").exists()


def test_summary_rows_before_a_bad_one_are_kept_and_the_stop_is_said(tmp_path):
    head = "input,status,error\n"
    (tmp_path / "summary.csv").write_bytes((head + "a.png,failed,x\nb.png,done,\n").encode() + b"c.png,failed,\xff\n")
    rows, total, why = outdir.failed_inputs(str(tmp_path))
    assert total == 1 and [r["input"] for r in rows] == ["a.png"]
    assert why and "summary.csv: not read from row" in why and "utf-8" in why.lower(), why
    (tmp_path / "summary.csv").write_text(head + "a.png,failed,x\n")
    assert outdir.failed_inputs(str(tmp_path)) == ([{"input": "a.png", "status": "failed", "error": "x"}], 1, None)
    os.remove(tmp_path / "summary.csv")
    assert outdir.failed_inputs(str(tmp_path)) == ([], 0, None)


def test_the_report_page_says_where_summary_reading_stopped(batch, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(batch / "out", out)
    with open(out / "summary.csv", "ab") as f:
        f.write(b"z.png,failed," + b"q" * (outdir.LINE_MAX + 5) + b"\n")
    done = report.write_report(out)
    assert any("summary.csv: not read from row" in p for p in done["problems"]), done["problems"]
    assert "summary.csv: not read from row" in (out / "report" / "index.html").read_text(encoding="utf-8")


def test_a_truth_mask_of_many_pages_is_read_by_its_first(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    pages = np.zeros((30, 40, 50), np.uint8)
    pages[0, :20] = 1  # the first page scores the top half
    tifffile.imwrite(tmp_path / "m.tif", pages)
    from uwhl_rs import truth

    m = truth.read_truth_mask(str(tmp_path / "m.tif"), 40, 50)
    assert m.shape == (40, 50) and m[:20].all() and not m[20:].any()


def test_a_mat_whose_arrays_inflate_past_its_map_is_not_read(tmp_path):
    sio = pytest.importorskip("scipy.io")
    from uwhl_rs import evaluate

    z = np.full((30, 40), 3.0)
    sio.savemat(tmp_path / "ok.mat", {"z": z}, do_compression=True)
    assert np.allclose(evaluate.read_distance(str(tmp_path / "ok.mat"), 30, 40), 3.0)
    # a second variable (3-D: not a map) of 16 MiB of zeros, a few kilobytes compressed
    sio.savemat(tmp_path / "bomb.mat", {"z": z, "pad": np.zeros((2, 1024, 1024))}, do_compression=True)
    assert (tmp_path / "bomb.mat").stat().st_size < 200_000
    with pytest.raises(ManifestError, match="inflate|hold more than"):
        evaluate.read_distance(str(tmp_path / "bomb.mat"), 30, 40)


def test_a_manifest_that_gives_a_key_twice_is_refused(tmp_path):
    from uwhl_rs import manifest

    (tmp_path / "m.json").write_text('{"images": [{"path": "a.png"}], "images": []}')
    with pytest.raises(ManifestError, match='"images" is given twice'):
        manifest.load_manifest(str(tmp_path / "m.json"))


def test_results_csv_writes_control_characters_as_escapes(tmp_path):
    import csv
    import io

    from uwhl_rs import evaluate

    buf = io.StringIO()
    evaluate._DisplayedRows(csv.writer(buf)).writerow(["a\x1b[2Jb.png", "l\u202ex", "c", "d", 1.5, "x", "y", "\x07z", "w"])
    text = buf.getvalue()
    assert "\x1b" not in text and "\u202e" not in text and "\x07" not in text
    assert "a\\x1b[2Jb.png" in text and "l\\u202ex" in text and "\\x07z" in text


def _poisoned_tiff(path, arr):
    """``arr`` as a TIFF whose ImageWidth is retyped ASCII with a count of
    nearly 4 GiB: the tiff crate printed a dbg! line for it, and the binary,
    which held stderr for its whole run, waited for ever."""
    import struct

    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(path, arr, photometric="rgb" if arr.ndim == 3 else None)
    b = bytearray(path.read_bytes())
    off = struct.unpack("<I", b[4:8])[0]
    for i in range(struct.unpack("<H", b[off:off + 2])[0]):
        p = off + 2 + 12 * i
        if struct.unpack("<H", b[p:p + 2])[0] == 256:
            b[p + 2:p + 8] = struct.pack("<HI", 2, 0xFFFFFF00)
    path.write_bytes(bytes(b))


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_tiff_whose_tag_passes_its_end_is_named_in_both_commands(impl, binary, tmp_path):
    from bothcmds import cmds, run_restore, sidecar

    img, _ = synth.demo_input(48, 64, water_type="3C", seed=3)
    (tmp_path / "depth").mkdir()
    _poisoned_tiff(tmp_path / "p.tif", (img * 255).astype(np.uint8))
    uwhl_rs.images.write_image(tmp_path / "a.png", img, bits=8, encoding="linear")
    _poisoned_tiff(tmp_path / "depth" / "a.tif", np.ones((48, 64), np.float32))
    cmd = cmds(binary)[impl]
    r = run_restore(cmd, tmp_path / "p.tif", tmp_path / "a.png", "-o", tmp_path / "out",
                    "--distance", tmp_path / "depth" / "{stem}.tif")
    assert r.returncode == 3, r.stderr  # the photo failed, named; the other restored
    assert "p.tif: " in r.stderr and "a damaged TIFF: the value of TIFF tag 0x0100" in r.stderr, r.stderr
    assert "ifd.rs" not in r.stderr and "LimitsExceeded" not in r.stderr, r.stderr
    rec = sidecar(tmp_path / "out", "a")["distance"]
    assert not rec["used"] and "is damaged: the value of TIFF tag 0x0100" in rec["rejected"], rec


def _calibrated(tmp_path):
    """A photo of a receding seabed and a folder of its restoration with
    its distance: a dive's water for --water-from."""
    h, w = 90, 120
    sc = synth.scene(h, w, kind="looking_down", seed=5)
    z = np.repeat(np.linspace(8.0, 1.0, h)[:, None], w, 1).astype(np.float32)
    img = synth.render(sc.clean, z, "3C", beta_b=0.3, noise=0.002, seed=1)
    uwhl_rs.images.write_image(tmp_path / "sea.png", img, bits=16, encoding="linear")
    cal = tmp_path / "cal"
    r = uwhl_rs.restore_file(tmp_path / "sea.png", cal, distance=z)
    assert r.sidecar["distance"]["used"], r.sidecar["distance"]
    return z, cal


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_dives_water_with_water_types_is_refused_alike(impl, binary, tmp_path):
    from bothcmds import cmds, run_restore

    _, cal = _calibrated(tmp_path)
    r = run_restore(cmds(binary)[impl], tmp_path / "sea.png", "-o", tmp_path / "o", "--water-from", cal,
                    "--water-type", "I")
    assert r.returncode == 2, r.stderr
    assert "--water-from gives the water type: it does not go with --water-type" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


def test_restore_file_refuses_what_the_commands_refuse(tmp_path):
    """The API as the commands: a dive's water with water types, a window
    without a lens to bend, depth of an array (hostile review)."""
    z, cal = _calibrated(tmp_path)
    with pytest.raises(uwhl_rs.ParameterError, match="water_from gives the water type"):
        uwhl_rs.restore_file(tmp_path / "sea.png", tmp_path / "o1", water_from=cal, water_types=["I"])
    with pytest.raises(uwhl_rs.ParameterError, match="port is the window of altitude"):
        uwhl_rs.restore_file(tmp_path / "sea.png", tmp_path / "o2", port="dome")
    with pytest.raises(uwhl_rs.ParameterError, match="depth_to_range"):
        uwhl_rs.restore_file(tmp_path / "sea.png", tmp_path / "o3", distance=z, distance_kind="depth", fov=80)
    # the default window is no window given: a photo restores as before
    assert uwhl_rs.restore_file(tmp_path / "sea.png", tmp_path / "o4", water_from=cal).sidecar["water_type"]


def _tiny_video(path):
    """Four frames of noise, 32 x 24, FFV1."""
    av = pytest.importorskip("av")
    with av.open(os.fsdecode(path), "w", format="mp4") as out:
        st = out.add_stream("ffv1", rate=24)
        st.width, st.height, st.pix_fmt = 32, 24, "bgr0"
        for k in range(4):
            px = np.random.default_rng(k).integers(20, 200, (24, 32, 3), dtype=np.uint8)
            f = av.VideoFrame.from_ndarray(px, format="rgb24").reformat(format="bgr0")
            f.pts = k
            for p in st.encode(f):
                out.mux(p)
        for p in st.encode():
            out.mux(p)


def test_a_video_named_in_bytes_that_are_not_utf8_is_known_again_by_its_hash(tmp_path):
    """Its sidecar cannot record its name (U+FFFD stands in): it records the
    file's SHA-256, and a rerun skips it (it was restored again as b_2, b_3)."""
    d = tmp_path / "nu"
    d.mkdir()
    name = os.path.join(os.fsencode(d), b"b\xff.mp4")
    _tiny_video(os.fsdecode(name))
    for k in range(2):
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(d), "-o", str(tmp_path / "out"), "-q"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
    assert len(list((tmp_path / "out").glob("*.json"))) == 1


def test_a_video_is_read_from_its_own_file_and_never_from_files_it_names(tmp_path):
    """FFmpeg took a bare ``file:x.mp4`` or ``concat:a|b`` as a protocol (the
    named video restored from other files), and a ``.mp4`` that is an
    ffconcat list opened what it lists (a FIFO: the batch hung)."""
    _tiny_video(tmp_path / "ten.mp4")
    (tmp_path / "file:ten.mp4").write_bytes(b"junk")
    os.mkfifo(tmp_path / "ff")
    (tmp_path / "clip.mp4").write_text("ffconcat version 1.0\nfile ff\nfile ten.mp4\n")
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "file:ten.mp4", "clip.mp4", "ten.mp4", "-o", "out",
                        "-q"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 3, r.stderr
    assert "file:ten.mp4: not a video FFmpeg can read" in r.stderr and "clip.mp4: not a video" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert sorted(p.name for p in (tmp_path / "out").glob("*.json")) == ["ten.json"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_an_output_subfolder_that_is_a_link_is_not_written_through(impl, binary, tmp_path):
    """dive/sub/a.jpg goes to OUT/sub/: a link there (to a folder outside)
    fails a.jpg, named, and nothing is written where it points."""
    from bothcmds import cmds, run_restore

    img, _ = synth.demo_input(48, 64, water_type="3C", seed=4)
    (tmp_path / "dive" / "sub").mkdir(parents=True)
    uwhl_rs.images.write_image(tmp_path / "dive" / "sub" / "a.png", img, bits=8, encoding="linear")
    uwhl_rs.images.write_image(tmp_path / "dive" / "top.png", img, bits=8, encoding="linear")
    (tmp_path / "out").mkdir()
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "out" / "sub")
    r = run_restore(cmds(binary)[impl], tmp_path / "dive", "-o", tmp_path / "out")
    assert r.returncode == 3, r.stderr
    assert "a symbolic link inside the output folder" in r.stderr and "sub" in r.stderr, r.stderr
    assert not any((tmp_path / "elsewhere").iterdir())
    assert (tmp_path / "out" / "top.json").exists()


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_sigint_ignored_at_start_stays_ignored(impl, binary, tmp_path):
    """A script's background job starts with SIGINT ignored: both commands
    keep it so (the binary stopped, exit 130, where Python went on)."""
    import signal
    import time

    from bothcmds import cmds

    n = 8
    for k in range(n):
        img, _ = synth.demo_input(240, 320, water_type="3C", seed=10 + k)
        uwhl_rs.images.write_image(tmp_path / f"p{k}.png", img, bits=8, encoding="linear")
    p = subprocess.Popen([*cmds(binary)[impl], "restore", *(str(tmp_path / f"p{k}.png") for k in range(n)), "-o",
                          str(tmp_path / "out"), "-q"], stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    # once the first input is done (or the run is over), SIGINT: a handler would stop the rest
    while p.poll() is None and not any((tmp_path / "out").glob("*.json")):
        time.sleep(0.01)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 0, err
    assert len(list((tmp_path / "out").glob("p*.json"))) == n


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_reuse_estimates_past_the_largest_count_is_refused_alike(impl, binary, tmp_path):
    from bothcmds import cmds, run_restore

    r = run_restore(cmds(binary)[impl], tmp_path / "x.png", "-o", tmp_path / "o", "--reuse-estimates", str(2**63))
    assert r.returncode == 2 and f'--reuse-estimates: "{2**63}" is over {2**63 - 1}' in r.stderr, r.stderr
