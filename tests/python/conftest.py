import json
import os
import shutil
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="session")
def binary():
    """The ``uwhl-rs`` executable: built with ``cargo build --profile test
    --features cli,internals``, which reuses what ``cargo test --features
    cli,internals`` (the CI command) compiled; ``UWHL_RS_BIN`` points the tests at another build."""
    path = os.environ.get("UWHL_RS_BIN")
    if path:
        return path
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("cargo is not installed: cannot build the uwhl-rs binary")
    r = subprocess.run(
        [cargo, "build", "--profile", "test", "--features", "cli,internals", "--bin", "uwhl-rs",
         "--message-format=json-render-diagnostics"],
        cwd=ROOT, capture_output=True, text=True, timeout=1800,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    for line in r.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg.get("executable") and \
                msg["target"]["name"] == "uwhl-rs":
            return msg["executable"]
    pytest.fail("cargo built no uwhl-rs executable")
