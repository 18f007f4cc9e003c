import numpy as np, sys
sys.path.insert(0,'../..')
import truth as T, uwhl_rs
from uwhl_rs import synth
rng = np.random.default_rng(0)
h, w = 360, 480
z = T.geometry('floor', h, w)
# piecewise-constant content: 16x16 blocks of random colours (J constant inside most tiles)
blocks = rng.uniform(0.05, 0.9, (h // 16 + 1, w // 16 + 1, 3))
rho_pc = np.repeat(np.repeat(blocks, 16, 0), 16, 1)[:h, :w]
rho_nat, _ = T.content('chelsea', 360)
rho_nat = rho_nat[:h, :w]
for name, rho in [('blocks', rho_pc), ('chelsea', rho_nat)]:
    for wt in ['I', 'II', '3C', '7C']:
        for noise in [0.0]:
            r = T.through_water('x', 'x', 'floor', rho, z, wt, 'own', 'white', noise, 1)
            res = uwhl_rs.restore(r.image, distance=z.astype(np.float32))
            bt = np.array([T.BETA_B[wt] / synth.JERLOV[wt][0], T.BETA_B[wt] / synth.JERLOV[wt][1], T.BETA_B[wt]])
            b = np.array(res.water['beta'])
            print(name, wt, 'ratio fit/true', np.round(b / bt, 3), 'A', np.round(res.veiling_light, 3), 'true', np.round(r.a, 3), res.water['nearest_type'])
