"""METHOD §13.2's tile weights with the image noise taken out of each
tile's residual variance (so that flat tiles, free of the content's own
gradients, keep the weight they have without noise): beta within 10% on the
renders of benches/truth.py with the true distance. Prototype on
benches/r32/fit.py (the core's fit in NumPy)."""
import sys
import numpy as np
sys.path.insert(0, '../../r32'); sys.path.insert(0, '../..'); sys.path.insert(0, '..')
import fit as F
import truth as T
import harness as H
from uwhl_rs import synth

split = sys.argv[1] if len(sys.argv) > 1 else 'tune'
every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
FLOORS = [None, 0.05, 0.2, 0.5]
res = {f: [] for f in FLOORS}
for k, r in enumerate(T.scenes(split, 360)):
    if k % every:
        continue
    z = np.where(np.isfinite(r.distance), r.distance, np.nan)
    bt = np.array([T.BETA_B[r.water_type] / synth.JERLOV[r.water_type][0],
                   T.BETA_B[r.water_type] / synth.JERLOV[r.water_type][1], T.BETA_B[r.water_type]])
    ts = F.tile_stats(r.image.astype(np.float64), z, eiv=True)
    sig2 = H.noise_sigma(r.image) ** 2
    line = []
    for fl in FLOORS:
        if fl is None:
            w = ts['w']
        else:
            n = ts['n'][:, None]
            content = np.maximum(ts['vr'] - sig2[None, :] * (1 - 2 / n), fl * sig2[None, :] + 1e-12)
            w = np.sqrt(np.median(n * ts['vz'][:, None] / content, axis=1))
        beta, a, _ = F.fit_tiles(None, None, weights=w, ts=ts)
        e = float(np.max(np.abs(beta / bt - 1)))
        res[fl].append((f'{r.stats}/{r.light}', e))
        line.append(f'{e:.2f}')
    print(r.name, ' '.join(line), flush=True)
for fl in FLOORS:
    v = res[fl]
    conds = sorted({c for c, _ in v})
    print('floor', fl, ' '.join(f"{c}: {sum(e <= 0.1 for cc, e in v if cc == c)}/{sum(cc == c for cc, _ in v)}" for c in conds),
          'all', sum(e <= 0.1 for _, e in v), 'of', len(v), 'median err', round(float(np.median([e for _, e in v])), 3))
