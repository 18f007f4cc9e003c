"""Hostile inputs of the ninth pass, Python side: a video's outputs on a
full disk (a failed write, exit 5, naming the output and not its
temporary), the command's messages naming options by their flags as
uwhl-rs does, empty and foreign files given as videos, unknown
single-dash options, integer distance arrays in the API (metres or
millimetres?), numbers too large for the API's parameters, and the API's
shapes, dtypes and water-type names that ``restore`` and
``depth_to_range`` took differently.

Each case says what must happen independently of the code: the exit
code and error kind of docs/CLI.md, the flag's spelling of the binary,
the package's ParameterError with a message naming the parameter."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys

import numpy as np
import pytest

PYTHON_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "python")


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = PYTHON_DIR + os.pathsep + env.get("PYTHONPATH", "")
    # a file size limit would cut the interpreter's own .pyc files short
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def uwhl(*args, cwd=None, preexec_fn=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          env=_env(), cwd=cwd, preexec_fn=preexec_fn, timeout=timeout)


def _file_size_limit(limit: int):
    """A child whose files cannot grow past ``limit`` bytes: a write past it
    fails with EFBIG, as on a full disk with ENOSPC (SIGXFSZ ignored, so the
    write fails instead of the process being killed)."""

    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return pre


def _video(path, n=24, h=48, w=64):
    from test_hostile_video import _write

    _write(path, n=n, codec="ffv1", pix="bgr0", h=h, w=w)


def _error(stderr: str) -> dict:
    lines = [json.loads(x) for x in stderr.splitlines() if x.startswith("{")]
    assert len(lines) == 1, stderr
    return lines[0]


# ------------------------------------------------------------------ 1. a full disk while writing a video


@pytest.mark.parametrize("extra", [[], ["--every", "6", "--format", "png", "--bits", "16"]],
                         ids=["video", "stills"])
def test_a_video_that_cannot_be_written_is_a_failed_write_naming_its_output(tmp_path, extra):
    """The restored video (24 lossless frames, some 100 KB) and a 16-bit
    still (18 KB) cannot be written under a 10 KB file size limit. That is
    a failed write (exit 5, write_failed) naming the output, as for a
    photo; it used to be an unreadable input (exit 3) naming the
    temporary ``.uwhl-PID-0.tmp.mp4``."""
    pytest.importorskip("av")
    src = tmp_path / "clip.mkv"
    _video(src)
    out = tmp_path / "out"
    r = uwhl("restore", src, "-o", out, "--video-codec", "ffv1", "--json-errors", "-q", *extra,
             preexec_fn=_file_size_limit(10_000))
    assert r.returncode == 5, r.stderr
    e = _error(r.stderr)
    assert e["error"] == "write_failed" and e["exit_code"] == 5, e
    assert ".uwhl-" not in e["message"] and ".tmp" not in e["message"], e
    assert e["message"].startswith(f"cannot write {out}{os.sep}clip"), e
    assert "File too large" in e["message"], e
    # nothing of the video is left but the summary
    assert sorted(os.listdir(out)) == ["summary.csv"]


def test_the_encoder_closing_on_a_full_disk_is_a_failed_write():
    """The container's trailer, written when it is closed, is where a full
    disk showed first; its error was raised from a ``finally`` outside the
    handler. A container whose close fails with ENOSPC now gives
    write_failed naming the output; abandoning the video after another
    error keeps that error (the close's own is dropped)."""
    import errno

    av = pytest.importorskip("av")
    from uwhl_rs.errors import CommandError, kind_of
    from uwhl_rs.videoencode import Writer

    class Full:
        closed = 0

        def mux(self, packet):
            pass

        def close(self):
            Full.closed += 1
            raise av.error.OSError(errno.ENOSPC, "No space left on device", "/out/.uwhl-1-0.tmp.mp4")

    class Encoder:
        def encode(self, frame=None):
            return []

    w = Writer.__new__(Writer)
    w.av, w.out, w.video, w.shown = av, Full(), Encoder(), "/out/dive.mp4"
    with pytest.raises(CommandError) as got:
        w.close()
    assert kind_of(got.value) == "write_failed"
    assert str(got.value) == "cannot write /out/dive.mp4: No space left on device (os error 28)"
    w.out = Full()
    w.close(flush=False)  # no error of its own
    assert Full.closed == 2
