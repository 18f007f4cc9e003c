"""One command-line contract (docs/CLI.md): ``uwhl restore`` and ``uwhl-rs
restore`` run over the same table of cases (good inputs, corrupt ones, bad
flags, over budget, unwritable output, interrupted, sequences) and must
agree on the exit code, the files written and the sidecars' fields.

The expected codes come from the contract's table, not from either
command: 0 ok, 2 bad arguments, 3 unreadable input, 4 over budget, 5
unwritable output, 130 interrupted.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import _core, synth

CONTRACT = {"ok": 0, "bad_arguments": 2, "unreadable_input": 3, "over_budget": 4, "write_failed": 5,
            "internal": 6, "unreachable": 7, "interrupted": 130}

# fields of the sidecar both commands must write alike (the estimates and the
# options that are not face-specific)
SAME_FIELDS = ["water_type", "scores", "excluded", "veiling_light", "vl_pixels", "flags", "guided_radius",
               "guided_subsample", "beta_ratios", "outputs", "reused_estimates"]


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("parity_inputs")
    for k, wt in enumerate(["II", "3C", "7C"]):
        img, _ = synth.demo_input(60, 80, water_type=wt, seed=k)
        uwhl_rs.images.write_image(d / f"f{k}.png", img, bits=8, encoding="linear")
    good = (d / "f0.png").read_bytes()
    (d / "truncated.png").write_bytes(good[: len(good) // 3])
    (d / "garbage.jpg").write_bytes(b"\xff\xd8\xff\xe0 not really a jpeg" * 10)
    (d / "a_file").write_text("not a folder")
    os.mkfifo(d / "fifo.jpg")  # opening it for reading would block
    return d


def _cmd(face: str, binary: str, args: list[str]) -> list[str]:
    if face == "python":
        return [sys.executable, "-m", "uwhl_rs", "restore", *args]
    return [binary, "restore", *args]


def _outputs(out) -> dict:
    """Each input's files (summary.csv, the batch's, is compared apart)."""
    if not os.path.isdir(out):
        return {}
    res = {}
    for dp, _, fs in os.walk(out):
        for f in fs:
            if f == "summary.csv" and dp == str(out):
                continue
            p = os.path.join(dp, f)
            rel = os.path.relpath(p, out)
            res[rel] = json.load(open(p)) if f.endswith(".json") else os.path.getsize(p)
    return res


#: summary.csv columns both commands must fill alike (seconds and messages may differ)
SUMMARY_SAME = ("status", "water_type", "A_R", "A_G", "A_B", "flags", "taken_at", "latitude", "longitude",
                "altitude", "image", "transmission", "transmission_color", "sidecar", "error_kind", "exit_code")


def _listing(out) -> list:
    """The files of OUTDIR, less the batch's summary.csv."""
    return sorted(f for f in os.listdir(out) if f != "summary.csv")


def _summary_rows(out) -> dict | None:
    """summary.csv by input, or None when there is none."""
    import csv

    p = os.path.join(out, "summary.csv")
    if not os.path.exists(p):
        return None
    with open(p, newline="", encoding="utf-8", errors="surrogateescape") as f:
        rows = list(csv.DictReader(f))
    return {r["input"]: r for r in rows}


def _same_summaries(py, rs) -> None:
    assert (py is None) == (rs is None), "one command wrote summary.csv, the other not"
    if py is None:
        return
    assert sorted(py) == sorted(rs)
    for inp, a in py.items():
        b = rs[inp]
        for c in SUMMARY_SAME:
            x, y = a[c], b[c]
            if c in ("image", "transmission", "transmission_color", "sidecar"):  # each in its own OUTDIR
                x, y = os.path.basename(x), os.path.basename(y)
            try:
                assert float(x) == pytest.approx(float(y), rel=1e-12), (inp, c)
            except ValueError:
                assert x == y, (inp, c, x, y)
        for c in [c for c in a if c.startswith("score_")]:
            assert (a[c] == "" and b[c] == "") or float(a[c]) == float(b[c]), (inp, c)


def _run(face, binary, args, tmp, stdin=None):
    # a hang (an input opened that never ends) fails the test instead of the suite
    r = subprocess.run(_cmd(face, binary, args), capture_output=True, text=True, timeout=120, env=_env(),
                       input=stdin, cwd=tmp)
    return r


