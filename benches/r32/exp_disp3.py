import numpy as np, common as C, fit as F, displab as D, pickle, sys
from collections import defaultdict
default=pickle.load(open("cache/default_tune.pkl","rb"))
def proj(e,beta):
    le=np.log(np.maximum(e,1e-12)); le-=le.mean(); b=beta-beta.mean()
    d=-np.dot(le,b)/np.dot(b,b); bn=b/np.linalg.norm(b)
    o=np.linalg.norm(le+d*b)  # residual after the best d (unclamped)
    return d,o
def ests(j,sel,tmin,beta):
    out={}
    for tau in (0.0,0.1,0.25):
        s=sel&(tmin>=tau)
        if s.sum()<2000: s=sel
        px=j[s][::3]
        out[f"gw{tau}"]=D.minkowski(px,1); out[f"sog2_{tau}"]=D.minkowski(px,2); out[f"sog4_{tau}"]=D.minkowski(px,4)
        out[f"wp{tau}"]=np.percentile(px,99,axis=0)
        ed=D.edges(j,2.0)[s][::3]
        out[f"ge1_{tau}"]=D.minkowski(ed,1); out[f"ge2_{tau}"]=D.minkowski(ed,2)
    return out
res=defaultdict(lambda: defaultdict(list)); dd=defaultdict(lambda: defaultdict(list))
for r in C.renders("tune"):
    z=C.variants(r)["distance"]; bt=C.beta_true(r); cond=f"{r.stats}/{r.light}"
    ts=F.tile_stats(r.image,z); b,a,_=F.fit_tiles(r.image,z,ts=ts); sus=F.suspect(ts,b,z)[0]
    cands={}
    if not sus:
        j=C.recover(r.image,z,b,a); sel=r.objects; tmin=np.exp(-b.max()*C.fill_nearest(z))
        E=ests(j,sel,tmin,b)
        cands["core"]=C.light_path_core(j,sel,b)
        P={k:proj(e,b) for k,e in E.items()}
        for k,(d,o) in P.items(): cands["d_"+k]=np.clip(d,0,15)
        for tau in (0.0,0.1):
            for nm,ks in (("c4",["gw","sog4_","ge1_","wp"]),("c3",["gw","ge1_","wp"]),("c6",["gw","sog2_","sog4_","ge1_","ge2_","wp"]),("cgw_wp",["gw","wp"]),("c_ge2wp",["gw","ge2_","wp"])):
                ks=[k+str(tau) for k in ks]
                best=min(ks,key=lambda k:P[k][1]); cands[f"{nm}_{tau}"]=np.clip(P[best][0],0,15)
            for th in (0.02,0.05):
                ks=[k+str(tau) for k in ["gw","sog4_","ge1_","wp"]]
                if P[ks[0]][1]<th: cands[f"gwfirst{th}_{tau}"]=np.clip(P[ks[0]][0],0,15)
                else: cands[f"gwfirst{th}_{tau}"]=np.clip(P[min(ks[1:],key=lambda k:P[k][1])][0],0,15)
        cands["true"]=5.0 if r.light=="tinted" else 0.0
        for k,d in cands.items():
            res[k][cond].append(C.score(C.expose(j,np.exp(b*d),sel),r)); dd[k][cond].append(d)
    else:
        for k in list(res.keys()) or ["core"]:
            res[k][cond].append(default[r.name])
    print(r.name,file=sys.stderr)
conds=["gray/white","gray/tinted","own/white","own/tinted"]
for k in res:
    print(f"{k:22s}"," | ".join(f"{np.median(res[k][c]):5.1f} (d {np.median(dd[k][c]):4.1f})" for c in conds), f" max {max(np.median(res[k][c]) for c in conds):.1f}")
