"""Hostile inputs found by the reviews of 2026-12-05 (third session):
each case says what must happen independently of the code."""

from __future__ import annotations

import os

import numpy as np
import pytest

from uwhl_rs import video, videofiles
from uwhl_rs.errors import ImageTooLargeError


def _video(path, h, w, n=2):
    av = pytest.importorskip("av")
    rng = np.random.default_rng(0)
    with av.open(str(path), "w") as out:
        st = out.add_stream("ffv1", rate=24)
        st.width, st.height, st.pix_fmt = w, h, "bgr0"
        for _ in range(n):
            f = av.VideoFrame.from_ndarray(rng.integers(0, 255, (h, w, 3), dtype=np.uint8), format="rgb24")
            for p in st.encode(f):
                out.mux(p)
        for p in st.encode():
            out.mux(p)


def test_a_video_over_the_memory_budget_is_refused_before_a_frame_is_decoded(tmp_path, monkeypatch):
    # The frame size comes from the stream's header; decoding a frame of a
    # 16000 x 16000 stream to read its rotation would take a gigabyte before
    # --max-memory was asked. Any decode before the refusal fails this test.
    src = tmp_path / "big.mkv"
    _video(src, 96, 128)
    decoded = []
    monkeypatch.setattr(video, "display_rotation", lambda p: decoded.append(p) or 0)
    need = videofiles.frame_need(video.probe(src, rotation=False), None)
    with pytest.raises(ImageTooLargeError, match="over max_memory"):
        videofiles.restore_video(src, tmp_path / "out", max_memory=need - 1)
    assert decoded == []
    # within the budget the rotation is read, once
    videofiles.restore_video(src, tmp_path / "out2", max_memory=need * 4)
    assert decoded == [str(src)]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_usage_error_is_named_before_a_bad_water_folder_in_both_commands(impl, binary, tmp_path):
    # --water-from naming a folder with no fits, given with --water-type:
    # the combination is a usage error whatever the folder holds, and both
    # commands name it (the binary read the folder first and named that)
    from bothcmds import cmds, run_restore
    from PIL import Image

    Image.new("RGB", (32, 24), (20, 80, 120)).save(tmp_path / "a.png")
    empty = tmp_path / "nofits"
    empty.mkdir()
    r = run_restore(cmds(binary)[impl], tmp_path / "a.png", "-o", tmp_path / "o", "--water-from", empty,
                    "--water-type", "I")
    assert r.returncode == 2, r.stderr
    assert "--water-from gives the water type: it does not go with --water-type" in r.stderr, r.stderr
    # alone, the folder's own problem is named
    r = run_restore(cmds(binary)[impl], tmp_path / "a.png", "-o", tmp_path / "o", "--water-from", empty)
    assert r.returncode == 2 and "nofits" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ planted sidecars (report, iFDO)


@pytest.fixture
def restored(binary, tmp_path):
    """A folder holding blue.jpg and blue.json as the binary writes them."""
    from PIL import Image
    from test_ifdo import restore

    rng = np.random.default_rng(3)
    img = np.clip(rng.normal([40, 110, 150], 25, (48, 64, 3)), 0, 255).astype(np.uint8)
    Image.fromarray(img).save(tmp_path / "blue.png")
    out = tmp_path / "out"
    assert restore("rust", binary, [tmp_path / "blue.png"], out).returncode == 0
    return out


def _ifdo(out, tmp_path):
    import yaml
    from test_ifdo import HEADER, POSITION, header_file, uwhl

    head = {**HEADER, **POSITION, "image-datetime": "2026-01-02 03:04:05.000000"}
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, head))
    doc = yaml.safe_load((out / "ifdo.yaml").read_text()) if (out / "ifdo.yaml").is_file() else None
    return r, doc


def test_a_sidecar_claiming_another_photo_cannot_change_its_uuid(restored, tmp_path):
    # a.json sorts before blue.json and names blue.jpg with its true SHA-256
    # but another image UUID and history: the photo keeps the UUID embedded
    # in it (its sidecar's), and the planted one is named
    import json

    genuine = json.loads((restored / "blue.json").read_text())
    fake = dict(genuine, input="elsewhere/other.jpg")
    fake["metadata"] = dict(genuine["metadata"], image_uuid="deadbeefdead4eefaeadbeefdeadbeef")
    (restored / "a.json").write_text(json.dumps(fake))
    r, doc = _ifdo(restored, tmp_path)
    assert r.returncode == 0, r.stderr
    want = genuine["metadata"]["image_uuid"]
    assert doc["image-set-items"]["blue.jpg"]["image-uuid"].replace("-", "") == want
    assert "a.json: not a usable sidecar: outputs.image is 'blue.jpg', not an output of its own name 'a'" in r.stdout


