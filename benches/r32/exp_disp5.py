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
        ed=EB[s][::3]
        out[f"ge1_{tau}"]=D.minkowski(ed,1); out[f"ge2_{tau}"]=D.minkowski(ed,2)
    return out
res=defaultdict(lambda: defaultdict(list)); dd=defaultdict(lambda: defaultdict(list))
for r in C.renders("tune"):
    z=C.variants(r)["distance"]; bt=C.beta_true(r); cond=f"{r.stats}/{r.light}"
    ts=F.tile_stats(r.image,z); b,a,_=F.fit_tiles(r.image,z,ts=ts); sus=F.suspect(ts,b,z)[0]
    cands={}
    if not sus:
        j=C.recover(r.image,z,b,a); sel=r.objects; tmin=np.exp(-b.max()*C.fill_nearest(z))
        from scipy.ndimage import uniform_filter
        jb=np.stack([uniform_filter(j[:,:,c],5,mode="nearest") for c in range(3)],2)
        gy=np.zeros_like(jb); gx=np.zeros_like(jb); gy[1:-1]=(jb[2:]-jb[:-2])/2; gx[:,1:-1]=(jb[:,2:]-jb[:,:-2])/2
        global EB; EB=np.hypot(gx,gy)
        E=ests(j,sel,tmin,b)
        cands["core"]=C.light_path_core(j,sel,b)
        P={k:proj(e,b) for k,e in E.items()}
        pass
        tau=0.0
        ks=["gw0.0","ge1_0.0","wp0.0"]
        for m in (1.0,0.7,0.5,0.3):
            rr={k:P[k][1]*(1.0 if k=="gw0.0" else 1/m) for k in ks}
            best=min(ks,key=lambda k:rr[k]); cands[f"c3_m{m}"]=np.clip(P[best][0],0,15)
        w=np.array([1/max(P[k][1],1e-3)**2 for k in ks]); cands["c3_w2"]=np.clip(np.dot(w,[P[k][0] for k in ks])/w.sum(),0,15)
        w=np.array([1/max(P[k][1],1e-3)**4 for k in ks]); cands["c3_w4"]=np.clip(np.dot(w,[P[k][0] for k in ks])/w.sum(),0,15)
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
