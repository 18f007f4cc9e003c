import numpy as np, glob, sys
sys.path.insert(0,'..')
from clines import estimate
import harness as H
TYPES = H.TYPES
split = sys.argv[1]; step = int(sys.argv[2]) if len(sys.argv) > 2 else 3
res = {}
for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::step]:
    d = np.load(f); wt = str(d['meta'][2]); I = d['image']; cond = str(d['meta'][1])
    sigma = H.noise_sigma(I); obj = np.isfinite(d['dist'])
    for aname in ['atrue', 'aest']:
        a = np.asarray(d['atrue'] if aname == 'atrue' else d['a'], float)
        sc = {}
        for t in TYPES:
            r = estimate(I, a, t, sigma)
            cand = (~r['clipped']) & (r['spread'] > 6 * sigma.mean()) & (r['line'] < 0.05)
            rel = r['emin'][cand] / r['spread'][cand]
            sc[t] = (np.median(rel), np.mean(rel < 0.1), cand.sum())
        for k, name in [(0, 'med'), (1, 'frac')]:
            pick = min(TYPES, key=lambda t: sc[t][0]) if k == 0 else max(TYPES, key=lambda t: sc[t][1])
            steps = abs(TYPES.index(pick) - TYPES.index(wt))
            res.setdefault((aname, name, cond), []).append(steps)
        print(str(d['meta'][0])[:38], aname, wt, 'med->', min(TYPES, key=lambda t: sc[t][0]), 'frac->', max(TYPES, key=lambda t: sc[t][1]),
              ' '.join(f'{sc[t][0]:.2f}' for t in TYPES), flush=True)
for k, v in sorted(res.items()):
    print(k, f'exact {sum(s==0 for s in v)} within1 {sum(s<=1 for s in v)} of {len(v)}')
