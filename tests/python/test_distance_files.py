"""``--distance TEMPLATE`` in both commands (docs/OUTPUTS.md "Distance"):
each input's map is found by its name, read in every documented format,
recorded in the sidecar; a photo whose map is missing, unreadable or of
another photo's shape is restored without it and flagged, never failed."""

import json

import numpy as np
import pytest
from PIL import Image

import uwhl_rs
from bothcmds import cmds as _cmds, run_restore as _run, sidecar as _side
from exrfile import exr_bytes
from uwhl_rs import synth

tifffile = pytest.importorskip("tifffile")

H, W = 90, 120


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    """Two photos of a seabed and their true distance, with a hole of
    known size in the map (the top 30 rows: 1/3 of the pixels unknown)."""
    d = tmp_path_factory.mktemp("dive")
    sc = synth.scene(H, W, kind="looking_down", seed=3)
    z = np.where(np.isfinite(sc.distance), sc.distance, np.nan).astype(np.float32)
    z[:30] = np.nan
    for k in (1, 2):
        img = synth.render(sc.clean, sc.distance, "3C", beta_b=0.3, noise=0.004, seed=k)
        tifffile.imwrite(d / f"p{k}.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    (d / "depth").mkdir()
    np.save(d / "depth" / "p1.npy", z)
    mm = np.where(np.isfinite(z), np.round(z * 1000), 0).astype(np.uint16)
    Image.fromarray(mm).save(d / "depth" / "p2.png")
    tifffile.imwrite(d / "depth" / "p1.tif", z)
    (d / "depth" / "p1.exr").write_bytes(exr_bytes({"Z": z}))
    return d, z



def test_read_distance_gives_the_map_the_commands_read(dive, tmp_path):
    """uwhl_rs.read_distance: the same metres from every format, NaN where unknown."""
    d, z = dive
    known = np.isfinite(z)
    for name in ("p1.npy", "p1.tif", "p1.exr"):
        got = uwhl_rs.read_distance(d / "depth" / name)
        assert got.dtype == np.float32 and got.shape == z.shape
        assert np.array_equal(np.isnan(got), ~known) and np.array_equal(got[known], z[known]), name
    mm = uwhl_rs.read_distance(d / "depth" / "p2.png")  # whole millimetres
    assert np.array_equal(np.isnan(mm), ~known) and np.max(np.abs(mm[known] - z[known])) <= 0.0005 + 1e-6
    (tmp_path / "notes.exr").write_text("a text file named like a map")
    with pytest.raises(uwhl_rs.ImageError, match="not a distance map"):
        uwhl_rs.read_distance(tmp_path / "notes.exr")
    with pytest.raises(MemoryError, match="over max_pixels 100"):
        uwhl_rs.read_distance(d / "depth" / "p1.exr", max_pixels=100)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_each_photo_gets_its_own_map_by_name(impl, binary, dive, tmp_path):
    d, z = dive
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", out, "--distance", d / "depth" / "{stem}.npy")
    assert r.returncode == 0, r.stderr
    side = _side(out, "p1")
    rec = side["distance"]
    assert rec["source"] == str(d / "depth" / "p1.npy")
    # 30 of 90 rows unknown: 2/3 of the pixels known
    assert abs(rec["coverage"] - 2 / 3) < 1e-6
    assert side["parameters"]["distance"] == str(d / "depth" / "{stem}.npy")
    assert "distance_missing" not in side["flags"]


@pytest.mark.parametrize("impl", ["python", "rust"])
@pytest.mark.parametrize("template", ["{stem}.png", "p1.tif", "{stem}.exr"])
def test_millimetre_png_float_tiff_and_openexr_give_the_same_coverage(impl, binary, dive, tmp_path, template):
    d, z = dive
    src = d / ("p2.tif" if template.endswith(".png") else "p1.tif")
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], src, "-o", out, "--distance", d / "depth" / template)
    assert r.returncode == 0, r.stderr
    assert abs(_side(out, src.stem)["distance"]["coverage"] - 2 / 3) < 1e-6


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_missing_or_unreadable_map_restores_the_photo_without_it_and_flags_it(impl, binary, dive, tmp_path):
    d, _ = dive
    out = tmp_path / impl
    bad = tmp_path / "maps"
    bad.mkdir()
    Image.fromarray(np.full((H, W), 7, np.uint8)).save(bad / "p2.png")  # 8 bits cannot hold a distance
    r = _run(_cmds(binary)[impl], d / "p1.tif", d / "p2.tif", "-o", out, "--distance", bad / "{stem}.png")
    assert r.returncode == 0, r.stderr
    for name, why in (("p1", "no such file"), ("p2", "16-bit")):
        side = _side(out, name)
        assert "distance_missing" in side["flags"], side["flags"]
        assert side["distance"]["used"] is False and why in side["distance"]["rejected"], side["distance"]
        assert side["distance"]["haze_order"] is None
        assert (out / f"{name}.jpg").exists()


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_disparity_given_as_distance_is_rejected_by_the_photos_haze(impl, binary, tmp_path):
    """A map that orders near and far against the photo's own haze (METHOD
    §13.1): recorded as distance.haze_order, the photo restored without it."""
    from test_distance_fit import _render

    img, _, z, _, _ = _render("III", 0.10, seed=4)
    tifffile.imwrite(tmp_path / "seabed.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    (tmp_path / "right").mkdir()
    (tmp_path / "disparity").mkdir()
    np.save(tmp_path / "right" / "seabed.npy", z)
    np.save(tmp_path / "disparity" / "seabed.npy", (20.0 / z).astype(np.float32))
    for kind, used in (("right", True), ("disparity", False)):
        out = tmp_path / f"{impl}_{kind}"
        r = _run(_cmds(binary)[impl], tmp_path / "seabed.tif", "-o", out, "--distance",
                 tmp_path / kind / "{stem}.npy")
        assert r.returncode == 0, r.stderr
        side = _side(out, "seabed")
        rec = side["distance"]
        assert rec["used"] is used, rec
        if used:
            assert rec["haze_order"] > 0.5 and "distance_rejected" not in side["flags"]
        else:
            assert rec["haze_order"] < -0.5 and "distance_rejected" in side["flags"]
            assert "orders near and far against the photo's own haze" in rec["rejected"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_map_of_another_shape_is_rejected_not_stretched(impl, binary, dive, tmp_path):
    d, z = dive
    np.save(tmp_path / "wide.npy", np.ones((H, 2 * W), np.float32))
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", out, "--distance", tmp_path / "wide.npy")
    assert r.returncode == 0, r.stderr
    side = _side(out, "p1")
    assert "distance_rejected" in side["flags"]
    assert "aspect ratio" in side["distance"]["rejected"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_distance_does_not_go_with_reuse_estimates(impl, binary, dive, tmp_path):
    d, _ = dive
    r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", tmp_path / impl, "--distance", "x.npy", "--reuse-estimates", "2")
    assert r.returncode == 2 and "--reuse-estimates" in r.stderr, r.stderr
    assert not (tmp_path / impl / "p1.json").exists()


def _nearest(br, bg):
    """The Jerlov type nearest to the ratios in log space (METHOD §13)."""
    return min(synth.JERLOV, key=lambda t: np.log(br / synth.JERLOV[t][0]) ** 2 + np.log(bg / synth.JERLOV[t][1]) ** 2)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_water_from_takes_the_median_of_the_calibrated_photos(impl, binary, dive, tmp_path):
    """Three calibrated sidecars (hand-made), one not used and one hostile:
    every photo of the run gets the ratios of the median beta as its one water type."""
    d, _ = dive
    cal = tmp_path / "calibrated"
    cal.mkdir()
    fits = [(0.50, 0.12, 0.06), (0.40, 0.10, 0.05), (0.66, 0.13, 0.06)]
    for k, b in enumerate(fits):
        (cal / f"c{k}.json").write_text(json.dumps({"distance": {"used": True, "water": {"beta": b}}}))
    (cal / "x.json").write_text(json.dumps({"distance": {"used": False, "water": {"beta": [9, 9, 0.01]}}}))
    (cal / "y.json").write_text("{" * 100000)
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", out, "--water-from", cal)
    assert r.returncode == 0, r.stderr
    side = _side(out, "p1")
    med = np.median(fits, axis=0)  # (0.50, 0.12, 0.06)
    br, bg = float(med[2] / med[0]), float(med[2] / med[1])
    assert side["beta_ratios"] == pytest.approx([br, bg], rel=1e-9)
    assert side["water_type"] == _nearest(br, bg)
    assert list(side["scores"]) == [side["water_type"]]
    rec = side["parameters"]["water_from"]
    assert rec["photos"] == 3 and rec["folder"] == str(cal)
    assert rec["ratio_range"][0] == pytest.approx([0.06 / 0.66, 0.125], rel=1e-9)
    assert rec["weighted"] is False  # no fit records its range: plain medians


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_water_from_holds_for_a_sequence_too(impl, binary, dive, tmp_path):
    """With --reuse-estimates the photos are one sequence: each is still
    restored with the dive's water (one score, its ratios), as the sidecar
    says, not with a type of its own choice."""
    d, _ = dive
    cal = tmp_path / "calibrated"
    cal.mkdir()
    (cal / "c.json").write_text(json.dumps({"distance": {"used": True, "water": {"beta": [0.9, 0.2, 0.1]}}}))
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], d / "p1.tif", d / "p2.tif", "-o", out, "--water-from", cal, "--reuse-estimates", "2")
    assert r.returncode == 0, r.stderr
    for p in ("p1", "p2"):
        side = _side(out, p)
        assert side["beta_ratios"] == pytest.approx([0.1 / 0.9, 0.1 / 0.2], rel=1e-9)
        assert list(side["scores"]) == [side["water_type"]] == [_nearest(0.1 / 0.9, 0.5)]
        assert side["parameters"]["water_from"]["beta_ratios"] == pytest.approx(side["beta_ratios"], rel=1e-9)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_water_from_weights_each_fit_by_how_far_it_pins_its_water(impl, binary, dive, tmp_path):
    """METHOD §13.6: a fit whose blue range spans x1.1 (weight 1 / ln 1.1 =
    10.5) outweighs two that span x10 (0.43 each): its ratios are the dive's,
    where the plain median would be another fit's."""
    d, _ = dive
    cal = tmp_path / "calibrated"
    cal.mkdir()
    fits = [((0.50, 0.12, 0.06), (0.01, 0.1)), ((0.40, 0.10, 0.05), (0.01, 0.1)), ((0.66, 0.13, 0.06), (0.057, 0.0627))]
    for k, (b, blue) in enumerate(fits):
        water = {"beta": b, "beta_range": [[0.1, 1.0], [0.05, 0.5], list(blue)]}
        (cal / f"c{k}.json").write_text(json.dumps({"distance": {"used": True, "water": water}}))
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", out, "--water-from", cal)
    assert r.returncode == 0, r.stderr
    side = _side(out, "p1")
    assert side["beta_ratios"] == pytest.approx([0.06 / 0.66, 0.06 / 0.13], rel=1e-9)
    assert float(np.median([b[2] / b[0] for b, _ in fits])) == pytest.approx(0.12)  # what the plain median gives
    assert side["parameters"]["water_from"]["weighted"] is True


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_water_from_a_folder_without_fits_is_a_usage_error(impl, binary, dive, tmp_path):
    d, _ = dive
    (tmp_path / "empty").mkdir()
    for args in (["--water-from", tmp_path / "empty"], ["--water-from", tmp_path / "nope"],
                 ["--water-from", d, "--water-type", "3C"]):
        r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", tmp_path / impl, *args)
        assert r.returncode == 2 and "--water-from" in r.stderr, (args, r.stderr)
    assert not (tmp_path / impl / "p1.json").exists()


def _axis_cosine(h, w, fov, port):
    """cos of each pixel's ray to the optical axis in water, for a pinhole
    camera of horizontal field of view ``fov`` in air (Snell's law at a
    flat window, n = 1.333; unbent behind a dome), computed here from the
    geometry, not by the package."""
    f = (w / 2) / np.tan(np.radians(fov) / 2)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    u, v = u + 0.5 - w / 2, v + 0.5 - h / 2
    sin_air = np.hypot(u, v) / np.sqrt(u * u + v * v + f * f)
    sin_water = sin_air / 1.333 if port == "flat" else sin_air
    return np.sqrt(1 - sin_water ** 2)


def test_depth_to_range_divides_by_the_cosine_of_each_ray():
    depth = np.full((H, W), 2.0, np.float32)
    depth[0, 0] = np.nan
    for port in ("flat", "dome"):
        got = uwhl_rs.depth_to_range(depth, 70.0, port=port)
        want = 2.0 / _axis_cosine(H, W, 70.0, port)
        assert np.isnan(got[0, 0]) and np.allclose(got[1:], want[1:], rtol=1e-6)
    # the corner of a 90-degree lens behind a dome: more than 1.2 times the depth
    assert uwhl_rs.depth_to_range(depth, 90.0, port="dome")[-1, -1] > 2.4
    with pytest.raises(uwhl_rs.ParameterError, match="field of view"):
        uwhl_rs.depth_to_range(depth, 180.0)


@pytest.fixture(scope="module")
def receding(tmp_path_factory):
    """A seabed receding from 1 m (bottom row) to 8 m (top row) seen
    through type 3C water, with its range map and the same seabed's depth
    along the axis of a 70-degree lens behind a flat port."""
    d = tmp_path_factory.mktemp("receding")
    sc = synth.scene(H, W, kind="looking_down", seed=5)
    rows = np.linspace(8.0, 1.0, H)[:, None]
    z = np.repeat(rows, W, 1).astype(np.float32)
    img = synth.render(sc.clean, z, "3C", beta_b=0.3, noise=0.002, seed=1)
    tifffile.imwrite(d / "sea.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    np.save(d / "range.npy", z)
    np.save(d / "depth.npy", (z * _axis_cosine(H, W, 70.0, "flat")).astype(np.float32))
    return d


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_depth_along_the_axis_is_restored_as_its_range(impl, binary, receding, tmp_path):
    """The same seabed given as ranges, and as depth along the axis with
    --distance-kind depth: the same fitted water; the lens is recorded; a
    photo without a lens is restored without distance, flagged."""
    d = receding
    cmd = _cmds(binary)[impl]
    out_r, out_d, out_x = tmp_path / "range", tmp_path / "depth", tmp_path / "nolens"
    r = _run(cmd, d / "sea.tif", "-o", out_r, "--distance", d / "range.npy")
    assert r.returncode == 0, r.stderr
    r = _run(cmd, d / "sea.tif", "-o", out_d, "--distance", d / "depth.npy", "--distance-kind", "depth", "--fov", "70")
    assert r.returncode == 0, r.stderr
    ranged, converted = _side(out_r, "sea")["distance"], _side(out_d, "sea")["distance"]
    assert ranged["used"] is True and converted["used"] is True, (ranged, converted)
    assert converted["depth"]["fov"] == 70.0 and converted["depth"]["port"] == "flat"
    in_water = 2 * np.degrees(np.arcsin(np.sin(np.radians(35.0)) / 1.333))
    assert converted["depth"]["fov_from"] == "--fov" and converted["depth"]["fov_in_water"] == pytest.approx(in_water)
    assert converted["water"]["beta"] == pytest.approx(ranged["water"]["beta"], rel=1e-3)
    params = _side(out_d, "sea")["parameters"]
    assert params["distance_kind"] == "depth" and "distance_kind" not in _side(out_r, "sea")["parameters"]
    # read as ranges, the same depth map fits another water
    r = _run(cmd, d / "sea.tif", "-o", tmp_path / "asis", "--distance", d / "depth.npy")
    assert r.returncode == 0, r.stderr
    asis = _side(tmp_path / "asis", "sea")["distance"]
    assert asis["water"]["beta"] != pytest.approx(ranged["water"]["beta"], rel=1e-3)
    # a float TIFF has no EXIF lens: without --fov the map is not used
    r = _run(cmd, d / "sea.tif", "-o", out_x, "--distance", d / "depth.npy", "--distance-kind", "depth")
    assert r.returncode == 0, r.stderr
    side = _side(out_x, "sea")
    assert "distance_missing" in side["flags"] and "no field of view" in side["distance"]["rejected"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_depth_kind_and_the_lens_go_with_their_distance(impl, binary, dive, tmp_path):
    d, _ = dive
    for args, needle in ((["--distance-kind", "depth"], "--distance-kind"),
                         (["--distance", "x.npy", "--fov", "70"], "--fov"),
                         (["--distance", "x.npy", "--distance-kind", "deep"], "--distance-kind")):
        r = _run(_cmds(binary)[impl], d / "p1.tif", "-o", tmp_path / impl, *args)
        assert r.returncode == 2 and needle in r.stderr, (args, r.stderr)
    assert not (tmp_path / impl / "p1.json").exists()


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_colmap_depth_map_is_read_and_turned_into_ranges(impl, binary, receding, tmp_path):
    """COLMAP's dense depth map (written here in its layout: the header
    WIDTH&HEIGHT&1&, then float32 with the column index fastest) of the
    receding seabed, as depth along the axis: the same water as its ranges."""
    d = receding
    depth = np.load(d / "depth.npy")
    (tmp_path / "sea.tif.geometric.bin").write_bytes(f"{W}&{H}&1&".encode() + np.nan_to_num(depth, nan=0.0).astype("<f4").tobytes())
    cmd = _cmds(binary)[impl]
    r = _run(cmd, d / "sea.tif", "-o", tmp_path / "colmap", "--distance", tmp_path / "{name}.geometric.bin",
             "--distance-kind", "depth", "--fov", "70")
    assert r.returncode == 0, r.stderr
    r = _run(cmd, d / "sea.tif", "-o", tmp_path / "range", "--distance", d / "range.npy")
    assert r.returncode == 0, r.stderr
    got, want = _side(tmp_path / "colmap", "sea")["distance"], _side(tmp_path / "range", "sea")["distance"]
    assert got["used"] is True and got["water"]["beta"] == pytest.approx(want["water"]["beta"], rel=1e-3)
    assert np.array_equal(uwhl_rs.read_distance(tmp_path / "sea.tif.geometric.bin"), depth, equal_nan=True)


def test_both_commands_record_the_same_fitted_water_to_the_last_digit(binary, tmp_path):
    """The fit runs in the same core for both commands; the Python command's
    record goes through a JSON parse on its way to the sidecar, which must
    give back the number written (every float of distance.water equal). On
    this seabed a parse that is not exact changed the last digit of some."""
    sc = synth.scene(H, W, kind="looking_down", seed=2)
    z = np.repeat(np.linspace(8.0, 1.0, H)[:, None], W, 1).astype(np.float32)
    img = synth.render(sc.clean, z, "3C", beta_b=0.3, noise=0.002, seed=1)
    tifffile.imwrite(tmp_path / "sea.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    np.save(tmp_path / "range.npy", z)
    water = {}
    for impl, cmd in _cmds(binary).items():
        r = _run(cmd, tmp_path / "sea.tif", "-o", tmp_path / impl, "--distance", tmp_path / "range.npy")
        assert r.returncode == 0, r.stderr
        water[impl] = _side(tmp_path / impl, "sea")["distance"]["water"]
    assert water["python"] is not None and water["python"] == water["rust"]
    assert len(water["rust"]["beta_range"]) == 3 and water["rust"]["plausible_types"]


@pytest.mark.parametrize("every", [1, 2, 3])
def test_both_commands_sample_a_map_of_any_size_alike_under_max_side(binary, tmp_path, every):
    """docs/CLI.md "--distance": a map of the photo's aspect ratio at any
    size is used; with --max-side the photo is shrunk and the map sampled at
    the shrunk size. Both commands must use the same map (same veiling
    light, same fitted water, same restored bytes), whatever the map's size.
    Rows of a 10 km distance are unknown and counted in both sidecars."""
    h, w = 240, 320
    sc = synth.scene(h, w, kind="looking_down", seed=4)
    z = np.repeat(np.linspace(9.0, 1.5, h)[:, None], w, 1).astype(np.float32)
    img = synth.render(sc.clean, z, "3C", beta_b=0.3, noise=0.002, seed=1)
    tifffile.imwrite(tmp_path / "sea.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    small = np.ascontiguousarray(z[::every, ::every])
    small[:2] = 10_000.0  # beyond the 1 km a distance may be: unknown
    np.save(tmp_path / "range.npy", small)
    side, pixels = {}, {}
    for impl, cmd in _cmds(binary).items():
        r = _run(cmd, tmp_path / "sea.tif", "-o", tmp_path / impl, "--distance", tmp_path / "range.npy",
                 "--max-side", "160", "--format", "tiff")
        assert r.returncode == 0, r.stderr
        side[impl] = _side(tmp_path / impl, "sea")
        pixels[impl] = tifffile.imread(tmp_path / impl / "sea.tif")
    py, rs = side["python"], side["rust"]
    assert rs["distance"]["used"] and py["distance"]["used"]
    assert py["distance"]["out_of_range"] == rs["distance"]["out_of_range"] == 2 * small.shape[1]
    assert py["distance"]["water"] == rs["distance"]["water"]
    assert py["veiling_light"] == rs["veiling_light"]
    assert np.array_equal(pixels["python"], pixels["rust"])


def _calibrate(cal, fits):
    for f in cal.glob("*.json"):
        f.unlink()
    for k, b in enumerate(fits):
        (cal / f"c{k}.json").write_text(json.dumps({"distance": {"used": True, "water": {"beta": b}}}))


I_FITS = [(0.05 / 0.1118, 0.05 / 0.4566, 0.05)] * 2  # Jerlov I at beta_B 0.05 1/m
C9_FITS = [(0.3 / 2.0708, 0.3 / 1.5942, 0.3)] * 2  # 9C at 0.3 1/m


def test_water_from_is_read_at_each_call_of_restore_file(dive, tmp_path):
    """A process serves one call after another: the folder as it is at the
    call, not as an earlier call found it."""
    from uwhl_rs import files

    d, _ = dive
    cal = tmp_path / "cal"
    cal.mkdir()
    _calibrate(cal, I_FITS)
    a = files.restore_file(d / "p1.tif", tmp_path / "a", water_from=cal)
    _calibrate(cal, C9_FITS)
    b = files.restore_file(d / "p1.tif", tmp_path / "b", water_from=cal)
    assert a.sidecar["water_type"] == "I" and b.sidecar["water_type"] == "9C"


def test_water_from_is_read_once_per_run_of_restore_many(dive, tmp_path):
    pytest.importorskip("pandas")
    from uwhl_rs import batch

    d, _ = dive
    cal = tmp_path / "cal"
    cal.mkdir()
    _calibrate(cal, I_FITS)
    a = batch.restore_many(str(d / "p1.tif"), str(tmp_path / "a"), water_from=str(cal))
    _calibrate(cal, C9_FITS)
    b = batch.restore_many(str(d / "p1.tif"), str(tmp_path / "b"), water_from=str(cal))
    assert list(a["water_type"]) == ["I"] and list(b["water_type"]) == ["9C"]


def test_a_dask_worker_reads_water_from_again_at_a_new_runs_first_task(monkeypatch):
    from uwhl_rs import cluster

    read = []
    monkeypatch.setattr(cluster._core, "new_run", lambda: read.append(True))
    monkeypatch.setattr(cluster, "restore_items", lambda *a: list(a))
    assert cluster._restore_in_run("run1", 1, 2) == [1, 2]
    cluster._restore_in_run("run1", 3)
    assert len(read) == 1  # the same run: the folder as its first task read it
    cluster._restore_in_run("run2", 4)
    assert len(read) == 2
