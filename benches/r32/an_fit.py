import json,sys,numpy as np
recs=json.load(open(sys.argv[1]))
cands=list(dict.fromkeys(r['cand'] for r in recs)); vs=list(dict.fromkeys(r['var'] for r in recs))
for v in vs:
  print("==",v)
  for c in cands:
    s=[r for r in recs if r['cand']==c and r['var']==v]
    e=np.array([np.max(np.abs(np.array(r['ratio'])-1)) for r in s])
    ex=np.array([r['nt']==r['type'] for r in s])
    geo={g: f"{sum((e<=.1)[[r['geom']==g for r in s]])}/{sum(r['geom']==g for r in s)}" for g in sorted(set(r['geom'] for r in s))}
    mr=np.median([r['ratio'] for r in s],0)
    print(f"{c:12s} within10 {sum(e<=.1):3d}/{len(s)} within20 {sum(e<=.2):3d} exact type {ex.sum():3d} med err {np.median(e):.3f} ratio {np.round(mr,2)} by geom {geo}")
