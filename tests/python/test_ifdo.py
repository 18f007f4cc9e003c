"""The iFDO of a batch (uwhl_rs.ifdo, docs/OUTPUTS.md "iFDO"), checked
against the standard's own JSON schemas (ifdo-v2.0.1.json and the
provenance-v0.1.0.json it refers to, as the mariqt package ships them) with
jsonschema, and against the files themselves: each item's hash is the
SHA-256 of the photo as written (hashlib), its UUID the EXIF ImageUniqueID
embedded in it (read with Pillow), its time and position those of the
input's EXIF."""

import copy
import datetime as dt
import hashlib
import importlib.util
import json
import os
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image
from PIL.TiffImagePlugin import IFDRational as R

from test_metadata import EXIF_IFD, GPS_IFD, _gps_exif, _scene

HEADER = {
    "image-context": {"name": "Test survey programme"},
    "image-project": {"name": "Reef colour", "uri": "https://example.org/projects/reef-colour"},
    "image-event": {"name": "DIVE_042"},
    "image-platform": {"name": "Diver"},
    "image-sensor": {"name": "SeaCam Housing 7"},
    "image-pi": {"name": "A. Researcher", "uri": "https://orcid.org/0000-0002-1825-0097"},
    "image-creators": [{"name": "A. Researcher"}, {"name": "B. Diver"}],
    "image-license": {"name": "CC-BY-4.0", "uri": "https://creativecommons.org/licenses/by/4.0/"},
    "image-copyright": "(c) 2026 Survey",
    "image-abstract": "Colour-corrected stills of a reef transect, restored with haze-lines.",
    "image-coordinate-uncertainty-meters": 5.0,
}
#: the defaults of photos without their own position
POSITION = {"image-latitude": -33.86, "image-longitude": 151.2, "image-altitude-meters": -10.0}


def _schema_dir() -> Path:
    spec = importlib.util.find_spec("mariqt")  # found, not imported: only its package data is used
    assert spec is not None, "the test extra installs mariqt, which ships the iFDO schemas"
    return Path(list(spec.submodule_search_locations)[0]) / "resources" / "fair-marine-images" / "docs" / "schemas"


def validator():
    """A jsonschema validator of iFDO 2.0.1, with its provenance schema
    resolved locally and formats (uri, date-time) checked."""
    from jsonschema import Draft202012Validator
    from referencing import Registry, Resource

    d = _schema_dir()
    ifdo_schema = json.loads((d / "ifdo-v2.0.1.json").read_text())
    prov = json.loads((d / "provenance-v0.1.0.json").read_text())
    registry = Registry().with_resources([(prov["$id"], Resource.from_contents(prov)),
                                          (ifdo_schema["$id"], Resource.from_contents(ifdo_schema))])
    return Draft202012Validator(ifdo_schema, registry=registry, format_checker=Draft202012Validator.FORMAT_CHECKER)


