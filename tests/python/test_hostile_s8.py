"""Hostile inputs found in the passes of 2026-12-05: what stream mode says
about lines that cannot be names, CSV cells a spreadsheet would run, and
values that are not numbers in the images written."""

import json
import subprocess

import pytest


def test_a_stream_line_that_cannot_be_a_name_is_identified(binary, tmp_path):
    """Its error object used to have ``"input": null``: a reader could not
    tell which of its lines failed. Now the line as it can be shown (one
    U+FFFD a byte, cut after 256 characters) and its number."""
    data = b"\xff\xfe.jpg\n\n" + b"a" * 70000 + b"\nmissing.jpg\n"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(tmp_path / "o")], input=data,
                       capture_output=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert len(lines) == 3, lines
    bad, long, missing = lines
    assert bad["error"] == "unreadable_input" and bad["input"] == "\ufffd\ufffd.jpg"
    assert "line 1 " in bad["message"] and "UTF-8" in bad["message"]
    # the empty line 2 is not a frame, but it is counted
    assert long["input"] == "a" * 256 + "..." and "line 3 " in long["message"]
    assert "65536" in long["message"]
    assert missing["input"] == "missing.jpg"