# (id, arguments with {d} = input folder and {o} = output folder, expected kind, expected output names)
CASES = [
    ("good", ["{d}/f0.png", "{d}/f1.png", "-o", "{o}", "--format", "png"], "ok",
     {f"f{k}{s}" for k in range(2) for s in (".png", "_t.png", "_t_color.png", "_confidence.png", ".json")}),
    ("out spelled --out", ["{d}/f0.png", "--out", "{o}", "--format", "png"], "ok",
     {"f0.png", "f0_t.png", "f0_t_color.png", "f0_confidence.png", "f0.json"}),
    ("out spelled --output", ["{d}/f0.png", "--output", "{o}", "--format", "png"], "ok",
     {"f0.png", "f0_t.png", "f0_t_color.png", "f0_confidence.png", "f0.json"}),
    ("truncated beside good", ["{d}/truncated.png", "{d}/f2.png", "-o", "{o}", "--format", "png"],
     "unreadable_input", {"f2.png", "f2_t.png", "f2_t_color.png", "f2_confidence.png", "f2.json"}),
    ("garbage jpeg", ["{d}/garbage.jpg", "-o", "{o}"], "unreadable_input", set()),
    ("missing input", ["{d}/nope.png", "-o", "{o}"], "unreadable_input", set()),
    ("quality 0", ["{d}/f0.png", "-o", "{o}", "--quality", "0"], "bad_arguments", set()),
    ("quality 101", ["{d}/f0.png", "-o", "{o}", "--quality", "101"], "bad_arguments", set()),
    ("unknown flag", ["{d}/f0.png", "-o", "{o}", "--frobnicate"], "bad_arguments", set()),
    ("bad water type", ["{d}/f0.png", "-o", "{o}", "--water-type", "XI"], "bad_arguments", set()),
    ("bad eps", ["{d}/f0.png", "-o", "{o}", "--guided-eps", "-1"], "bad_arguments", set()),
    ("bits 16 with jpg", ["{d}/f0.png", "-o", "{o}", "--bits", "16"], "bad_arguments", set()),
    ("bits 12", ["{d}/f0.png", "-o", "{o}", "--format", "png", "--bits", "12"], "bad_arguments", set()),
    ("reuse mask without reuse", ["{d}/f0.png", "-o", "{o}", "--reuse-water-mask"], "bad_arguments", set()),
    ("no output folder", ["{d}/f0.png"], "bad_arguments", set()),
    ("over max-pixels", ["{d}/f0.png", "-o", "{o}", "--max-pixels", "100"], "over_budget", set()),
    ("over max-memory", ["{d}/f0.png", "-o", "{o}", "--max-memory", "64K"], "over_budget", set()),
    ("output is a file", ["{d}/f0.png", "-o", "{d}/a_file"], "write_failed", set()),
    ("FIFO named like an image", ["{d}/fifo.jpg", "{d}/f0.png", "-o", "{o}", "--format", "png"], "unreadable_input",
     {"f0.png", "f0_t.png", "f0_t_color.png", "f0_confidence.png", "f0.json"}),
    ("sequence", ["{d}/f0.png", "{d}/f1.png", "{d}/f2.png", "-o", "{o}", "--format", "png",
                  "--reuse-estimates", "2", "--guided-subsample", "auto"], "ok",
     {f"f{k}{s}" for k in range(3) for s in (".png", "_t.png", "_t_color.png", "_confidence.png", ".json")}),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_both_commands_keep_one_contract(binary, files, tmp_path, case):
    name, args, kind, names = case
    seen = {}
    for face in ("python", "rust"):
        out = tmp_path / face
        a = [x.format(d=files, o=out) for x in args]
        r = _run(face, binary, a, tmp_path)
        assert r.returncode == CONTRACT[kind], (face, r.returncode, r.stderr[-2000:])
        got = _outputs(out)
        assert set(got) == names, (face, sorted(got))
        if kind != "ok" and not (kind == "unreadable_input" and names):
            assert r.stderr.strip(), face  # a message names the problem
        seen[face] = got
    _same_summaries(_summary_rows(tmp_path / "python"), _summary_rows(tmp_path / "rust"))
    for f in names:
        if f.endswith(".json"):
            py, rs = seen["python"][f], seen["rust"][f]
            for key in SAME_FIELDS:
                assert py.get(key) == rs.get(key), (f, key)
            for key, value in py["parameters"].items():
                if key not in ("threads", "half_size"):
                    assert rs["parameters"].get(key) == value, (f, key)


def test_json_errors_are_the_same_objects(binary, files, tmp_path):
    objs = {}
    for face in ("python", "rust"):
        r = _run(face, binary, [str(files / "garbage.jpg"), "-o", str(tmp_path / face), "--json-errors"], tmp_path)
        assert r.returncode == CONTRACT["unreadable_input"], r.stderr
        lines = [json.loads(x) for x in r.stderr.splitlines() if x.strip()]  # nothing but JSON
        assert len(lines) == 1, r.stderr
        objs[face] = lines[0]
    for o in objs.values():
        assert set(o) == {"error", "input", "message", "exit_code"}
        assert (o["error"], o["exit_code"]) == ("unreadable_input", 3)
        assert o["input"].endswith("garbage.jpg") and o["message"]


def test_progress_skip_and_summary_lines_agree(binary, files, tmp_path):
    lines = {}
    for face in ("python", "rust"):
        out = tmp_path / face
        args = [str(files / "f0.png"), str(files / "f1.png"), "-o", str(out), "--format", "png"]
        first = _run(face, binary, args, tmp_path)
        again = _run(face, binary, args, tmp_path)
        assert (first.returncode, again.returncode) == (0, 0)
        text = first.stdout + first.stderr
        assert "[1/2] " in text and "[2/2] " in text and " -> " in text and "(water type " in text, text
        assert "2 done, 0 skipped, 0 failed in " in first.stdout, first.stdout
        text = again.stdout + again.stderr
        assert f"{files / 'f0.png'}: skipped ({out / 'f0.json'} exists)" in text, text
        assert "0 done, 2 skipped, 0 failed in " in again.stdout, again.stdout
        lines[face] = sorted(ln.split(" (water type")[0] for ln in text.splitlines() if ln.startswith("[")) 
    assert lines["python"] == [ln.replace("/rust/", "/python/") for ln in lines["rust"]]


def test_rust_only_and_python_only_options_are_refused_with_a_pointer(binary, files, tmp_path):
    r = _run("rust", binary, [str(files / "f0.png"), "-o", str(tmp_path / "o"), "--contact-sheet"], tmp_path)
    assert r.returncode == 2 and "Python command" in r.stderr
    r = subprocess.run([binary, "evaluate"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "uwhl evaluate" in r.stderr
    r = _run("python", binary, [str(files / "f0.png"), "-o", str(tmp_path / "o"), "--stream"], tmp_path)
    assert r.returncode == 2


def test_help_of_both_lists_the_shared_options_and_exit_codes(binary):
    py = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "--help"], capture_output=True, text=True,
                        env=_env(), timeout=60).stdout
    rs = subprocess.run([binary, "--help"], capture_output=True, text=True, timeout=60).stdout
    for o in _core.OPTIONS:
        if o["faces"] in ("both", "python"):
            assert o["flag"] in py, o["flag"]
        if o["faces"] in ("both", "rust"):
            assert o["flag"] in rs, o["flag"]
    for code, name, _ in _core.EXIT_CODES:
        assert CONTRACT[name] == code
        assert f"  {code} " in py and f"  {code} " in rs, code


@pytest.mark.skipif(not hasattr(signal, "SIGTERM"), reason="no SIGINT / SIGTERM")
@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_interrupt_is_130_and_resumes(binary, files, tmp_path, sig):
    """SIGINT or SIGTERM (a batch system's stop) mid-batch: exit 130 with the
    resume hint, no temporaries or claims, every sidecar written has its
    outputs, and the same command run again finishes the rest with exit 0
    without touching the finished inputs. SIGINT goes back to its default
    in the child: a shell that starts the suite in the background passes
    it on ignored."""
    sig = getattr(signal, sig)
    many = tmp_path / "many"
    many.mkdir()
    for k in range(30):
        os.link(files / f"f{k % 3}.png", many / f"m{k:02d}.png")
    for face in ("python", "rust"):
        out = tmp_path / face
        args = _cmd(face, binary, [str(many), "-o", str(out), "--format", "png", "--max-side", "40"])
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(),
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        deadline = time.time() + 120
        while time.time() < deadline and not (out.exists() and any(f.endswith(".json") for f in os.listdir(out))):
            time.sleep(0.02)
        p.send_signal(sig)
        _, err = p.communicate(timeout=120)
        done = [f for f in os.listdir(out) if f.endswith(".json")]
        if len(done) == 30:
            pytest.skip(f"{face}: the run finished before the interrupt")
        assert p.returncode == CONTRACT["interrupted"], (face, p.returncode, err[-1000:])
        assert "run the same command again to resume" in err, (face, err)
        assert not [f for f in os.listdir(out) if f.startswith(".")], face  # no temporaries
        for f in done:
            stem = f[:-5]
            for s in (".png", "_t.png", "_t_color.png"):
                assert (out / f"{stem}{s}").exists(), (face, stem, s)
        stamps = {f: os.stat(out / f).st_mtime_ns for f in done}
        again = subprocess.run(args, capture_output=True, text=True, env=_env(), timeout=600)
        assert again.returncode == 0, again.stderr
        assert len([f for f in os.listdir(out) if f.endswith(".json")]) == 30
        assert f"{len(done)} skipped" in again.stdout
        assert {f: os.stat(out / f).st_mtime_ns for f in done} == stamps, face  # finished inputs untouched


def test_demo_in_both_commands(binary, tmp_path):
    """`demo` in both: the same options, the same four files of the scene's
    size, the same report lines; each renders its own scene with the water
    type asked for and restores it (docs/CLI.md)."""
    from PIL import Image

    for face, cmd in (("python", [sys.executable, "-m", "uwhl_rs"]), ("rust", [binary])):
        out = tmp_path / face
        r = subprocess.run([*cmd, "demo", "-o", str(out), "--water-type", "1C", "--size", "90x120", "--seed", "3"],
                           capture_output=True, text=True, env=_env(), timeout=300)
        assert r.returncode == 0, (face, r.stderr)
        assert sorted(os.listdir(out)) == ["clean_truth.png", "input.png", "restored.png", "transmission.png"]
        for f in os.listdir(out):
            assert Image.open(out / f).size == (120, 90), (face, f)
        lines = r.stdout.splitlines()
        assert "true water type:      1C" in lines, (face, r.stdout)
        for start in ("estimated water type: ", "veiling light A: true (", "water region: ", "rho(true distance, -ln t_B) = "):
            assert any(ln.startswith(start) for ln in lines), (face, start, r.stdout)
        rho = float(next(ln for ln in lines if ln.startswith("rho(")).split("= ")[1])
        assert rho > 0.5, (face, rho)  # the transmission follows the rendered distances
        bad = subprocess.run([*cmd, "demo", "--size", "3x9", "-o", str(tmp_path / "x")], capture_output=True,
                             text=True, env=_env(), timeout=60)
        assert bad.returncode == 2 and not (tmp_path / "x").exists(), face


def test_an_input_inside_the_output_folder_is_refused_with_a_message(binary, files, tmp_path):
    for face in ("python", "rust"):
        out = tmp_path / face
        out.mkdir()
        (out / "x.png").write_bytes((files / "f0.png").read_bytes())
        r = _run(face, binary, [str(out / "x.png"), "-o", str(out)], tmp_path)
        assert r.returncode == CONTRACT["unreadable_input"], (face, r.returncode, r.stderr)
        assert "inside the output folder" in r.stderr, (face, r.stderr)
        assert _listing(out) == ["x.png"], face


def test_stream_refuses_a_fifo_line_and_goes_on(binary, files, tmp_path):
    lines = f"{files / 'fifo.jpg'}\n{files / 'f1.png'}\n"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(tmp_path / "o"), "--format", "png"], input=lines,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    objs = [json.loads(x) for x in r.stdout.splitlines() if x.strip()]
    assert objs[0]["error"] == "unreadable_input" and "FIFO" in objs[0]["message"], objs[0]
    assert objs[1]["water_type"] and os.path.exists(tmp_path / "o" / "f1.json")


