"""The method profiles and their steps (docs/METHOD.md §12): the white
balance against its formula and under a known illuminant, the type choice
on renders of every type, the haze-line floor's transmission, the paper
profile as the paper's steps, the sidecar's record and every error path."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import ParameterError, evaluate as ev, synth

NAMES = [n for n, _, _ in uwhl_rs._core.JERLOV_TABLE]
GRAYS = (0.90, 0.59, 0.36, 0.19, 0.09, 0.03)


def _chart_scene(h, w, water_type, seed, illuminant=(1.0, 1.0, 1.0), noise=0.003):
    """An open-water render with a six-patch gray chart near the bottom (the
    chart and the scene lit by `illuminant`), its chart mask, patch boxes,
    true water region and true veiling light."""
    sc = synth.scene(h, w, kind="open_water", seed=seed)
    # the scene's colors rebalanced so that its 4-norm color is gray: the
    # assumption the white balance makes (METHOD §12.1) holds exactly
    objects = np.isfinite(sc.distance)
    norm = (sc.clean[objects].astype(np.float64) ** 4).mean(0) ** 0.25
    clean = np.clip(sc.clean * (norm.mean() / norm), 0, 1).astype(np.float32)
    side, gap = max(6, w // 20), 3
    x0, y0 = (w - 6 * side - 5 * gap) // 2, h - 2 * side
    boxes = []
    for k, g in enumerate(GRAYS):
        x = x0 + k * (side + gap)
        clean[y0:y0 + side, x:x + side] = g
        boxes.append((x + 1, y0 + 1, x + side - 1, y0 + side - 1))
    clean = np.clip(clean * np.asarray(illuminant, np.float32), 0, 1).astype(np.float32)
    a = synth.default_veiling_light(water_type)
    img = synth.render(clean, sc.distance, water_type, beta_b=0.2, noise=noise, seed=seed)
    mask = np.ones((h, w), bool)
    mask[y0 - gap:y0 + side + gap, x0 - gap:x0 + 6 * side + 5 * gap + gap] = False
    return img, mask, boxes, sc.water, a


def _psi(img, boxes):
    return float(np.nanmean([ev.angle_deg(img[y0:y1, x0:x1].reshape(-1, 3).astype(np.float64).mean(0))
                             for x0, y0, x1, y1 in boxes]))


def test_white_balance_follows_its_formula():
    """image = clip(radiance * g * s): g makes the object pixels' 4-norm (or
    mean) color gray, s maps the largest balanced channel's 99th percentile
    over the masked-in pixels to 1 (METHOD §12.1), computed here in NumPy
    (without the fallback of §12.5, which blends after it)."""
    img, mask, _, water, a = _chart_scene(96, 128, "III", 3)
    for wb, p in [("shades_of_gray", 4.0), ("gray_world", 1.0), ("white_patch", None)]:
        r = uwhl_rs.restore(img, mask=mask, water_mask=water, water_types=["III"], white_balance=wb, fallback="none")
        j = r.radiance.astype(np.float64)
        obj = mask & ~r.veiling_mask
        top = np.array([np.quantile(j[mask][:, c], 0.99) for c in range(3)])
        est = top if p is None else (j[obj] ** p).mean(0) ** (1 / p)
        g = est.mean() / est
        want = np.clip(j * (g / (g * top).max()), 0, 1)
        assert np.abs(r.image - want).max() < 1e-4, wb


def test_white_balance_removes_a_known_illuminant():
    """The same scene and chart (colors rebalanced so their 4-norm color is
    gray) under white, yellowish and greenish light, rendered in type III,
    restored with the true type, water region and A. The balance makes the
    result nearly independent of the light: the chart's psi-bar moves by
    less than 5 degrees between lights (measured 3.2) where the paper's
    display stretch moves it by more than 8 (measured 9.3), and it stays
    below the paper's under every light (measured 16.8-20.0 against
    27.5-36.8). It does not reach the input's gray on this near chart: the
    haze-line transmission, not the balance, sets that floor (METHOD §12.1)."""
    revised, paper = [], []
    for light in [(1.0, 1.0, 1.0), (1.0, 0.8, 0.55), (0.6, 1.0, 0.9)]:
        img, mask, boxes, water, a = _chart_scene(120, 160, "III", 5, illuminant=light)
        kw = dict(mask=mask, water_mask=water, water_types=["III"], veiling_light=a)
        revised.append(_psi(uwhl_rs.restore(img, **kw).image, boxes))
        paper.append(_psi(uwhl_rs.restore(img, method="paper", **kw).image, boxes))
    assert max(revised) - min(revised) < 5.0, revised
    assert max(paper) - min(paper) > 8.0, paper
    assert all(r < p for r, p in zip(revised, paper)) and max(revised) < 22.0, (revised, paper)


@pytest.mark.parametrize("noise", [0.003, 0.02])
def test_type_choice_on_renders_of_every_type(noise):
    """Renders of all ten types with the water region given: the revised
    choice lands within one step of the true type on at least 7 of 10 (and
    at least as often as the paper's gray world), measured on 120x160."""
    revised = paper = 0
    for k, t in enumerate(NAMES):
        img, mask, _, water, _ = _chart_scene(120, 160, t, 40 + k, noise=noise)
        for method in ("revised", "paper"):
            r = uwhl_rs.restore(img, mask=mask, water_mask=water, method=method)
            near = abs(NAMES.index(r.water_type) - k) <= 1
            revised += near and method == "revised"
            paper += near and method == "paper"
    assert revised >= 7 and revised >= paper, (revised, paper)


def _chromaticity(x):
    y = np.maximum(x.astype(np.float64), 1e-6)
    return y / y.sum(1, keepdims=True)


@pytest.mark.parametrize("seed, balance", [(1, None), (2, None), (1, "stretch")])
def test_central_choice_is_the_display_between_the_other_two(seed, balance):
    """The default type choice (METHOD §12.2) against the rule computed here
    from the whole displays: each of the three best-scored types restored
    alone, its displayed chromaticity over every object pixel, the type
    whose summed median L1 distance to the other two is least. The core
    compares 4,000 of those pixels and estimates the blend's veil excess on
    them: it may differ only where two spreads are within 0.005. With the
    paper's stretch as the display, the displays compared are the stretch's."""
    kw = {} if balance is None else {"white_balance": balance}
    for t in NAMES:
        img, _ = synth.demo_input(120, 160, water_type=t, seed=seed)
        r = uwhl_rs.restore(img, **kw)
        best3 = sorted(r.scores, key=r.scores.get)[:3]
        objects = ~r.veiling_mask
        shown = {k: _chromaticity(uwhl_rs.restore(img, water_types=[k], **kw).image[objects]) for k in best3}
        spread = {a: sum(np.median(np.abs(shown[a] - shown[b]).sum(1)) for b in best3) for a in best3}
        assert r.water_type in best3 and spread[r.water_type] <= min(spread.values()) + 0.005, (t, r.water_type, spread)
        # the scores are shades_of_gray's, whose choice is the best of them
        assert uwhl_rs.restore(img, type_choice="shades_of_gray", **kw).water_type == best3[0]


def test_haze_floor_estimates_a_clear_type_with_the_floors_ratios():
    """A type below the floor gets exactly the floor type's transmission
    (the same haze-lines, bound, matting and filter), and its own recovery."""
    img, mask, _, water, a = _chart_scene(96, 128, "II", 7)
    kw = dict(mask=mask, water_mask=water, veiling_light=a, method="paper")
    low = uwhl_rs.restore(img, water_types=["I"], haze_floor="3C", **kw)
    floor = uwhl_rs.restore(img, water_types=["3C"], **kw)
    own = uwhl_rs.restore(img, water_types=["I"], **kw)
    assert np.array_equal(low.transmission, floor.transmission)
    assert not np.array_equal(low.radiance, floor.radiance)
    # without the floor, type I's t_B sits at its own floor 0.1^0.1118 = 0.773
    assert own.transmission.min() >= np.float32(0.1 ** 0.1118) - 1e-6 > low.transmission.min()
    # a type at or above the floor is untouched by it
    hi = uwhl_rs.restore(img, water_types=["5C"], haze_floor="3C", **kw)
    assert np.array_equal(hi.image, uwhl_rs.restore(img, water_types=["5C"], **kw).image)


def test_paper_profile_is_the_paper_steps():
    img, _ = synth.demo_input(64, 80, seed=2)
    paper = uwhl_rs.restore(img, method="paper")
    steps = uwhl_rs.restore(img, white_balance="stretch", type_choice="gray_world", haze_floor="none",
                            selection="exhaustive", fallback="none")
    assert np.array_equal(paper.image, steps.image) and paper.scores == steps.scores
    assert uwhl_rs.method_steps(method="paper") == {"method": "paper", "selection": "exhaustive",
                                                    "white_balance": "stretch", "type_choice": "gray_world",
                                                    "haze_floor": "none", "fallback": "none"}
    assert uwhl_rs.method_steps() == {"method": "revised", "selection": "fast", "white_balance": "shades_of_gray",
                                      "type_choice": "central", "haze_floor": "3C", "fallback": "input_balance"}
    # an explicit step overrides the profile's
    assert uwhl_rs.method_steps(method="paper", white_balance="white_patch")["white_balance"] == "white_patch"
    # the revised choice never excludes a type; its scores are shades_of_gray's,
    # which picks the lowest, and it picks among their three best (METHOD §12.2)
    rev = uwhl_rs.restore(img)
    sog = uwhl_rs.restore(img, type_choice="shades_of_gray")
    assert rev.excluded == [] and rev.scores == sog.scores
    assert sog.scores[sog.water_type] == min(sog.scores.values())
    assert rev.water_type in sorted(rev.scores, key=rev.scores.get)[:3]


@pytest.mark.parametrize("kw, name", [
    ({"method": "best"}, "method"), ({"method": 1}, "method"), ({"white_balance": "auto"}, "white_balance"),
    ({"white_balance": ["stretch"]}, "white_balance"), ({"type_choice": "drift"}, "type_choice"),
    ({"haze_floor": "XI"}, "haze_floor"), ({"haze_floor": 3}, "haze_floor"), ({"t_scale": 0.0}, "t_scale"),
    ({"t_scale": 1.5}, "t_scale"), ({"t_scale": float("nan")}, "t_scale"), ({"t_scale": "0.9"}, "t_scale"),
    ({"t_scale": True}, "t_scale"),
])
def test_bad_step_keywords_name_themselves(kw, name):
    img, _ = synth.demo_input(32, 40, seed=1)
    with pytest.raises(ParameterError, match=name):
        uwhl_rs.restore(img, **kw)
    with pytest.raises(ParameterError, match=name):
        uwhl_rs.Sequence(**kw).restore(img)


def test_haze_floor_names_are_case_insensitive_on_the_command_line():
    assert uwhl_rs._core.parse_option("haze_floor", "3c") == "3C"
    assert uwhl_rs._core.parse_option("method", "PAPER") == "paper"
    for key, bad in [("method", "best"), ("t_scale", "1.5"), ("t_scale", "0"), ("haze_floor", "XI"),
                     ("white_balance", "auto"), ("type_choice", "x")]:
        with pytest.raises(ValueError, match=key.replace("_", "-")):
            uwhl_rs._core.parse_option(key, bad)


@pytest.mark.parametrize("flags, steps", [
    ([], {"method": "revised", "selection": "fast", "white_balance": "shades_of_gray",
          "type_choice": "central", "haze_floor": "3C", "t_scale": 0.9, "fallback": "input_balance"}),
    (["--method", "paper", "--t-scale", "0.8"], {"method": "paper", "selection": "exhaustive",
                                                 "white_balance": "stretch", "type_choice": "gray_world",
                                                 "haze_floor": "none", "t_scale": 0.8, "fallback": "none"}),
    (["--selection", "exhaustive"], {"method": "revised", "selection": "exhaustive"}),
    (["--method", "paper", "--white-balance", "white_patch", "--haze-floor", "1c"],
     {"method": "paper", "white_balance": "white_patch", "type_choice": "gray_world", "haze_floor": "1C"}),
])
def test_both_commands_record_the_steps_used(tmp_path, binary, flags, steps):
    img, _ = synth.demo_input(48, 64, seed=4)
    src = tmp_path / "in.png"
    uwhl_rs.images.write_image(str(src), img, bits=16, encoding="linear")
    cmds = {"uwhl": [sys.executable, "-m", "uwhl_rs", "restore"], "uwhl-rs": [binary]}
    images = {}
    for name, cmd in cmds.items():
        out = tmp_path / name
        r = subprocess.run([*cmd, str(src), "-o", str(out), "-q", "--format", "png", *flags],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        side = json.loads((out / "in.json").read_text())
        for k, v in steps.items():
            assert side["parameters"][k] == v, (name, k, side["parameters"])
        images[name] = (out / "in.png").read_bytes()
    assert len(set(images.values())) == 1


@pytest.mark.parametrize("flag", [["--method", "best"], ["--t-scale", "2"], ["--haze-floor", "XI"]])
def test_bad_step_flags_are_usage_errors_in_both_commands(tmp_path, binary, flag):
    img, _ = synth.demo_input(32, 40, seed=1)
    src = tmp_path / "in.png"
    uwhl_rs.images.write_image(str(src), img, bits=8)
    cmds = [[sys.executable, "-m", "uwhl_rs", "restore"], [binary]]
    for cmd in cmds:
        r = subprocess.run([*cmd, str(src), "-o", str(tmp_path / "o"), *flag], capture_output=True, text=True)
        assert r.returncode == 2 and flag[0] in r.stderr, (cmd, r.returncode, r.stderr)
        assert not (tmp_path / "o" / "in.jpg").exists()


def test_the_demo_finds_its_own_water_type(tmp_path, binary):
    """The README's first command on its built-in scene (type III): the
    revised profile names III (the paper's choice named 3C, with III
    excluded by the t_R rule); the binary's own rendered scene is within one
    step (measured: 1C)."""
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "demo", "-o", str(tmp_path / "py")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "true water type:      III" in r.stdout and "estimated water type: III " in r.stdout, r.stdout
    r = subprocess.run([binary, "demo", "-o", str(tmp_path / "rs")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    est = r.stdout.split("estimated water type:")[1].split()[0]
    assert abs(NAMES.index(est) - NAMES.index("III")) <= 1, r.stdout
