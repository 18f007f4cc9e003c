"""Hostile inputs from the passes of 2026-12-05 (second session): stream
mode fed its own outputs, the raw-frame pipe's options, videos on a full
disk, and what each command names when an option is wrong."""

import json
import subprocess

import numpy as np


def _png(path, h=40, w=56, seed=0):
    from PIL import Image

    rng = np.random.default_rng(seed)
    base = np.array([40, 110, 150], np.float64)
    img = base * (0.5 + rng.random((h, w, 1))) + rng.normal(0, 8, (h, w, 3))
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8)).save(path)


def test_stream_mode_does_not_take_its_own_outputs_as_inputs(binary, tmp_path):
    """A watch on the output folder piped into ``--stream -o out`` fed the
    frames' own outputs back in (``a.png`` restored again as ``a_2``, its
    transmission map as a photo). A file under the output folder is refused
    as a batch refuses it: an error line naming it, the others restored."""
    _png(tmp_path / "a.png")
    out = tmp_path / "out"
    first = subprocess.run([binary, "restore", "--stream", "-o", str(out)], input=f"{tmp_path / 'a.png'}\n",
                           capture_output=True, text=True, timeout=120)
    assert first.returncode == 0 and (out / "a_t.png").is_file(), first.stderr
    before = sorted(p.name for p in out.iterdir())
    # the outputs by a relative name, by an absolute one, and through a link into the folder
    (tmp_path / "link").symlink_to(out)
    shown = next(p.name for p in out.iterdir() if p.stem == "a")
    lines = f"{out / 'a_t.png'}\n{tmp_path / 'link' / shown}\n{tmp_path / 'a.png'}\n"
    r = subprocess.run([binary, "restore", "--stream", "--overwrite", "-o", str(out)], input=lines,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    got = [json.loads(x) for x in r.stdout.splitlines()]
    assert len(got) == 3, got
    for g in got[:2]:
        assert g.get("error") == "unreadable_input" and "inside the output folder" in g["message"], g
    assert "water_type" in got[2], got[2]
    assert sorted(p.name for p in out.iterdir()) == before


def test_a_distance_map_counts_in_the_memory_budget(binary, tmp_path):
    """The map was checked against the whole of --max-memory and the photo's
    plan left it out: with a small photo and a large float64 map, both
    commands went 4-39 MiB over the limit. Now the map gets what the budget
    leaves beside the photo (the refusal names both), and one that does not
    fit is left out with the photo restored: at the tightest budget that
    reads the map (plus the margin of docs/CLI.md), the peak resident
    memory measured by the kernel stays under it."""
    import re

    from test_parity import _cmd, _peak_rss

    _png(tmp_path / "p.png", 48, 64)
    ramp = np.tile(np.linspace(1.0, 5.0, 1600)[None, :], (1200, 1))  # float64: 12 bytes a pixel to read
    np.save(tmp_path / "p.npy", ramp)
    margin = {"rust": 1 << 20, "python": 4 << 20}
    for face in ("rust", "python"):
        out = tmp_path / face
        args = [str(tmp_path / "p.png"), "-o", str(out), "--format", "png", "--overwrite"]
        code, _, err = _peak_rss(_cmd(face, binary, [*args, "--max-memory", "1M"]))
        photo = int(re.search(r"need about (\d+) bytes", err).group(1)) + margin[face]
        # enough for the photo, not for the map: the map is refused by name, the photo restored without it
        code, _, err = _peak_rss(_cmd(face, binary, [*args, "--distance", str(tmp_path / "p.npy"), "--max-memory", str(photo)]))
        assert code == 0, (face, err)
        why = json.loads((out / "p.json").read_text())["distance"]["rejected"]
        got = re.search(r"needs about (\d+) bytes, more than the (\d+) bytes --max-memory leaves it beside the photo", why)
        assert got, (face, why)
        # what the photo keeps for itself is the budget less what it left the map
        need, room = int(got.group(1)), int(got.group(2))
        budget = need + (photo - room) + margin[face]
        code, peak, err = _peak_rss(_cmd(face, binary, [*args, "--distance", str(tmp_path / "p.npy"), "--max-memory", str(budget)]))
        assert code == 0, (face, err)
        side = json.loads((out / "p.json").read_text())
        assert "max-memory" not in (side["distance"]["rejected"] or ""), (face, side["distance"])
        assert peak <= budget, (face, peak, budget)


def test_a_map_that_does_not_fit_is_left_out_at_any_budget_and_shrinks_with_max_side(binary, tmp_path):
    """A larger budget used to fail what a smaller one restored (the map's
    own check dropped it, the photo's plan with the map failed the photo
    with exit 4 naming only its pixels); with --max-side the Python command
    compared the map with the shrunk photo and failed the input with exit 2.
    Now every budget that fits the photo restores it, with the map or
    without it (named in ``distance.rejected``), in both commands."""
    from PIL import Image

    from test_parity import _cmd

    rng = np.random.default_rng(4)
    Image.fromarray((rng.random((300, 400, 3)) * 200).astype(np.uint8)).save(tmp_path / "p.jpg")
    np.save(tmp_path / "p.npy", np.full((1200, 1600), 3.0, np.float32))
    for face in ("rust", "python"):
        out = tmp_path / face
        args = [str(tmp_path / "p.jpg"), "-o", str(out), "--overwrite", "-q", "--distance", str(tmp_path / "p.npy")]
        r = subprocess.run(_cmd(face, binary, [*args, "--max-memory", "1M"]), capture_output=True, text=True, timeout=120)
        import re

        photo = int(re.search(r"need about (\d+) bytes", r.stderr).group(1))
        # from the margin that absorbs run-to-run changes of the process's own size (docs/CLI.md)
        margin = (1 << 20) if face == "rust" else (4 << 20)
        for extra in (margin, margin + (8 << 20), margin + (16 << 20), margin + (32 << 20), margin + (64 << 20)):
            r = subprocess.run(_cmd(face, binary, [*args, "--max-memory", str(photo + extra)]), capture_output=True,
                               text=True, timeout=120)
            assert r.returncode == 0, (face, extra, r.stderr)
        r = subprocess.run(_cmd(face, binary, [*args, "--max-side", "100"]), capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, (face, r.stderr)


def test_the_progress_line_says_when_a_distance_asked_for_is_not_used(binary, tmp_path):
    """A mistyped --distance template left every photo of a batch restored
    without a distance, with progress lines like a normal run's: the reason
    was only in the sidecar. Both commands now say it on the line; and a
    water given with a distance gets a note once (it is for the photos whose
    distance is not used)."""
    from test_parity import _cmd

    _png(tmp_path / "p.png", 48, 64)
    np.save(tmp_path / "p.npy", np.tile(np.linspace(1.0, 5.0, 64)[None, :], (48, 1)).astype(np.float32))
    for face in ("rust", "python"):
        out = tmp_path / face
        base = [str(tmp_path / "p.png"), "-o", str(out), "--overwrite"]
        r = subprocess.run(_cmd(face, binary, [*base, "--distance", str(tmp_path / "nope" / "{stem}.npy")]),
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, (face, r.stderr)
        line = [x for x in r.stdout.splitlines() if x.startswith("[1/1]")][0]
        assert ", no distance (see distance.rejected)" in line, (face, line)
        # a map that is read but not used (a ramp across a random photo: the fit refuses it)
        r = subprocess.run(_cmd(face, binary, [*base, "--distance", str(tmp_path / "{stem}.npy"), "--water-type", "3C"]),
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, (face, r.stderr)
        side = json.loads((out / "p.json").read_text())
        line = [x for x in r.stdout.splitlines() if x.startswith("[1/1]")][0]
        assert ("distance_rejected" in side["flags"]) == (", distance not used" in line), (face, line, side["flags"])
        notes = [x for x in r.stderr.splitlines() if "note:" in x]
        assert len(notes) == 1 and "--water-type is used for the photos whose --distance gives no usable distance" in notes[0], (face, r.stderr)
        # without a distance, no such words
        r = subprocess.run(_cmd(face, binary, base), capture_output=True, text=True, timeout=120)
        assert "distance" not in r.stdout + r.stderr, (face, r.stdout, r.stderr)


def test_distance_maps_and_logs_say_what_is_wrong_with_them(tmp_path):
    """Messages that named the wrong problem (a hostile pass): a BigTIFF
    was "not a distance map", a 16-bit RGB PNG was told that "8 bits cannot
    hold a distance", a signed 16-bit TIFF was told that 16-bit millimetres
    are read, a two-channel TIFF got the decoder's debug text, a float64 of
    1e39 m became unknown instead of out of range, and a .npy whose header
    says 'shape' twice was read with the first (NumPy takes the last)."""
    import struct

    import tifffile
    from PIL import Image

    import uwhl_rs

    z = np.linspace(1.0, 5.0, 48 * 64, dtype=np.float32).reshape(48, 64)
    tifffile.imwrite(tmp_path / "big.tif", z, bigtiff=True)
    assert np.array_equal(uwhl_rs.read_distance(tmp_path / "big.tif"), z)
    tifffile.imwrite(tmp_path / "two.tif", np.stack([z, z], -1), planarconfig="contig")
    tifffile.imwrite(tmp_path / "i16.tif", (z * 1000).astype(np.int16))
    Image.fromarray(np.zeros((48, 64, 3), np.uint16).astype(np.uint8)).save(tmp_path / "rgb.png")
    head = b"{'descr': '<f4', 'shape': (1, 1), 'fortran_order': False, 'shape': (48, 64), }"
    head += b" " * ((64 - (10 + len(head) + 1) % 64) % 64) + b"\n"
    (tmp_path / "dup.npy").write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head + z.tobytes())
    for name, want in [("two.tif", "has 2 channels: a distance map has one"),
                       ("i16.tif", "of signed 16-bit samples"),
                       ("rgb.png", "is RGB: a distance map is one channel"),
                       ("dup.npy", "with 'shape' twice in its header")]:
        try:
            uwhl_rs.read_distance(tmp_path / name)
        except uwhl_rs.ImageError as e:
            assert want in str(e) and "Multiband" not in str(e), (name, str(e))
        else:
            raise AssertionError(f"{name} was read")


def test_a_photo_whose_time_or_altitude_is_there_but_unreadable_is_told_so(binary, tmp_path):
    """With a navigation log matched by time, a photo whose EXIF time is not
    a calendar time (30 February) was told it "has no time", and an XMP
    altitude that is no number that the XMP "has no" altitude: both now
    show the value, in both commands."""
    from PIL import Image

    from test_parity import _cmd

    ex = Image.Exif()
    ex[34665] = {36867: "2026:02:30 10:15:42"}  # DateTimeOriginal: no such day
    rng = np.random.default_rng(1)
    Image.fromarray((rng.random((48, 64, 3)) * 200).astype(np.uint8)).save(tmp_path / "p.jpg", exif=ex)
    (tmp_path / "nav.csv").write_text("time,altitude\n2026-03-01T10:15:40,2.0\n")
    for face in ("rust", "python"):
        out = tmp_path / face
        r = subprocess.run(_cmd(face, binary, [str(tmp_path / "p.jpg"), "-o", str(out), "--altitude", str(tmp_path / "nav.csv"),
                                               "--fov", "70"]), capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, (face, r.stderr)
        why = json.loads((out / "p.json").read_text())["distance"]["rejected"]
        assert 'the photo\'s EXIF time "2026:02:30 10:15:42" is not a date and time' in why, (face, why)


def test_raw_frames_refuse_the_photo_options_they_would_ignore(binary):
    """``--linear`` and ``--preprocess reference`` were accepted with
    ``--raw-frames`` and changed nothing (the samples' curve is
    ``--transfer``): now a usage error naming the option to use."""
    frame = bytes(16 * 12 * 3)
    for extra, word in ((["--linear"], "--linear is for photos"), (["--preprocess", "reference"], "--preprocess is for photos")):
        r = subprocess.run([binary, "restore", "--raw-frames", "16x12", "-o", "-", *extra], input=frame,
                           capture_output=True, timeout=60)
        assert r.returncode == 2 and word in r.stderr.decode() and r.stdout == b"", (extra, r.stderr)


def test_an_unknown_short_option_is_named_whole_with_how_to_give_such_a_file(binary, tmp_path):
    """``uwhl-rs restore -dash.mp4`` said "invalid option '-d'"; both
    commands now name the whole word and say how to give a file whose name
    starts with '-'. A usage error found past the parser (options that do
    not go together) ends with where to look, in both commands."""
    from test_parity import _cmd

    for face in ("rust", "python"):
        r = subprocess.run(_cmd(face, binary, ["-dash.mp4", "-o", str(tmp_path / "o")]), capture_output=True, text=True,
                           timeout=60)
        assert r.returncode == 2 and "'-dash.mp4'" in r.stderr and "./-dash.mp4" in r.stderr, (face, r.stderr)
        r = subprocess.run(_cmd(face, binary, ["x.png", "-o", str(tmp_path / "o"), "--fov", "70"]), capture_output=True,
                           text=True, timeout=60)
        lines = r.stderr.splitlines()
        assert r.returncode == 2 and len(lines) == 2 and lines[1].startswith("Try '") and "--help'." in lines[1], (face, lines)


def test_a_port_that_nothing_uses_is_refused(binary, tmp_path):
    """``--port dome`` with a distance map of ranges (or none) changed
    nothing and was accepted; like ``--fov`` it is the lens side of
    ``--altitude`` or of ``--distance-kind depth``, and refused without them,
    in both commands. With ``--altitude`` it is taken."""
    from test_parity import _cmd

    _png(tmp_path / "p.png", 48, 64)
    np.save(tmp_path / "p.npy", np.full((48, 64), 3.0, np.float32))
    for face in ("rust", "python"):
        r = subprocess.run(_cmd(face, binary, [str(tmp_path / "p.png"), "-o", str(tmp_path / face), "--port", "dome",
                                               "--distance", str(tmp_path / "p.npy")]), capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and "--port is the window of --altitude" in r.stderr, (face, r.stderr)
        r = subprocess.run(_cmd(face, binary, [str(tmp_path / "p.png"), "-o", str(tmp_path / face), "--port", "dome",
                                               "--altitude", "2", "--fov", "60"]), capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, (face, r.stderr)
        assert json.loads((tmp_path / face / "p.json").read_text())["distance"]["floor"]["port"] == "dome"


def test_same_named_inputs_of_a_listing_each_keep_their_own_copy(moto_s3, tmp_path):
    """Inputs of one name in different folders of an object-storage listing
    were fetched to one scratch name: the next input's copy overwrote (or
    its cleanup removed) the copy the previous input's hash and metadata
    were still being read from. Sidecars recorded another input's hash and
    inputs failed as missing. Each input's copy is now its own: every
    sidecar's ``input_sha256`` is the sha256 of its own object."""
    import hashlib
    import sys

    fs, endpoint = moto_s3
    fs.mkdir("same9")
    for k in range(12):
        _png(tmp_path / "p.png", 40, 56, seed=k)
        fs.put(str(tmp_path / "p.png"), f"same9/in/d{k:02d}/f.png")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "s3://same9/in/", "-o", str(out), "-q",
                        "--storage-option", f"endpoint_url={endpoint}"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    for k in range(12):
        side = json.loads((out / f"d{k:02d}" / "f.json").read_text())
        want = hashlib.sha256(fs.cat(f"same9/in/d{k:02d}/f.png")).hexdigest()
        assert side["metadata"]["input_sha256"] == want, k


def test_an_s3_store_that_never_answers_is_given_up_on_within_its_deadlines(moto_s3):
    """botocore's defaults (60 s a read, retried) under s3fs's 5 attempts
    held a batch 7 minutes on an endpoint that accepts connections and never
    answers. The client of an S3 URL is built with 10 s to connect, 20 s a
    read and 2 attempts, s3fs makes 2, unless the options give their own
    timeouts; other stores are left as they are."""
    from uwhl_rs import storage

    fs, endpoint = moto_s3
    got, _ = storage.filesystem("s3://anything/x.png", {"endpoint_url": endpoint})
    config = got.s3.meta.config
    assert (config.connect_timeout, config.read_timeout, config.retries["total_max_attempts"]) == (10, 20, 2)
    assert got.retries == storage.S3FS_ATTEMPTS == 2
    # the user's own win, key by key
    own = storage.with_deadlines("s3://b/x", {"config_kwargs": {"read_timeout": 300, "retries": {"mode": "adaptive"}}})
    assert own["config_kwargs"] == {"read_timeout": 300, "retries": {"mode": "adaptive"}, "connect_timeout": 10}
    assert storage.with_deadlines("gs://b/x", {"token": "anon"}) == {"token": "anon"}
    assert storage.with_deadlines("file:///tmp/x", None) == {}


def test_usage_errors_are_json_objects_with_json_errors_in_both_commands(binary, tmp_path):
    """``uwhl``'s parser wrote its usage errors as text (and a "Try" line)
    even with ``--json-errors``; uwhl-rs wrote the JSON object. Now both
    write one object of kind bad_arguments, exit 2, and nothing else."""
    from test_parity import _cmd

    for face in ("rust", "python"):
        for extra in (["-z"], ["--format", "xxx"], ["--quality", "0"]):
            r = subprocess.run(_cmd(face, binary, ["a.jpg", "-o", str(tmp_path / "o"), "--json-errors", *extra]),
                               capture_output=True, text=True, timeout=60)
            lines = r.stderr.splitlines()
            assert r.returncode == 2 and len(lines) == 1, (face, extra, r.stderr)
            obj = json.loads(lines[0])
            assert obj["error"] == "bad_arguments" and obj["exit_code"] == 2 and obj["input"] is None, (face, obj)
    # after "--" it is an input's name, not the option
    r = subprocess.run(_cmd("python", binary, ["-o", str(tmp_path / "o"), "-z", "--", "--json-errors"]),
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.startswith("uwhl restore: error:"), r.stderr


def test_dash_dash_is_not_an_output_folder_in_either_command(binary, tmp_path):
    """``-o --`` was a usage error for uwhl and a folder named ``--`` for
    uwhl-rs; both refuse it now, and ``./--`` names such a folder."""
    from test_parity import _cmd

    _png(tmp_path / "a.png")
    for face in ("rust", "python"):
        r = subprocess.run(_cmd(face, binary, ["-o", "--", str(tmp_path / "a.png")]), capture_output=True, text=True,
                           timeout=60, cwd=tmp_path)
        assert r.returncode == 2 and not (tmp_path / "--").exists(), (face, r.stderr)
    r = subprocess.run(_cmd("rust", binary, ["-o", "./--", str(tmp_path / "a.png"), "-q"]), capture_output=True, text=True,
                       timeout=60, cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "--" / "a.json").is_file(), r.stderr


def test_restore_file_takes_an_altitude_in_metres(tmp_path):
    """``restore_file(altitude=2.0)`` raised a TypeError from os.fspath: a
    number is metres, as ``--altitude 2`` is; what is neither a number nor
    a path is a ParameterError naming it."""
    import pytest

    from uwhl_rs import ParameterError, files

    _png(tmp_path / "a.png", 48, 64)
    r = files.restore_file(tmp_path / "a.png", tmp_path / "o", altitude=2.5, fov=60)
    assert r.sidecar["distance"]["floor"]["altitude"] == 2.5
    for bad in (True, [1]):
        with pytest.raises(ParameterError, match="altitude must be metres"):
            files.restore_file(tmp_path / "a.png", tmp_path / "o2", altitude=bad, fov=60)
