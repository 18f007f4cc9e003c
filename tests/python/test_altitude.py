"""``--altitude`` (METHOD §13.7, docs/OUTPUTS.md "Distance"): the distance
of a downward camera over a flat seabed, from a number, a navigation log
(by file name or by time) or the photo's XMP, with the field of view from
``--fov`` or the EXIF; in both commands, recorded in the sidecar; a photo
the log does not cover is restored without distance and flagged; a
malformed log is refused before any photo, naming its line and column."""

import math
import sys

import numpy as np
import pytest
from PIL import Image

import uwhl_rs
from bothcmds import cmds as _cmds, run_restore as _run, sidecar as _side
from uwhl_rs import synth

tifffile = pytest.importorskip("tifffile")

H, W = 96, 128
BETA_B = 0.3
WTYPE = "3C"



# -- the geometry, against closed forms ------------------------------------------------------------------------


def _rays(h, w, fov):
    """Unit rays in air of a pinhole camera (x right, y down, z along the axis)."""
    f = (w / 2) / math.tan(math.radians(fov) / 2)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    d = np.stack([u + 0.5 - w / 2, v + 0.5 - h / 2, np.full((h, w), f)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_a_level_camera_behind_a_dome_sees_altitude_over_the_cosine():
    z = uwhl_rs.floor_distance((H, W), 2.0, 80.0, port="dome")
    d = _rays(H, W, 80.0)
    np.testing.assert_allclose(z, 2.0 / d[..., 2], rtol=1e-5)


def test_a_flat_port_bends_each_ray_by_snells_law():
    z = uwhl_rs.floor_distance((H, W), 2.0, 80.0, port="flat")
    d = _rays(H, W, 80.0)
    theta_air = np.arccos(d[..., 2])
    theta_water = np.arcsin(np.sin(theta_air) / 1.333)
    np.testing.assert_allclose(z, 2.0 / np.cos(theta_water), rtol=1e-5)
    # narrower in water: every off-axis pixel is nearer than behind a dome
    assert (z <= uwhl_rs.floor_distance((H, W), 2.0, 80.0, port="dome") + 1e-6).all()


def test_pitch_and_roll_rotate_the_rays_as_a_vehicle_does():
    """Nose up by p: the body's down axis turns towards forward (the photo's
    top); starboard down by r: towards port (the photo's left). The seabed
    is h below: range = h / (down component of the ray)."""
    p, r = math.radians(12.0), math.radians(-7.0)
    z = uwhl_rs.floor_distance((H, W), 3.0, 70.0, pitch=12.0, roll=-7.0, port="dome")
    d = _rays(H, W, 70.0)
    body = np.stack([-d[..., 1], d[..., 0], d[..., 2]], axis=-1)  # forward, starboard, down
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    world = body @ (ry @ rx).T
    np.testing.assert_allclose(z, 3.0 / world[..., 2], rtol=1e-5)
    up = uwhl_rs.floor_distance((H, W), 3.0, 70.0, pitch=12.0, port="dome")
    assert up[0].mean() > up[-1].mean()


def _bench():
    """benches/altitude.py, whose ray-surface intersection makes the true ranges of its renders."""
    import importlib.util
    import os

    path = os.path.join(os.path.dirname(__file__), "..", "..", "benches", "altitude.py")
    spec = importlib.util.spec_from_file_location("altitude_bench", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclasses look themselves up there
    spec.loader.exec_module(mod)
    return mod


def test_the_benchs_marching_meets_a_tilted_plane_where_the_closed_form_does():
    """The bench measures --altitude against ranges found by marching along
    each ray to a heightfield. On a plane h below the camera's foot sloping
    by a towards azimuth psi, depth = h + tan(a)(X cos psi + Y sin psi), so
    the ray t w meets it at t = h / (w_Z - tan(a)(w_X cos psi + w_Y sin psi))
    (a bilinear grid of a plane is the plane). Over a level floor the bench's
    rays give floor_distance's ranges."""
    A = _bench()
    h, a, psi = 2.5, math.radians(20.0), math.radians(130.0)
    gx, gy = math.tan(a) * math.cos(psi), math.tan(a) * math.sin(psi)
    step, half = 0.1, 20.0
    xs = -half + step * np.arange(int(2 * half / step) + 1)
    field = A.Heightfield(h, gx * xs[:, None] + gy * xs[None, :], step, half)
    w = A.camera_rays(24, 32, 70.0, pitch=35.0, roll=-6.0)
    want = h / (w[..., 2] - gx * w[..., 0] - gy * w[..., 1])
    want = np.where(want > 0, want, np.nan)
    near = np.hypot(want * w[..., 0], want * w[..., 1]) < half - 1  # where the grid holds the plane
    assert near.mean() > 0.5
    got = A.march(field.depth, w, 0.0, 2 * half)
    np.testing.assert_allclose(got[near], want[near], rtol=1e-6)
    # the nadir of a level camera meets the sloping plane at the altitude itself
    assert abs(float(A.march(field.depth, np.array([[0.0, 0.0, 1.0]]), 0.0, 10.0)[0]) - h) < 1e-6
    level = A.Plane(h).intersect(A.camera_rays(H, W, 80.0, pitch=12.0, roll=-7.0))
    np.testing.assert_allclose(level, uwhl_rs.floor_distance((H, W), h, 80.0, pitch=12.0, roll=-7.0), rtol=1e-5)


def test_values_out_of_range_are_parameter_errors():
    for kw in ({"altitude": 0.0, "fov": 70}, {"altitude": 2, "fov": 190}, {"altitude": 2, "fov": 70, "pitch": 95}):
        with pytest.raises(uwhl_rs.ParameterError):
            uwhl_rs.floor_distance((H, W), kw.pop("altitude"), kw.pop("fov"), **kw)
    with pytest.raises(uwhl_rs.ParameterError, match="port"):
        uwhl_rs.floor_distance((H, W), 2.0, 70.0, port="glass")


# -- both commands ----------------------------------------------------------------------------------------------


def _render(altitude, fov, pitch=0.0, roll=0.0, seed=3):
    """A seabed's texture seen from `altitude` over a flat floor: the
    distance is the geometry's, the water 3C with beta_B = 0.3."""
    sc = synth.scene(H, W, kind="looking_down", seed=seed)
    z = uwhl_rs.floor_distance((H, W), altitude, fov, pitch=pitch, roll=roll)
    return synth.render(sc.clean, z, WTYPE, beta_b=BETA_B, noise=0.003, seed=seed)


def _true_beta():
    br, bg = synth.JERLOV[WTYPE]
    return np.array([BETA_B / br, BETA_B / bg, BETA_B])


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    d = tmp_path_factory.mktemp("alt")
    tifffile.imwrite(d / "level.tif", _render(2.5, 70.0), photometric="rgb")
    tifffile.imwrite(d / "tilted.tif", _render(2.0, 70.0, pitch=10.0, roll=-5.0), photometric="rgb")
    # an ROV's oblique view: 2.4 to 9 m along the rays
    tifffile.imwrite(d / "oblique.tif", _render(2.0, 70.0, pitch=55.0, roll=-8.0), photometric="rgb")
    return d


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_constant_altitude_gives_the_fitted_water_and_records_the_floor(impl, binary, photos, tmp_path):
    out = tmp_path / impl
    r = _run(_cmds(binary)[impl], photos / "level.tif", "-o", out, "--altitude", "2.5", "--fov", "70")
    assert r.returncode == 0, r.stderr
    side = _side(out, "level")
    rec = side["distance"]
    assert rec["source"] == "altitude 2.5 m", rec
    # straight down the ranges span too little: restored without, flagged (METHOD §13.7)
    assert rec["used"] is False and "too narrow a range" in rec["rejected"] and "distance_rejected" in side["flags"]
    fl = rec["floor"]
    assert fl["altitude"] == 2.5 and fl["fov"] == 70.0 and fl["port"] == "flat" and fl["fov_from"] == "--fov"
    assert fl["pitch"] == 0.0 and fl["pose_from"] == "--altitude"
    # 2 asin(sin 35 / 1.333) = 51.03 degrees in water
    assert abs(fl["fov_in_water"] - 2 * math.degrees(math.asin(math.sin(math.radians(35)) / 1.333))) < 1e-6


def test_the_oblique_view_fits_the_water_and_a_level_one_cannot(photos):
    """Seen obliquely (2.4-9 m along the rays) the photo holds enough water
    between near and far to fit it; straight down from 2.5 m the ranges
    span 2.5-2.9 m, too little to tell attenuation from content (METHOD
    §13.7): rejected by name, the photo restored without distance."""
    img = tifffile.imread(photos / "oblique.tif")
    res = uwhl_rs.restore(img, distance=uwhl_rs.floor_distance(img.shape, 2.0, 70.0, pitch=55.0, roll=-8.0))
    beta = np.array(res.water["beta"])
    assert np.all(np.abs(beta / _true_beta() - 1) < 0.4), (beta, _true_beta())
    level = tifffile.imread(photos / "level.tif")
    res = uwhl_rs.restore(level, distance=uwhl_rs.floor_distance(level.shape, 2.5, 70.0))
    assert res.distance["used"] is False and "too narrow a range" in res.distance["rejected"]
    assert "distance_rejected" in res.flags


def test_both_commands_write_the_same_outputs(binary, photos, tmp_path):
    for impl, cmd in _cmds(binary).items():
        r = _run(cmd, photos / "tilted.tif", "-o", tmp_path / impl, "--altitude", "2", "--fov", "70", "--format", "png")
        assert r.returncode == 0, r.stderr
    py, rs = _side(tmp_path / "python", "tilted"), _side(tmp_path / "rust", "tilted")
    assert py["distance"] == rs["distance"]
    for suffix in ("", "_t"):
        assert (tmp_path / "python" / f"tilted{suffix}.png").read_bytes() == (tmp_path / "rust" / f"tilted{suffix}.png").read_bytes()


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_log_by_name_gives_each_photo_its_pose_and_one_it_lacks_is_flagged(impl, binary, photos, tmp_path):
    log = tmp_path / "nav.csv"
    log.write_text("# dive 17\nFile,Altitude,Pitch,Roll\nlevel.tif,2.5,0,0\n\"dives/tilted.tif\",2.0,10,-5\n"
                   "oblique.tif,2,55,-8\n")
    (tmp_path / "in").mkdir()
    for n in ("level", "tilted", "oblique"):
        (tmp_path / "in" / f"{n}.tif").write_bytes((photos / f"{n}.tif").read_bytes())
    (tmp_path / "in" / "other.tif").write_bytes((photos / "level.tif").read_bytes())
    out = tmp_path / "out"
    r = _run(_cmds(binary)[impl], tmp_path / "in", "-o", out, "--altitude", log, "--fov", "70")
    assert r.returncode == 0, r.stderr
    tilted = _side(out, "tilted")["distance"]
    assert (tilted["floor"]["pitch"], tilted["floor"]["roll"], tilted["floor"]["altitude"]) == (10.0, -5.0, 2.0)
    assert tilted["floor"]["pose_from"] == {"log": str(log), "line": 4, "matched": "name"}
    assert _side(out, "oblique")["distance"]["used"] is True
    other = _side(out, "other")
    assert other["distance"]["used"] is False and 'no row for "other.tif"' in other["distance"]["rejected"]
    assert "distance_missing" in other["flags"]


def _jpeg_with_exif(path, img, when=None, focal35=None):
    ex = Image.Exif()
    sub = {}
    if when is not None:
        sub[36867] = when  # DateTimeOriginal
    if focal35 is not None:
        sub[41989] = focal35  # FocalLengthIn35mmFilm
    ex[34665] = sub
    u8 = np.clip(np.round(uwhl_rs.to_srgb(img) * 255), 0, 255).astype(np.uint8)
    Image.fromarray(u8).save(path, quality=95, exif=ex)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_log_by_time_interpolates_and_the_exif_gives_the_lens(impl, binary, tmp_path):
    # 2 s after a record at 2.0 m, 2 s before one at 3.0 m: 2.5 m
    _jpeg_with_exif(tmp_path / "p.jpg", _render(2.5, 71.6), when="2026:11:30 10:15:42", focal35=24)
    log = tmp_path / "nav.csv"
    log.write_text("time,altitude\n2026-11-30T10:15:40,2.0\n2026-11-30T10:15:44,3.0\n2026-11-30T10:20:00,9\n")
    out = tmp_path / "out"
    r = _run(_cmds(binary)[impl], tmp_path / "p.jpg", "-o", out, "--altitude", log)
    assert r.returncode == 0, r.stderr
    fl = _side(out, "p")["distance"]["floor"]
    assert abs(fl["altitude"] - 2.5) < 1e-9
    assert fl["pose_from"]["matched"] == "time, interpolated" and fl["pose_from"]["line"] == [2, 3]
    # 24 mm equivalent on a 4:3 photo: its width is 43.27 * 4/5 = 34.61 mm of the 35 mm frame's diagonal
    want = 2 * math.degrees(math.atan(21.6333 * 0.8 / 24))
    assert abs(fl["fov"] - want) < 0.01 and "FocalLengthIn35mmFormat" in fl["fov_from"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_without_a_lens_or_a_time_the_photo_is_restored_without_distance(impl, binary, tmp_path):
    _jpeg_with_exif(tmp_path / "p.jpg", _render(2.5, 70.0))
    log = tmp_path / "nav.csv"
    log.write_text("time,altitude\n2026-11-30T10:15:40,2.0\n")
    for args, why in ((["--altitude", "2.5"], "no field of view"), (["--altitude", log, "--fov", "70"], "no time")):
        out = tmp_path / f"o{len(args)}"
        r = _run(_cmds(binary)[impl], tmp_path / "p.jpg", "-o", out, *args)
        assert r.returncode == 0, r.stderr
        side = _side(out, "p")
        assert side["distance"]["used"] is False and why in side["distance"]["rejected"], side["distance"]
        assert "distance_missing" in side["flags"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_the_xmp_field_of_ifdo_gives_the_altitude(impl, binary, tmp_path):
    from PIL import PngImagePlugin

    xmp = ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
           '<rdf:Description xmlns:ifdo="https://www.marine-imaging.com/fair/ifdo" '
           'ifdo:image-meters-above-ground="2.5"/></rdf:RDF></x:xmpmeta>')
    info = PngImagePlugin.PngInfo()
    info.add_itxt("XML:com.adobe.xmp", xmp)
    u8 = np.clip(np.round(uwhl_rs.to_srgb(_render(2.5, 70.0)) * 255), 0, 255).astype(np.uint8)
    Image.fromarray(u8).save(tmp_path / "p.png", pnginfo=info)
    out = tmp_path / "out"
    r = _run(_cmds(binary)[impl], tmp_path / "p.png", "-o", out, "--altitude", "xmp", "--fov", "70")
    assert r.returncode == 0, r.stderr
    rec = _side(out, "p")["distance"]
    assert rec["floor"]["altitude"] == 2.5 and rec["floor"]["pose_from"] == "xmp"


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_malformed_log_is_refused_before_any_photo_naming_line_and_column(impl, binary, photos, tmp_path):
    log = tmp_path / "nav.csv"
    log.write_text("file,altitude,pitch\nlevel.tif,2.5,0\ntilted.tif,2.o,3\n")
    out = tmp_path / "out"
    r = _run(_cmds(binary)[impl], photos / "level.tif", "-o", out, "--altitude", log, "--fov", "70")
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "line 3, column 2 (altitude)" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("impl", ["python", "rust"])
@pytest.mark.parametrize("args,word", [
    (["--fov", "70"], "--altitude"),
    (["--altitude", "2", "--distance", "d/{stem}.npy"], "two sources"),
    (["--altitude", "2", "--reuse-estimates", "5"], "--reuse-estimates"),
    (["--altitude", "-2"], "an altitude is in"),
    (["--altitude", "2", "--fov", "200"], "--fov"),
    (["--altitude", "2", "--port", "glass"], "--port"),
])
def test_distance_options_that_do_not_go_together_are_usage_errors(impl, binary, photos, tmp_path, args, word):
    r = _run(_cmds(binary)[impl], photos / "level.tif", "-o", tmp_path / "o", *args)
    assert r.returncode == 2 and word in r.stderr and "Traceback" not in r.stderr, (r.returncode, r.stderr)


def test_restoring_with_the_floor_beats_the_estimate_on_an_oblique_view(photos):
    """The point of the option: with the geometry known, the restored colours
    are nearer the truth than the estimate without it."""
    sc = synth.scene(H, W, kind="looking_down", seed=3)
    img = tifffile.imread(photos / "oblique.tif")
    z = uwhl_rs.floor_distance((H, W), 2.0, 70.0, pitch=55.0, roll=-8.0)

    def angle(j):
        a, b = j.reshape(-1, 3).astype(np.float64), sc.clean.reshape(-1, 3).astype(np.float64)
        cos = (a * b).sum(1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-12)
        return float(np.median(np.degrees(np.arccos(np.clip(cos, -1, 1)))))

    with_floor = angle(uwhl_rs.restore(img, distance=z).image)
    without = angle(uwhl_rs.restore(img).image)
    assert with_floor < without, (with_floor, without)


def test_a_log_is_read_at_each_call_of_restore_file(photos, tmp_path):
    """A process serves one call after another: the log as it is at the
    call (a dive's log that grew, or was corrected), not as an earlier call
    read it."""
    from uwhl_rs import files

    log = tmp_path / "nav.csv"
    log.write_text("File,Altitude\nlevel.tif,2.5\n")
    a = files.restore_file(photos / "level.tif", tmp_path / "a", altitude=str(log), fov=70)
    log.write_text("File,Altitude\nlevel.tif,3.5\n")
    b = files.restore_file(photos / "level.tif", tmp_path / "b", altitude=str(log), fov=70)
    assert a.sidecar["distance"]["floor"]["altitude"] == 2.5
    assert b.sidecar["distance"]["floor"]["altitude"] == 3.5
