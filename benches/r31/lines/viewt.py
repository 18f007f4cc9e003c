import numpy as np, glob, sys
sys.path.insert(0,'..'); sys.path.insert(0,'../..')
import viz, truth as T
rows, labels = [], []
for idx in sys.argv[2:]:
    split, i = idx.split(':'); d = np.load(f'out/cache/{split}/{int(i):03d}.npz')
    wt = str(d['meta'][2]); tb_true = np.exp(-T.BETA_B[wt] * np.where(np.isfinite(d['dist']), d['dist'], 1e3))
    rows.append([viz.tile(d['image']), viz.tile(d['truth']), viz.tile(d['Dt']), viz.tile(tb_true, lo=0, hi=1), viz.tile(d['tbt'], lo=0, hi=1),
                 viz.tile(np.log(np.clip(d['tbt'],1e-3,1)) - np.log(np.clip(tb_true,1e-3,1)), lo=-0.5, hi=0.5)])
    labels.append([str(d['meta'][0])[:30], 'truth', 'default true type', 't_B true', 't_B est (true type)', 'ln err (-0.5..0.5)'])
viz.sheet(rows, sys.argv[1], labels)
