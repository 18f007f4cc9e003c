"""The entropy's type (benches/r31/s14, rule ent3->sog) guarded by the
model's own evidence: the veil excess N0 of METHOD §12.5 step 2 (the share
of object pixels the estimated veil over-explains). A type change is
taken only when it does not raise N0 by more than a margin over §12.2's
type. Per render of a split: both types' N0 and fallback share, beside
the angles of the s14 cache (same order as truth.scenes).

    PYTHONPATH=python python3 benches/r31/s16/guard.py SPLIT CACHE.json OUT.json
"""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import rules as R  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402

split, cache, out = sys.argv[1], sys.argv[2], sys.argv[3]
rows = json.load(open(cache))
got = []
for i, (r, c) in enumerate(zip(T.scenes(split), rows)):
    assert r.name == c["name"], (r.name, c["name"])
    k = R.r_ent3_sog(c)
    d = uwhl_rs.restore(r.image)
    assert d.water_type == c["chosen"], (d.water_type, c["chosen"])
    e = d if k == d.water_type else uwhl_rs.restore(r.image, water_types=[k])
    got.append({"name": c["name"], "k": k, "n0_default": d.veil_excess, "n0_k": e.veil_excess,
                "fb_default": d.fallback_share, "fb_k": e.fallback_share})
    if i % 20 == 0:
        print(i, r.name, file=sys.stderr)
json.dump(got, open(out, "w"))
