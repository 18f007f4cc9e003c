"""The type stubs python/uwhl_rs/_core.pyi against the built extension:
mypy's stubtest compares every name, signature, default, property and
class of the stub with the module as imported, so a function added to the
Rust bindings without its stub (or with a different signature) fails here.

The extension of the tests is built with the Cargo feature ``internals``,
which adds the ``_stage_*`` entry points; the stub declares them. Against a
build without them (a release wheel) the test tells stubtest that the
module's ``__all__`` lacks them.
"""
import os
import re
import subprocess
import sys

import uwhl_rs
from uwhl_rs import _core

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PACKAGE = os.path.dirname(uwhl_rs.__file__)
STUB = os.path.join(PACKAGE, "_core.pyi")

#: stubtest allowlist for a build without the ``internals`` feature. stubtest
#: passes a private stub function the module lacks, so the ``_stage_*`` stubs
#: need no entry; the stub's ``__all__`` lists them, the module's does not.
NO_INTERNALS = """\
# lists the _stage_* names, built only with the internals feature
uwhl_rs\\._core\\.__all__
"""


def _stubtest(tmp_path, mypy_path=None):
    """Runs ``python -m mypy.stubtest uwhl_rs._core`` on the imported
    package (the stub from ``mypy_path`` first, when given); (returncode, output)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(PACKAGE)] + [p for p in [env.get("PYTHONPATH")] if p])
    if mypy_path:
        env["MYPYPATH"] = mypy_path
    else:
        env.pop("MYPYPATH", None)
    cmd = [sys.executable, "-m", "mypy.stubtest", "uwhl_rs._core"]
    if not hasattr(_core, "_stage_stretch"):
        allow = tmp_path / "no_internals.txt"
        allow.write_text(NO_INTERNALS)
        cmd += ["--allowlist", str(allow)]
    # in its own folder: mypy's cache and any mypy.ini of the caller stay out
    work = tmp_path / "work"
    work.mkdir(exist_ok=True)
    r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=600)
    return r.returncode, r.stdout + r.stderr


def test_stub_matches_the_built_module(tmp_path):
    assert os.path.realpath(_core.__file__).startswith(os.path.realpath(PACKAGE)), _core.__file__
    rc, out = _stubtest(tmp_path)
    assert rc == 0, out
    assert "Success: no issues found in 1 module" in out, out


def test_stubtest_fails_when_a_function_lacks_its_stub(tmp_path):
    """The check has teeth: the same stub without ``_colormap`` (a function
    the package calls) is reported, by name, as missing."""
    stub = open(STUB).read()
    cut, n = re.subn(r"^def _colormap\(.*?\n(?=\S)", "", stub, count=1, flags=re.M | re.S)
    assert n == 1 and "def _colormap" not in cut
    shadow = tmp_path / "stubs" / "uwhl_rs"
    shadow.mkdir(parents=True)
    (shadow / "__init__.pyi").write_text("")
    (shadow / "_core.pyi").write_text(cut)
    rc, out = _stubtest(tmp_path, mypy_path=str(tmp_path / "stubs"))
    assert rc != 0, out
    assert "uwhl_rs._core._colormap is not present in stub" in out, out
