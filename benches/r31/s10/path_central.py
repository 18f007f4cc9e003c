"""The light-path display (§12.8, `../exp_path.py`) on the central type
choice of today's core, against the harness's default display."""
import sys, os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import exp
from exp_path import make
cands = {"default (harness)": make('sog', False), "default, path p4": make('path:4', False)}
exp.run(cands, split=sys.argv[1], every=int(sys.argv[2]), out=f"/tmp/s10/path_{sys.argv[1]}.json")
