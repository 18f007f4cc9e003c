import numpy as np, glob, sys, json

import uwhl_rs
from uwhl_rs import truth as TR, evaluate as ev
picks = {}
for split in ['tune', 'held']:
    for ln in open(f'out/cltype_{split}_all.txt'):
        p = ln.split()
        if len(p) > 6 and p[1] == 'aest':
            picks[(split, p[0])] = p[6]
res = {}
for split in ['tune', 'held']:
    for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
        d = np.load(f); name = str(d['meta'][0])[:38]; cond = str(d['meta'][1])
        pk = picks[(split, name)]
        sc = lambda x: TR.score(x, d['truth'], d['objects'], gains=False)['median']
        r = uwhl_rs.restore(d['image'], water_types=[pk])
        for k, v in [('D', d['D']), ('Dt', d['Dt']), ('Dcl', r.image), ('G', ev.grayworld(d['image']))]:
            res.setdefault((split, cond, k), []).append(sc(v))
for split in ['tune','held']:
    conds = sorted({c for s,c,k in res if s==split}); keys = list(dict.fromkeys(k for s,c,k in res if s==split))
    print(split, conds)
    for k in keys: print(f'{k:6s}', ' '.join(f'{np.median(res[(split,c,k)]):6.2f}' for c in conds))