def test_long_file_names_fit_their_temporaries(binary, files, tmp_path):
    """An input stem of 240 bytes: NAME_confidence.png is 255 bytes, the
    most a name may have; the temporary names are short in both commands."""
    src = tmp_path / ("n" * 240 + ".png")
    src.write_bytes((files / "f2.png").read_bytes())
    for face in ("python", "rust"):
        out = tmp_path / face
        r = _run(face, binary, [str(src), "-o", str(out), "--format", "png"], tmp_path)
        assert r.returncode == 0, (face, r.stderr)
        assert len(_listing(out)) == 5 and not [f for f in os.listdir(out) if f.startswith(".")], face


def test_stream_stops_when_its_output_is_gone(binary, files, tmp_path):
    """stdout on a full disk: uwhl-rs --stream stops with exit 5 and a
    message, instead of restoring every frame while its lines are lost."""
    src = tmp_path / "frames"
    src.mkdir()
    for k in range(12):
        os.link(files / f"f{k % 3}.png", src / f"m{k:02d}.png")
    lines = "".join(f"{src / f'm{k:02d}.png'}\n" for k in range(12))
    out = tmp_path / "o"
    with open("/dev/full", "w") as full:
        r = subprocess.run([binary, "restore", "--stream", "-o", str(out), "--format", "png", "--max-side", "40"],
                           input=lines, stdout=full, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == CONTRACT["write_failed"], r.stderr
    assert "cannot write the frame lines to stdout" in r.stderr
    done = [f for f in os.listdir(out) if f.endswith(".json")] if out.exists() else []
    assert len(done) <= 3, done  # the frame in flight and the one read ahead at most


def test_a_rerun_removes_the_temporaries_a_killed_run_left(binary, files, tmp_path):
    """Temporaries of a dead process (a pid above the kernel's largest) go
    at the start of a run; those of a live one (this test) stay."""
    for face in ("python", "rust"):
        out = tmp_path / face
        out.mkdir()
        dead = [out / ".uwhl-4194399-3.tmp", out / ".uwhl-4194399-x1y2z3.tmp.png"]
        live = out / f".uwhl-{os.getpid()}-0.tmp"
        for p in dead + [live]:
            p.write_bytes(b"left behind")
        r = _run(face, binary, [str(files / "f0.png"), "-o", str(out), "--format", "png"], tmp_path)
        assert r.returncode == 0, (face, r.stderr)
        assert not any(p.exists() for p in dead) and live.exists(), (face, sorted(os.listdir(out)))


def _summary_counts(stdout: str) -> tuple[int, int, int]:
    import re

    m = re.search(r"(\d+) done, (\d+) skipped, (\d+) failed", stdout)
    assert m, stdout
    return tuple(int(g) for g in m.groups())


def _limited(fsize: int):
    """A child whose files cannot grow past ``fsize`` bytes (a disk that
    fills mid-input): writes past it fail with EFBIG instead of SIGXFSZ."""
    import resource

    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
    return pre


def test_overwrite_on_a_full_disk_keeps_the_earlier_outputs(binary, files, tmp_path):
    """Item 1 of issue 20: an --overwrite whose later output cannot be
    written leaves the earlier run's outputs and sidecar whole (the image
    is not removed under a sidecar that still lists it), and a rerun
    without --overwrite skips an input that is complete."""
    for face in ("python", "rust"):
        out = tmp_path / face
        args = [str(files / "f1.png"), "-o", str(out), "--format", "jpg", "--quality", "5"]
        assert _run(face, binary, args, tmp_path).returncode == 0
        before = {f: (out / f).read_bytes() for f in _listing(out)}
        sizes = {f: len(b) for f, b in before.items()}
        # the image (written first) fits, the transmission (written next) does not
        limit = sizes["f1.jpg"] + 16
        assert sizes["f1_t.png"] > limit, sizes
        r = subprocess.run(_cmd(face, binary, [*args, "--overwrite"]), capture_output=True, text=True, timeout=120,
                           env=_env(), cwd=tmp_path, preexec_fn=_limited(limit), restore_signals=False)
        assert r.returncode == CONTRACT["write_failed"], (face, r.returncode, r.stderr)
        assert "f1_t.png" in r.stderr or "File too large" in r.stderr, (face, r.stderr)
        after = {f: (out / f).read_bytes() for f in _listing(out)}
        assert after == before, (face, sorted(after))  # nothing half-replaced, no temporary left
        side = json.loads(after["f1.json"])
        assert all((out / f).exists() for f in side["outputs"].values()), face
        r = _run(face, binary, args, tmp_path)
        assert r.returncode == 0 and "skipped" in r.stdout + r.stderr, (face, r.stdout, r.stderr)


def test_stream_frames_with_one_name_keep_both(binary, files, tmp_path):
    """Item 2: camA/frame.png and camB/frame.png on consecutive lines: camB's
    outputs go under frame_2, camA's are kept; the same path on two
    consecutive lines is restored once."""
    for cam, k in (("camA", 0), ("camB", 1)):
        (tmp_path / cam).mkdir()
        os.link(files / f"f{k}.png", tmp_path / cam / "frame.png")
    a, b = tmp_path / "camA" / "frame.png", tmp_path / "camB" / "frame.png"
    out = tmp_path / "o"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(out), "--format", "png"],
                       input=f"{a}\n{a}\n{b}\n", capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    objs = [json.loads(x) for x in r.stdout.splitlines() if x.strip()]
    assert len(objs) == 3 and "skipped" in objs[1], objs
    assert json.load(open(out / "frame.json"))["input"] == str(a)
    assert json.load(open(out / "frame_2.json"))["input"] == str(b)
    assert objs[2]["outputs"]["image"] == "frame_2.png"
    # camA's restoration is still the one under frame.png
    assert sorted(f for f in os.listdir(out)) == ["frame.json", "frame.png", "frame_2.json", "frame_2.png",
                                                   "frame_2_confidence.png", "frame_2_t.png", "frame_2_t_color.png",
                                                   "frame_confidence.png", "frame_t.png", "frame_t_color.png"]
    # a rerun of the same lines does nothing more
    r = subprocess.run([binary, "restore", "--stream", "-o", str(out), "--format", "png"],
                       input=f"{a}\n{b}\n", capture_output=True, text=True, timeout=120)
    assert [json.loads(x).get("skipped") for x in r.stdout.splitlines()] == ["sidecar exists"] * 2, r.stdout


