import numpy as np, sys
sys.path.insert(0,'../..')
import truth as T, uwhl_rs
from uwhl_rs import synth
from shadefit import tiles, refine
for cname in sys.argv[1].split(','):
    rho, _ = T.content(cname, 360); h, w = rho.shape[:2]
    for geom in ['floor', 'wall']:
        z = T.geometry(geom, h, w)
        for wt in ['I', 'II', '3C', '7C']:
            r = T.through_water('x', 'x', geom, rho, z, wt, 'own', 'white', float(sys.argv[2]), 1)
            res = uwhl_rs.restore(r.image, distance=z.astype(np.float32))
            bt = np.array([T.BETA_B[wt] / synth.JERLOV[wt][0], T.BETA_B[wt] / synth.JERLOV[wt][1], T.BETA_B[wt]])
            if res.water is None: print(cname, geom, wt, 'no fit'); continue
            b0 = np.array(res.water['beta']); a0 = np.array(res.veiling_light)
            Tl = tiles(r.image.astype(np.float64), z)
            b1, a1, _ = refine(Tl, b0, a0, shade=True)
            b2, a2, _ = refine(Tl, b0, a0, shade=False)
            print(cname, geom, wt, 'core', np.round(b0 / bt, 2), 'shade', np.round(b1 / bt, 2), 'noshade', np.round(b2 / bt, 2), flush=True)
