"""Programs some tests drive (a browser, FFmpeg): found on PATH, or
installed from Debian's packages when missing (CI runs as root), and a
failure when they cannot be: such a test never passes silently without
them."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest


def installed(command: str, package: str, *names: str) -> str:
    """The path of ``command`` (or of one of ``names``), installing Debian's
    ``package`` with apt-get when none is on PATH."""
    for name in (command, *names):
        path = shutil.which(name)
        if path:
            return path
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for step in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "--no-install-recommends", package]):
        r = subprocess.run(step, capture_output=True, text=True, env=env, timeout=900)
        if r.returncode != 0:
            pytest.fail(f"cannot install {package} for this test ({' '.join(step)}): {r.stderr[-800:]}")
    path = shutil.which(command)
    if not path:
        pytest.fail(f"apt-get installed {package} but {command} is not on PATH")
    return path
