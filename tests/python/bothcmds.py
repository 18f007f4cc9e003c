"""The two commands a parity test drives (`uwhl` of the package and the
`uwhl-rs` binary), one restore run of either, and a sidecar read back."""

import json
import subprocess
import sys


def cmds(binary):
    """The command line of each face: ``python`` and ``rust``."""
    return {"python": [sys.executable, "-m", "uwhl_rs"], "rust": [binary]}


def run_restore(cmd, *args):
    """``cmd restore ARGS -q``, its output captured."""
    return subprocess.run([*cmd, "restore", *map(str, args), "-q"], capture_output=True, text=True, timeout=300)


def sidecar(out, name):
    """The sidecar ``OUT/NAME.json`` as a dict."""
    return json.loads((out / f"{name}.json").read_text())
