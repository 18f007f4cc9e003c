"""The sidecar's `parameters` record what was asked, the same in both
commands: `max_memory` is "auto" unless given (the default follows the
machine's free memory, so a sidecar that recorded it would differ from run
to run and machine to machine), with the budget used beside it."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

import uwhl_rs
from uwhl_rs import _core, images, synth


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


@pytest.mark.parametrize("face", ["python", "rust"])
@pytest.mark.parametrize("asked", [None, "900M"])
def test_max_memory_is_recorded_as_asked(binary, tmp_path, face, asked):
    img, _ = synth.demo_input(50, 70, seed=4)
    images.write_image(tmp_path / "x.png", img, encoding="linear")
    cmd = [sys.executable, "-m", "uwhl_rs", "restore"] if face == "python" else [binary, "restore"]
    extra = [] if asked is None else ["--max-memory", asked]
    r = subprocess.run([*cmd, str(tmp_path / "x.png"), "-o", str(tmp_path / "o"), "-q", *extra],
                       capture_output=True, text=True, timeout=300, env=_env())
    assert r.returncode == 0, r.stderr
    p = json.loads((tmp_path / "o" / "x.json").read_text())["parameters"]
    if asked is None:
        assert p["max_memory"] == "auto"
        assert isinstance(p["max_memory_used"], int) and p["max_memory_used"] > 0
    else:
        assert p["max_memory"] == p["max_memory_used"] == 900 << 20
    # every method option of the table is recorded, and nothing is recorded twice
    assert {o["key"] for o in _core.OPTIONS if o["method"]} <= set(p)
