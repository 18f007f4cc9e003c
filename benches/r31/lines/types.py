import numpy as np, glob, sys, json
import uwhl_rs
TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
out = []
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); I = d['image']; meta = [str(x) for x in d['meta']]
    r = uwhl_rs.restore(I)
    ve = {}
    for t in TYPES:
        ve[t] = uwhl_rs.restore(I, water_types=[t]).veil_excess
    out.append({'split': split, 'name': meta[0], 'cond': meta[1], 'true': meta[2], 'chosen': meta[3], 'scores': r.scores, 've': ve})
    print(meta[0], flush=True)
json.dump(out, open('out/types.json', 'w'))
