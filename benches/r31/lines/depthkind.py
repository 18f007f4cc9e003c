"""A depth map along the axis read as ranges, against the same map turned
into ranges (METHOD §13.7, "Depth along the axis"): held renders of
benches/truth.py with a 70-degree lens behind a flat port assumed for the
map; median angle to the truth per condition."""
import sys
import numpy as np
sys.path.insert(0, '../..')
import truth as T
import uwhl_rs
from uwhl_rs import truth as TR

split = sys.argv[1] if len(sys.argv) > 1 else 'held'
fov = float(sys.argv[2]) if len(sys.argv) > 2 else 70.0
rows = {}
for r in T.scenes(split, 360):
    z = np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
    ones = np.ones_like(z)
    cos = ones / uwhl_rs.depth_to_range(ones, fov, port="flat")
    depth = z * cos
    cell = rows.setdefault(f'{r.stats}/{r.light}', {'range': [], 'depth read as range': [], 'depth turned into range': []})
    for key, zz in (('range', z), ('depth read as range', depth), ('depth turned into range', uwhl_rs.depth_to_range(depth, fov, port="flat"))):
        res = uwhl_rs.restore(r.image, distance=zz)
        cell[key].append(TR.score(res.image, r.truth, r.objects, gains=False)['median'])
        bt = np.array([T.BETA_B[r.water_type] / T.synth.JERLOV[r.water_type][0],
                       T.BETA_B[r.water_type] / T.synth.JERLOV[r.water_type][1], T.BETA_B[r.water_type]])
        err = np.inf if res.water is None else float(np.max(np.abs(np.array(res.water['beta']) / bt - 1)))
        cell.setdefault(key + ' beta', []).append(err)
conds = [f'{s}/{l}' for s, l in T.CONDITIONS]
print(f'{split}, a {fov:g}-degree lens behind a flat port; median angle (deg)')
for key in [k for k in rows[conds[0]] if not k.endswith(' beta')]:
    print(f'{key:26s}', ' '.join(f'{np.median(rows[c][key]):6.2f}' for c in conds),
          ' beta median error', ' '.join(f'{np.median(rows[c][key + " beta"]):.2f}' for c in conds))