def test_a_lone_surrogate_in_a_sidecar_is_read_as_u_fffd_not_a_crash(restored, tmp_path):
    # "\ud800" is valid JSON and no character: os.lstat of it raised
    # UnicodeEncodeError, and ifdo and restore --ifdo ended with exit 6.
    # It is read as U+FFFD, as the core reads a sidecar.
    import json

    from test_ifdo import uwhl

    text = (restored / "blue.json").read_text()
    # a planted sidecar whose output names one: not its own name, named
    (restored / "z.json").write_text(text.replace('"blue.jpg"', '"x\\ud800.jpg"'))
    # the photo's own sidecar with one in its input's name
    doc = json.loads(text)
    doc["input"] = "in/x\udce9\ud800.png"  # a low half, then a high one with no low after it
    (restored / "blue.json").write_text(json.dumps(doc))
    assert "\\udce9\\ud800" in (restored / "blue.json").read_text()
    r, got = _ifdo(restored, tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "z.json: not a usable sidecar: outputs.image is 'x\ufffd.jpg', not an output of its own name 'z'" \
        in r.stdout, r.stdout
    assert list(got["image-set-items"]) == ["blue.jpg"]
    used = got["image-set-header"]["image-set-provenance"]["provenance-activities"][0]["used-entities"][0]
    assert used["name"] == "x\ufffd\ufffd.png"
    r = uwhl("report", restored)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    # a pair of surrogate escapes is one character (a fish), kept
    doc["input"] = "fish\U0001f41f.png"
    (restored / "z.json").unlink()
    (restored / "blue.json").write_text(json.dumps(doc))  # ensure_ascii: "\ud83d\udc1f"
    assert "\\ud83d\\udc1f" in (restored / "blue.json").read_text()
    r, got = _ifdo(restored, tmp_path)
    used = got["image-set-header"]["image-set-provenance"]["provenance-activities"][0]["used-entities"][0]
    assert r.returncode == 0 and used["name"] == "fish\U0001f41f.png", r.stdout + r.stderr


def test_a_sidecars_parameters_are_bounded_before_they_are_copied(restored, tmp_path):
    # Tiny lists by the hundred thousand (650,000 of them in a sidecar under
    # its 4 MiB cap), copied into every activity of the iFDO, made a YAML
    # file of 20 MB and took 750 MB. Real parameters are about 1 kB.
    import json

    doc = json.loads((restored / "blue.json").read_text())
    assert len(json.dumps(doc["parameters"])) < 4096
    doc["parameters"] = {"x": [[0, 0]] * 400_000}
    (restored / "blue.json").write_text(json.dumps(doc, separators=(",", ":")))
    r, _ = _ifdo(restored, tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    # as json.dumps spaces it: '{"x": [' + 400,000 x "[0, 0]" + 399,999 x ", " + "]}"
    assert "blue.json: not a usable sidecar: parameters is 3200007 bytes as JSON, over 32768" in r.stderr, r.stderr


# ------------------------------------------------------------------ iFDO header files


def _header_text(tmp_path, text, name):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_a_yaml_merge_key_is_no_key_given_twice(tmp_path):
    # "<<:" merges a mapping in; the keys of the mapping itself win over the merged ones
    from uwhl_rs import ifdo
    from uwhl_rs.errors import IfdoError

    text = "x:\n  <<: {a: 1, b: 2}\n  b: 3\n"
    assert ifdo.load_yaml(text, "h") == {"x": {"a": 1, "b": 3}}
    with pytest.raises(IfdoError, match="the key 'b' is given twice"):
        ifdo.load_yaml("x:\n  <<: {a: 1}\n  b: 3\n  b: 4\n", "h")


def test_a_json_header_as_json_dump_writes_it_is_read(tmp_path):
    # json.dump escapes a character outside the BMP as two surrogate escapes: valid JSON that
    # libyaml refuses ("while parsing a quoted scalar")
    import json

    import yaml
    from test_ifdo import HEADER

    from uwhl_rs import ifdo

    head = dict(HEADER, **{"image-abstract": "Coral \U0001f41f survey"})
    p = _header_text(tmp_path, json.dumps(head), "h.json")
    assert "\\ud83d\\udc1f" in p.read_text()
    with pytest.raises(yaml.YAMLError):
        yaml.load(p.read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    assert ifdo.load_header(str(p))["image-abstract"] == "Coral \U0001f41f survey"


@pytest.mark.parametrize("text, said", [
    ('{"image-abstract": "a", "image-abstract": "b"}', "the key 'image-abstract' is given twice in one object"),
    ('{"x": NaN}', "x must be a finite number, not nan"),
    ('{"x": "\\ud800"}', "lone UTF-16 surrogate"),
    ('{"x": ' + "[" * 40 + "]" * 40 + "}", "nested deeper than 32 levels"),
    ("image-abstract: a\nimage-copyright: c\nimage-abstract: b\n",
     "the key 'image-abstract' is given twice in one mapping (line 3)"),
    ('image-abstract: "unterminated\nimage-copyright: c\n', "not YAML or JSON (found unexpected end of stream at line 3, "
                                                           "column 1)"),
])
def test_a_header_file_says_what_is_wrong_and_where(tmp_path, text, said):
    from uwhl_rs import ifdo
    from uwhl_rs.errors import IfdoError

    with pytest.raises(IfdoError) as e:
        ifdo.load_header(str(_header_text(tmp_path, text, "h.yaml")))
    assert said in str(e.value), str(e.value)


# ------------------------------------------------------------------ raw files


def _raw_ifd(t):
    """The IFD of a DNG that holds the most pixels: IFD0 or one of its SubIFDs."""
    pages = []
    for p in t.pages:
        pages.append(p)
        pages.extend(getattr(p, "pages", None) or [])
    return max(pages, key=lambda p: p.imagewidth * p.imagelength)


@pytest.mark.parametrize("name", ["Blackmagic.dng", "canon_eos_6d.dng"])
def test_a_dng_whose_size_outgrows_its_tile_table_is_refused_before_libraw(tmp_path, name):
    # LibRaw decoded the tiles past the table from whatever bytes followed (3.4 GB, garbage, exit 0)
    import struct

    from uwhl_rs import images
    from uwhl_rs.errors import ImageReadError

    tifffile = pytest.importorskip("tifffile")
    src = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "raw", name)
    if not os.path.isfile(src):
        pytest.skip("../shared/data is not here")
    b = bytearray(open(src, "rb").read())
    with tifffile.TiffFile(src) as t:
        p = _raw_ifd(t)
        bo = t.byteorder
        w, h = p.imagewidth, p.imagelength
        tiled = p.is_tiled
        step_w, step_h = (p.tilewidth, p.tilelength) if tiled else (w, p.rowsperstrip or h)
        listed = len(p.dataoffsets)
        for tag_name, v in (("ImageWidth", w * 2), ("ImageLength", h * 2)):
            tag = p.tags[tag_name]
            if struct.unpack_from(bo + "H", b, tag.offset + 2)[0] == 3:
                struct.pack_into(bo + "H", b, tag.offset + 2, 4)  # SHORT to LONG, the value field is 4 bytes
            struct.pack_into(bo + "I", b, tag.offset + 8, v)
    # by hand: the patched size needs this many strips or tiles, the table lists what it did
    needed = -(-2 * w // step_w) * -(-2 * h // step_h) if tiled else -(-2 * h // min(step_h, 2 * h))
    assert needed > listed
    bad = tmp_path / name
    bad.write_bytes(bytes(b))
    with pytest.raises(ImageReadError) as e:
        images.read_image(str(bad))
    what = "tiles" if tiled else "strips"
    assert f"a damaged raw file: the raw image of {2 * w} x {2 * h} pixels needs {needed} {what}, and its table " \
           f"lists {listed}" in str(e.value)
    # the file as it is reads
    img, _ = images.read_image(src, half_size=True)
    assert img.ndim == 3


def test_an_ifdo_file_that_cannot_be_replaced_is_named(restored, tmp_path):
    (restored / "ifdo.yaml").mkdir()
    r, _ = _ifdo(restored, tmp_path)
    assert r.returncode == 5 and "Traceback" not in r.stderr, r.stderr
    assert "cannot write the iFDO" in r.stderr and "ifdo.yaml" in r.stderr, r.stderr


# ------------------------------------------------------------------ signals in stream mode and raw frames


@pytest.mark.parametrize("mode", [["--stream"], ["--raw-frames", "64x48"]])
def test_a_signal_ends_a_stream_at_once_and_takes_its_temporaries(binary, tmp_path, mode):
    # The run waits on stdin (an idle producer): SIGTERM must end it at once,
    # by the signal (as the default action did), after removing what this
    # process left in the output folder; another process's files stay.
    import signal
    import subprocess
    import time

    out = tmp_path / "out"
    p = subprocess.Popen([binary, "restore", *mode, "-o", str(out)], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not out.is_dir() and time.monotonic() < deadline:
            time.sleep(0.02)
        # a temporary of this process (its pid), and one of another
        mine, theirs = out / f".uwhl-{p.pid}-7.tmp.png", out / ".uwhl-1-7.tmp.png"
        mine.write_bytes(b"half")
        theirs.write_bytes(b"another run's")
        time.sleep(0.2)
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == -signal.SIGTERM, (p.returncode, p.stderr.read())
    assert not mine.exists() and theirs.exists()
