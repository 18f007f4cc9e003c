import numpy as np, glob, sys, json
sys.path.insert(0,'../..')
import uwhl_rs
from uwhl_rs import truth as TR, evaluate as ev
import truth as T
rows = []
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); cond = str(d['meta'][1]); wt = str(d['meta'][2])
    I = d['image']; vm = d['vm'].astype(bool)
    sc = lambda x: TR.score(x, d['truth'], d['objects'], gains=False)['median']
    r = dict(split=split, cond=cond, name=str(d['meta'][0]), true=wt, D=sc(d['D']), G=sc(ev.grayworld(I)))
    for key, tb in [('P', d['tb']), ('Pt', d['tbt'])]:
        z = (-10 * np.log(np.clip(tb, 1e-3, 1))).astype(np.float32)
        z[vm] = np.nan; z[z <= 0] = np.nan
        res = uwhl_rs.restore(I, distance=z)
        r[key] = sc(res.image); r[key+'_used'] = bool(res.distance['used']); r[key+'_type'] = res.water_type
        r[key+'_steps'] = T.type_steps(res.water_type, wt)
    rows.append(r)
json.dump(rows, open('out/pseudo.json','w'))
from clcore import by_condition
for split, c, rr, f in by_condition(rows):
    print(split, c, f"D {f('D'):.2f} G {f('G'):.2f} P {f('P'):.2f} used {sum(r['P_used'] for r in rr)} w1 {sum((r['P_steps'] or 9)<=1 for r in rr)}  Pt {f('Pt'):.2f} used {sum(r['Pt_used'] for r in rr)}")
