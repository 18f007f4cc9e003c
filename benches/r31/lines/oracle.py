import numpy as np, glob, sys, json

from uwhl_rs import truth as TR, evaluate as ev
def sog(img, m, p=4):
    e = (img[m]**p).mean(0)**(1/p); return img*(e.mean()/np.maximum(e,1e-9))
rows = []
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); cond = str(d['meta'][1])
    I = d['image'].astype(np.float64); D = d['D'].astype(np.float64); m = ~d['vm'].astype(bool)
    B = sog(I, m); Bp = np.clip(B * (D.sum(2, keepdims=True) / np.maximum(B.sum(2, keepdims=True), 1e-9)), 0, 1)
    G = ev.grayworld(I)
    sc = lambda x: TR.score(x, d['truth'], d['objects'], gains=False)['median']
    rows.append(dict(split=split, cond=cond, name=str(d['meta'][0]), D=sc(D), B=sc(Bp), G=sc(G), I=sc(I)))
json.dump(rows, open('out/oracle.json','w'))
from clcore import by_condition
for split, c, rr, f in by_condition(rows):
    print(split, c, f"D {f('D'):.2f} B {f('B'):.2f} G {f('G'):.2f} oracleDB {np.median([min(r['D'],r['B']) for r in rr]):.2f} oracleDG {np.median([min(r['D'],r['G']) for r in rr]):.2f}")
