"""Evaluate fit candidates: beta error, type, angles with the core's display search and with the true d."""
import numpy as np, common as C, fit as F, sys, pickle, json, time
from collections import defaultdict

def run(fitters, split="tune", variants=("distance",), disp=None, verbose=False):
    default = pickle.load(open(f"{C.HERE}/cache/default_{split}.pkl","rb"))
    recs=[]
    for r in C.renders(split):
        bt=C.beta_true(r); dtrue=5.0 if r.light=="tinted" else 0.0
        vz=C.variants(r)
        for vn in variants:
            z=vz[vn]
            for name,fn in fitters.items():
                beta,a,ok=fn(r.image,z)
                rec=dict(name=r.name,geom=r.geometry,cond=f"{r.stats}/{r.light}",type=r.water_type,var=vn,cand=name,
                         err=float(np.max(np.abs(beta/bt-1))),exact=F.nearest_type(beta)==r.water_type,ok=ok,ratio=(beta/bt).tolist())
                if ok:
                    j=C.recover(r.image,z,beta,a); sel=r.objects & np.isfinite(z)
                    d=C.light_path_core(j,sel,beta) if disp is None else disp(j,sel,beta,r,z)
                    rec["core"]=C.score(C.expose(j,np.exp(beta*d),r.objects),r)
                    rec["true_d"]=C.score(C.expose(j,np.exp(beta*dtrue),r.objects),r)
                    rec["d"]=float(d)
                else:
                    rec["core"]=rec["true_d"]=default[r.name]; rec["d"]=None
                recs.append(rec)
        if verbose: print(r.name,file=sys.stderr)
    return recs

def summary(recs):
    conds=["gray/white","gray/tinted","own/white","own/tinted"]
    lines=[]
    for (vn,name) in dict.fromkeys((r['var'],r['cand']) for r in recs):
        s=[r for r in recs if r['var']==vn and r['cand']==name]
        cells=[]
        for c in conds:
            q=[r for r in s if r['cond']==c]
            cells.append(f"{np.median([r['core'] for r in q]):5.1f} [{np.median([r['true_d'] for r in q]):4.1f}] b{sum(r['err']<=.1 for r in q):2d} t{sum(r['exact'] for r in q):2d} u{sum(r['ok'] for r in q):2d}")
        geo={g: sum(r['err']<=.1 for r in s if r['geom']==g) for g in ('floor','floor_water','wall')}
        lines.append(f"{vn:15s} {name:14s} | "+" | ".join(cells)+f" | b10 {sum(r['err']<=.1 for r in s)} exact {sum(r['exact'] for r in s)} {geo}")
    return "\n".join(lines)