def test_output_names_of_different_roles_never_collide(binary, files, tmp_path):
    """Item 3: inputs a.png and a_t.png written as PNG (a_t.png is a's
    transmission) get distinct names, the same in both commands; a file
    already in the output folder under an output's name is kept."""
    src = tmp_path / "in"
    src.mkdir()
    os.link(files / "f0.png", src / "a.png")
    os.link(files / "f1.png", src / "a_t.png")
    os.link(files / "f2.png", src / "x.png")
    got = {}
    for face in ("python", "rust"):
        out = tmp_path / face
        out.mkdir()
        (out / "x_t.png").write_bytes(b"someone's own file")
        r = _run(face, binary, [str(src), "-o", str(out), "--format", "png"], tmp_path)
        assert r.returncode == 0, (face, r.stderr)
        sides = {f: json.load(open(out / f)) for f in os.listdir(out) if f.endswith(".json")}
        got[face] = {f: (os.path.basename(s["input"]), s["outputs"]) for f, s in sides.items()}
        assert (out / "x_t.png").read_bytes() == b"someone's own file", face
        # every file a sidecar lists is that input's: no two sidecars share one
        listed = [v for s in sides.values() for v in s["outputs"].values()]
        assert len(listed) == len(set(listed)), (face, listed)
    assert got["python"] == got["rust"]
    names = {inp: f for f, (inp, _) in got["rust"].items()}
    assert names == {"a.png": "a.json", "a_t.png": "a_t_2.json", "x.png": "x_2.json"}, names