def uwhl(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def restore(face, binary, inputs, out, *extra):
    cmd = [sys.executable, "-m", "uwhl_rs", "restore"] if face == "python" else [binary, "restore"]
    return subprocess.run(cmd + [str(i) for i in inputs] + ["-o", str(out), "-q", *map(str, extra)],
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    """Three photos: GPS and a time without UTC offset; GPS elsewhere and a
    time with one (+10:00); no EXIF at all."""
    d = tmp_path_factory.mktemp("dive")
    Image.fromarray(_scene(seed=1)).save(d / "a_0001.jpg", quality=92, exif=_gps_exif())
    ex = _gps_exif()
    e = ex.get_ifd(EXIF_IFD)
    e[0x9003] = "2026:11:30 08:00:00"
    e[0x9291] = "5"
    e[0x9011] = "+10:00"  # OffsetTimeOriginal
    g = ex.get_ifd(GPS_IFD)
    g[2] = (R(33, 1), R(52, 1), R(0, 1))
    g[6] = R(21, 1)
    Image.fromarray(_scene(seed=2)).save(d / "b_0002.jpg", quality=92, exif=ex)
    Image.fromarray(_scene(seed=3)).save(d / "c_0003.png")
    return d


def header_file(tmp_path, fields, name="header.yaml"):
    p = tmp_path / name
    p.write_text(json.dumps(fields) if name.endswith(".json") else yaml.safe_dump(fields))
    return p


@pytest.mark.parametrize("face", ["python", "rust"])
def test_a_batch_gives_a_valid_ifdo(face, binary, dive, tmp_path):
    out = tmp_path / "DIVE_042_restored"
    head = header_file(tmp_path, {**HEADER, **POSITION})
    # the activities' times lie within the run (whole seconds either side: the times are rounded)
    began = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    if face == "python":
        r = restore(face, binary, [dive], out, "--ifdo", head)
        assert r.returncode == 0, r.stderr
    else:
        r = restore(face, binary, [dive], out)
        assert r.returncode == 0, r.stderr
        r = uwhl("ifdo", out, "--header", head)
        assert r.returncode == 0, r.stderr
        assert "3 photos" in r.stdout and "taken as UTC" in r.stdout
    ended = dt.datetime.now(dt.timezone.utc) + dt.timedelta(seconds=1)
    doc = yaml.safe_load((out / "ifdo.yaml").read_text())
    validator().validate(doc)

    items = doc["image-set-items"]
    assert sorted(items) == ["a_0001.jpg", "b_0002.jpg", "c_0003.jpg"]
    for name, item in items.items():
        data = (out / name).read_bytes()
        assert item["image-hash-sha256"] == hashlib.sha256(data).hexdigest()
        with Image.open(out / name) as im:
            embedded = im.getexif().get_ifd(EXIF_IFD)[0xA420]
        assert uuid.UUID(item["image-uuid"]) == uuid.UUID(hex=embedded)
        assert uuid.UUID(item["image-uuid"]).version == 4
        assert item["image-handle"] == (out / name).resolve().as_uri()
    assert len({i["image-uuid"] for i in items.values()}) == 3
    a, b, c = items["a_0001.jpg"], items["b_0002.jpg"], items["c_0003.jpg"]
    # a: no offset, taken as UTC; b: 08:00:00.5 at +10:00 is 22:00:00.5 UTC the day before
    assert a["image-datetime"] == "2026-11-30 10:15:42.437"
    assert b["image-datetime"] == "2026-11-29 22:00:00.500"
    assert a["image-latitude"] == pytest.approx(-(33 + 51 / 60 + 35.9 / 3600), abs=1e-12)
    assert a["image-longitude"] == pytest.approx(151 + 12 / 60 + 40.5 / 3600, abs=1e-12)
    assert a["image-altitude-meters"] == -18.5 and b["image-altitude-meters"] == -21.0
    assert b["image-latitude"] == pytest.approx(-(33 + 52 / 60), abs=1e-12)
    assert not any(k in c for k in ("image-datetime", "image-latitude", "image-altitude-meters"))

    h = doc["image-set-header"]
    assert {k: h[k] for k in HEADER} == HEADER
    assert {k: h[k] for k in POSITION} == POSITION  # the header's defaults win over derived ones
    assert h["image-set-ifdo-version"] == "v2.0.1" and h["image-set-name"] == "DIVE_042_restored"
    assert h["image-datetime"] == "2026-11-29 22:00:00.500"  # the earliest
    assert h["image-set-min-latitude-degrees"] == b["image-latitude"]
    assert h["image-set-max-latitude-degrees"] == a["image-latitude"]
    assert h["image-set-handle"] == out.resolve().as_uri() + "/"

    prov = h["image-set-provenance"]
    assert [ag["name"].split()[0] for ag in prov["provenance-agents"]] == ["uwhl_rs"]
    acts = {x["uwhl-restoration"]["sidecar"]: x for x in prov["provenance-activities"]}
    assert sorted(acts) == ["a_0001.json", "b_0002.json", "c_0003.json"]
    for stem, src in (("a_0001", "a_0001.jpg"), ("b_0002", "b_0002.jpg"), ("c_0003", "c_0003.png")):
        act = acts[stem + ".json"]
        side = json.loads((out / f"{stem}.json").read_text())
        assert act["used-entities"][0] == {"name": src,
                                           "id": "sha256:" + hashlib.sha256((dive / src).read_bytes()).hexdigest()}
        assert act["uwhl-restoration"]["water-type"] == side["water_type"]
        assert act["uwhl-restoration"]["veiling-light"] == side["veiling_light"]
        assert act["uwhl-restoration"]["fallback-share"] == side["fallback_share"]
        assert act["uwhl-restoration"]["veil-excess"] == side["veil_excess"]
        t0 = dt.datetime.fromisoformat(act["start-time"].replace("Z", "+00:00"))
        t1 = dt.datetime.fromisoformat(act["end-time"].replace("Z", "+00:00"))
        assert began - dt.timedelta(seconds=1) <= t0 <= t1 <= ended
    ents = {e["name"]: e for e in prov["provenance-entities"]}
    assert ents["a_0001.jpg"]["id"] == "urn:uuid:" + a["image-uuid"]
    assert ents["a_0001.jpg"]["generated-by"] == [acts["a_0001.json"]["id"]]

    # the validator is live: what the standard requires is checked
    broken = copy.deepcopy(doc)
    del broken["image-set-items"]["a_0001.jpg"]["image-hash-sha256"]
    assert not validator().is_valid(broken)
    broken = copy.deepcopy(doc)
    broken["image-set-items"]["a_0001.jpg"]["image-uuid"] = str(uuid.uuid1())
    assert not validator().is_valid(broken)


def test_a_rerun_keeps_the_set_uuid_and_json_and_a_handle_base_are_written(binary, dive, tmp_path):
    out = tmp_path / "out"
    assert restore("rust", binary, [dive], out).returncode == 0
    head = header_file(tmp_path, {**HEADER, **POSITION}, "header.json")
    r = uwhl("ifdo", out, "--header", head, "-q")
    assert r.returncode == 0 and r.stdout == "", r.stderr
    first = json.loads((out / "ifdo.json").read_text())
    validator().validate(first)
    r = uwhl("ifdo", out, "--header", head, "--format", "yaml", "--handle-base", "https://data.example.org/dive42/")
    assert r.returncode == 0, r.stderr
    again = yaml.safe_load((out / "ifdo.yaml").read_text())
    validator().validate(again)
    assert again["image-set-header"]["image-set-uuid"] == first["image-set-header"]["image-set-uuid"]
    assert again["image-set-items"]["a_0001.jpg"]["image-handle"] == "https://data.example.org/dive42/a_0001.jpg"
    assert again["image-set-header"]["image-set-handle"] == "https://data.example.org/dive42/"
    assert again["image-set-items"] == {
        k: {**v, "image-handle": "https://data.example.org/dive42/" + k} for k, v in first["image-set-items"].items()}
    assert not [p for p in os.listdir(out) if p.endswith(".tmp")]


def test_missing_header_fields_are_named_before_any_photo_is_restored(binary, dive, tmp_path):
    out = tmp_path / "out"
    fields = {k: v for k, v in HEADER.items() if k not in ("image-pi", "image-license")}
    r = restore("python", binary, [dive], out, "--ifdo", header_file(tmp_path, fields))
    assert r.returncode == 2
    assert "image-pi" in r.stderr and "image-license" in r.stderr
    assert not out.exists() or not any(out.iterdir())
    bad = {**HEADER, "image-project": "Reef colour", "image-coordinate-uncertainty-meters": -1}
    r = restore("python", binary, [dive], out, "--ifdo", header_file(tmp_path, bad))
    assert r.returncode == 2 and "image-project must be a mapping" in r.stderr and "uncertainty" in r.stderr
    for text, why in ((": [unclosed", "not YAML"), ("- a list\n", "must be a mapping")):
        (tmp_path / "h.yaml").write_text(text)
        r = restore("python", binary, [dive], out, "--ifdo", tmp_path / "h.yaml")
        assert r.returncode == 2 and why in r.stderr, r.stderr
    r = restore("python", binary, [dive], out, "--ifdo", tmp_path / "absent.yaml")
    assert r.returncode == 2 and "cannot read the header" in r.stderr


def test_photos_without_position_need_the_header_default(binary, dive, tmp_path):
    out = tmp_path / "out"
    assert restore("rust", binary, [dive], out).returncode == 0
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, HEADER))
    assert r.returncode == 2
    assert "image-latitude" in r.stderr and "1 of 3 photos have no GPS position" in r.stderr
    assert not (out / "ifdo.yaml").exists()
    # the same after a batch: the photos are restored and written, the iFDO
    # is the output that could not be (exit 5, not the 2 of "nothing read")
    out1 = tmp_path / "out1"
    r = restore("python", binary, [dive], out1, "--ifdo", header_file(tmp_path, HEADER))
    assert r.returncode == 5 and "no iFDO written" in r.stderr and "image-latitude" in r.stderr, r.stderr
    assert len(list(out1.glob("*.json"))) == 3 and not (out1 / "ifdo.yaml").exists()
    # with every photo positioned and timed, nothing more is needed
    only = tmp_path / "positioned"
    only.mkdir()
    for n in ("a_0001.jpg", "b_0002.jpg"):
        (only / n).write_bytes((dive / n).read_bytes())
    out2 = tmp_path / "out2"
    assert restore("rust", binary, [only], out2).returncode == 0
    r = uwhl("ifdo", out2, "--header", header_file(tmp_path, HEADER))
    assert r.returncode == 0, r.stderr
    doc = yaml.safe_load((out2 / "ifdo.yaml").read_text())
    validator().validate(doc)
    h = doc["image-set-header"]
    lats = [i["image-latitude"] for i in doc["image-set-items"].values()]
    assert h["image-latitude"] == pytest.approx(np.mean(lats)) and h["image-altitude-meters"] == pytest.approx(-19.75)