def test_two_processes_on_one_folder_restore_each_input_once(binary, files, tmp_path):
    """Item 11: two runs on the same output folder at once (one of each
    command) share the inputs: each is restored by one of them, the other
    skips it (done, or being restored by the other)."""
    src = tmp_path / "in"
    src.mkdir()
    img, _ = synth.demo_input(240, 320, water_type="3C", seed=5)
    uwhl_rs.images.write_image(src / "base.png", img, bits=8, encoding="linear")
    for k in range(8):
        os.link(src / "base.png", src / f"p{k}.png")
    (src / "base.png").unlink()
    out = tmp_path / "out"
    args = [str(src), "-o", str(out), "--format", "png"]
    procs = [subprocess.Popen(_cmd(face, binary, args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=_env(), cwd=tmp_path) for face in ("rust", "python")]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    counts = [_summary_counts(o) for o, _ in outs]
    assert sum(c[0] for c in counts) == 8 and sum(c[1] for c in counts) == 8, (counts, outs)
    sides = [json.load(open(out / f"p{k}.json")) for k in range(8)]
    assert sorted(os.path.basename(s["input"]) for s in sides) == [f"p{k}.png" for k in range(8)]
    assert not [f for f in os.listdir(out) if f.startswith(".")], os.listdir(out)


def _big_png(path, h: int, w: int) -> None:
    """A PNG of h x w RGB pixels, every row the same ramp (so the image is
    not constant, which the core would refuse before allocating), written
    row by row: small on disk whatever its size, never held in memory whole."""
    import struct
    import zlib

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    z = zlib.compressobj(9)
    row = b"\x00" + (bytes(range(256)) * (3 * w // 256 + 1))[: 3 * w]
    body = b"".join(z.compress(row) for _ in range(h)) + z.flush()
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", body) + chunk(b"IEND", b""))


def _address_space(limit: int):
    import resource

    def pre():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return pre


def test_memory_the_system_will_not_give_fails_one_input_not_the_process(binary, files, tmp_path):
    """Item 6: a 12000 x 12000 PNG under `ulimit -v` 3 GB: refused with exit
    4 (by the default budget, which follows the limit, and, with a budget
    set above it, by the allocation probe) while the next input is
    restored; the stream goes on to the next frame."""
    big = tmp_path / "big.png"
    _big_png(big, 12000, 12000)
    assert big.stat().st_size < 4 << 20
    limit = 3 << 30
    for face in ("python", "rust"):
        for extra, why in (([], "over --max-memory"), (["--max-memory", "60G"], "system gives")):
            out = tmp_path / f"{face}{len(extra)}"
            r = subprocess.run(_cmd(face, binary, [str(big), str(files / "f0.png"), "-o", str(out), "--format", "png",
                                                   *extra]), capture_output=True, text=True, timeout=120,
                               env=_env(), cwd=tmp_path, preexec_fn=_address_space(limit))
            assert r.returncode == CONTRACT["over_budget"], (face, extra, r.returncode, r.stderr[-2000:])
            import re

            assert re.search(why, r.stderr), (face, extra, r.stderr)
            assert _listing(out) == ["f0.json", "f0.png", "f0_confidence.png", "f0_t.png", "f0_t_color.png"], (face, extra)
    r = subprocess.run([binary, "restore", "--stream", "-o", str(tmp_path / "s"), "--format", "png", "--max-memory",
                        "60G"], input=f"{big}\n{files / 'f1.png'}\n", capture_output=True, text=True, timeout=120,
                       preexec_fn=_address_space(limit))
    objs = [json.loads(x) for x in r.stdout.splitlines() if x.strip()]
    assert r.returncode == 0 and len(objs) == 2, (r.returncode, r.stderr)
    assert objs[0]["error"] == "over_budget" and objs[1]["water_type"], objs


# Runs argv[1:] and prints its peak resident bytes. A child's peak counts
# the pages of the process it was forked from until it execs, so the
# command is started from this small launcher and not from pytest.
_LAUNCHER = """
import os, sys
pid = os.posix_spawn(sys.argv[1], sys.argv[1:], os.environ)
_, status, usage = os.wait4(pid, 0)
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024)
"""


def _peak_rss(cmd: list[str], stdin: str | None = None) -> tuple[int, int, str]:
    """Runs cmd; returns its exit code, its peak resident bytes (the
    kernel's count) and its stderr."""
    r = subprocess.run([sys.executable, "-c", _LAUNCHER, *cmd], input=stdin, capture_output=True, text=True,
                       timeout=300, env=_env())
    code, peak = r.stdout.split()[-2:]
    return int(code), int(peak), r.stderr


def test_peak_memory_stays_under_max_memory(binary, tmp_path):
    """Item 7: at the tightest budget a command accepts (the need it reports
    when refusing, plus the margin that absorbs run-to-run changes of the
    process's own size), the peak resident memory of the whole process,
    measured by the kernel, stays under --max-memory: one input, and a
    stream of 6 frames (binary)."""
    import re

    src = tmp_path / "in"
    src.mkdir()
    for k in range(6):
        img, _ = synth.demo_input(480, 640, water_type="3C", seed=k)
        uwhl_rs.images.write_image(src / f"m{k}.png", img, bits=8, encoding="linear")
    margin = {"rust": 1 << 20, "python": 4 << 20}
    for face in ("rust", "python"):
        args = [str(src / "m0.png"), "-o", str(tmp_path / face), "--format", "png", "--overwrite"]
        code, _, err = _peak_rss(_cmd(face, binary, [*args, "--max-memory", "1M"]))
        assert code == CONTRACT["over_budget"], err
        budget = int(re.search(r"need about (\d+) bytes", err).group(1)) + margin[face]
        code, peak, err = _peak_rss(_cmd(face, binary, [*args, "--max-memory", str(budget)]))
        assert code == 0, (face, err)
        assert peak <= budget, (face, peak, budget)
    lines = "".join(f"{src / f'm{k}.png'}\n" for k in range(6))
    code, _, err = _peak_rss([binary, "restore", "--stream", "-o", str(tmp_path / "s"), "--max-memory", "1M"], lines)
    assert code == 0, err
    budget = int(re.search(r"need about (\d+) bytes", err).group(1)) + margin["rust"]
    code, peak, err = _peak_rss([binary, "restore", "--stream", "-o", str(tmp_path / "s"), "--max-memory",
                                 str(budget)], lines)
    assert code == 0 and len(os.listdir(tmp_path / "s")) == 30, err
    assert peak <= budget, (peak, budget)


def test_a_cmyk_tiff_is_read_as_its_colors_in_both(binary, tmp_path):
    """Item 4: a CMYK TIFF (photometric "separated") is converted to RGB by
    the Python command as by uwhl-rs: pure cyan, magenta, yellow and black
    inks decode to their RGB colours, and both commands write the same
    restoration."""
    import tifffile

    rng = np.random.default_rng(3)
    cmyk = rng.integers(0, 256, size=(48, 64, 4), dtype=np.uint8)
    cmyk[:4, :4] = [0, 255, 255, 0]  # red
    cmyk[:4, 4:8] = [255, 0, 255, 0]  # green
    cmyk[:4, 8:12] = [0, 0, 0, 255]  # black
    path = tmp_path / "cmyk.tif"
    tifffile.imwrite(path, cmyk, photometric="separated")
    img, meta = uwhl_rs.images.read_image(path, preprocess="reference")  # codes / 255, no curve
    assert np.allclose(img[0, 0], [1, 0, 0]) and np.allclose(img[0, 5], [0, 1, 0]) and np.allclose(img[0, 9], 0)
    got = {}
    for face in ("python", "rust"):
        out = tmp_path / face
        r = _run(face, binary, [str(path), "-o", str(out), "--format", "png"], tmp_path)
        assert r.returncode == 0, (face, r.stderr)
        got[face] = (out / "cmyk.png").read_bytes()
    assert got["python"] == got["rust"]


def test_non_utf8_names_are_named_alike_by_both(binary, files, tmp_path):
    """Item 13: a file name that is not UTF-8 gets the same output names
    from both commands (U+FFFD for the byte that is not), and two such names
    that differ only there do not collide."""
    src = os.path.join(os.fsencode(tmp_path), b"in")
    os.mkdir(src)
    for b, k in ((b"caf\xe9.png", 0), (b"caf\xe8.png", 1)):
        os.link(files / f"f{k}.png", os.path.join(src, b))
    names = {}
    for face in ("python", "rust"):
        out = tmp_path / face
        r = subprocess.run(_cmd(face, binary, [os.fsdecode(src), "-o", str(out), "--format", "png"]),
                           capture_output=True, timeout=120, env=_env(), cwd=tmp_path)
        assert r.returncode == 0, (face, r.stderr)
        names[face] = sorted(f for f in os.listdir(os.fsencode(out)) if f != b"summary.csv")
    assert names["python"] == names["rust"] and len(names["rust"]) == 10, names
    _same_summaries(_summary_rows(tmp_path / "python"), _summary_rows(tmp_path / "rust"))


def test_a_name_with_control_characters_is_printed_escaped_by_both(binary, files, tmp_path):
    """A file name that holds an escape sequence and a newline cannot recolour
    the terminal or forge a line: both commands write its control characters
    as \\xNN, in the progress line and in the error line; a line separator
    and a right-to-left override (which makes the rest of a name read
    backwards, hiding its real extension) as \\uNNNN."""
    d = tmp_path / "in"
    d.mkdir()
    name = "red\x1b[31m\nfake.png"
    (d / name).write_bytes((files / "f0.png").read_bytes())
    (d / "x\u202egnp.exe\u2028y.png").write_bytes((files / "f0.png").read_bytes())
    (d / "bad\x07.jpg").write_bytes(b"not a jpeg at all")
    for face in ("python", "rust"):
        r = _run(face, binary, [str(d), "-o", str(tmp_path / face)], tmp_path)
        text = r.stdout + r.stderr
        assert r.returncode == 3, text
        assert "\x1b" not in text and "\x07" not in text, face
        assert "red\\x1b[31m\\x0afake.png -> " in text and "bad\\x07.jpg: " in text, (face, text)
        assert "\u202e" not in text and "\u2028" not in text, face
        assert "x\\u202egnp.exe\\u2028y.png -> " in text, (face, text)


@pytest.mark.parametrize("bad, code", [("trunc", 2), ("huge", 4)])
def test_a_mask_that_cannot_be_read_is_one_error_before_any_input(binary, tmp_path, bad, code):
    """docs/CLI.md: --mask is read once, before any input: a truncated mask
    (exit 2) or one over --max-pixels (exit 4) is one line naming it in both
    commands, and no output folder is made."""
    from PIL import Image

    from bothcmds import cmds, run_restore
    from uwhl_rs import images

    img, _ = synth.demo_input(40, 56, water_type="3C", seed=1)
    for k in (1, 2):
        images.write_image(tmp_path / f"p{k}.png", img, bits=8, encoding="linear")
    mask = tmp_path / "mask.png"
    if bad == "trunc":
        Image.new("L", (56, 40), 255).save(mask)
        mask.write_bytes(mask.read_bytes()[:60])
    else:
        Image.new("L", (200, 200), 255).save(mask)
    for face, cmd in cmds(binary).items():
        out = tmp_path / f"out_{face}"
        r = run_restore(cmd, tmp_path / "p1.png", tmp_path / "p2.png", "-o", out, "--mask", mask,
                        "--max-pixels", "10000")
        assert r.returncode == code, (face, r.stderr)
        lines = [x for x in r.stderr.splitlines() if x.startswith(("uwhl:", "uwhl-rs:"))]
        assert len(lines) == 1 and f"--mask {mask}" in lines[0], (face, r.stderr)
        assert not out.exists(), face


@pytest.mark.parametrize("value, said", [
    ("", "no type named"), (",,", "no type named"), ("X:1:2:3", "a custom type is NAME:BETA_BR:BETA_BG"),
    ("X:\uff11:2", "a custom type is"), ("X:1_0:2", "a custom type is"), ("III,III", "is listed twice"),
    ("bogus", "unknown water type"),
])
def test_water_type_values_are_parsed_alike(binary, tmp_path, value, said):
    """--water-type is read by one parser in both commands: an empty list,
    a fourth field, digits Rust does not read (a full-width one, 1_0), a
    type twice or an unknown name are one usage error (exit 2), the same
    words, before any input."""
    from bothcmds import cmds, run_restore
    from uwhl_rs import images

    img, _ = synth.demo_input(40, 56, water_type="3C", seed=1)
    images.write_image(tmp_path / "p.png", img, bits=8, encoding="linear")
    lines = {}
    for face, cmd in cmds(binary).items():
        r = run_restore(cmd, tmp_path / "p.png", "-o", tmp_path / face, "--water-type", value)
        assert r.returncode == 2 and not (tmp_path / face).exists(), (face, r.stderr)
        lines[face] = r.stderr.splitlines()[0].split(": ", 1)[1]
        assert said in lines[face], (face, r.stderr)
    assert lines["python"] == lines["rust"]