def test_a_folder_without_photos_or_with_unwritten_metadata(binary, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    r = uwhl("ifdo", empty, "--header", header_file(tmp_path, {**HEADER, **POSITION}))
    assert r.returncode == 2 and "no restored photo" in r.stderr
    r = uwhl("ifdo", tmp_path / "absent", "--header", header_file(tmp_path, HEADER))
    assert r.returncode == 3 and "no such folder" in r.stderr


def test_a_photo_gets_another_uuid_when_restored_otherwise(binary, tmp_path):
    """The UUID follows input and restoration: the same for both commands on
    one input with one set of parameters (a PNG input: both decode it alike),
    another with other parameters or another input."""
    src = tmp_path / "in"
    src.mkdir()
    Image.fromarray(_scene(seed=4)).save(src / "x.png")
    Image.fromarray(_scene(seed=5)).save(src / "y.png")
    got = {}
    for face, extra in (("python", ()), ("rust", ()), ("rust", ("--water-type", "3C"))):
        out = tmp_path / f"{face}{len(extra)}"
        assert restore(face, binary, [src], out, *extra).returncode == 0
        got[face, extra] = {n: json.loads((out / f"{n}.json").read_text())["metadata"]["image_uuid"] for n in "xy"}
    assert got["python", ()] == got["rust", ()]
    assert got["rust", ()]["x"] != got["rust", ()]["y"]
    assert got["rust", ("--water-type", "3C")]["x"] != got["rust", ()]["x"]


def test_a_planted_sidecar_lists_no_photo_that_is_not_there_or_not_its_own(binary, dive, tmp_path):
    """The iFDO publishes each photo's SHA-256: a sidecar naming a photo
    that is not in the folder, or another file of the folder, or a photo
    changed since, is left out with a note; the photos as written stay."""
    out = tmp_path / "out"
    assert restore("rust", binary, [dive], out).returncode == 0
    names = sorted(p.stem for p in out.glob("*.json"))
    side = json.loads((out / f"{names[0]}.json").read_text())
    planted = {"ghost": "ghost.jpg", "other": "summary.csv"}
    for stem, image in planted.items():
        doc = copy.deepcopy(side)
        doc["outputs"] = {"image": image}
        doc["metadata"]["image_uuid"] = uuid.uuid4().hex
        (out / f"{stem}.json").write_text(json.dumps(doc))
    # a photo changed after it was written: its sidecar's hash is not its own any more
    changed = out / f"{names[1]}.jpg"
    changed.write_bytes(changed.read_bytes() + b"\0")
    head = header_file(tmp_path, {**HEADER, **POSITION})
    r = uwhl("ifdo", out, "--header", head)
    assert r.returncode == 0, r.stderr
    items = yaml.safe_load((out / "ifdo.yaml").read_text())["image-set-items"]
    assert sorted(items) == sorted(f"{n}.jpg" for n in names if n != names[1])
    for n in items:
        assert items[n]["image-hash-sha256"] == hashlib.sha256((out / n).read_bytes()).hexdigest()
    said = r.stdout + r.stderr
    assert "'ghost.jpg' is not there; left out of the iFDO" in said
    # another file of the folder is not an output of the sidecar's own name (NAME.json lists NAME.jpg)
    assert "other.json: not a usable sidecar: outputs.image is 'summary.csv', not an output of its own name" in said
    assert f"'{names[1]}.jpg' is not the file its sidecar describes" in said
