import numpy as np, common as C, fit as F, sys
from collections import defaultdict
from uwhl_rs import truth as sc
res=defaultdict(lambda: defaultdict(list))
for r in C.renders("tune"):
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    bf,af,_=F.fit_tiles(r.image,z)
    cond=f"{r.stats}/{r.light}"
    for wn,(b,a) in (("fit",(bf,af)),("true",(bt,r.a))):
        j=C.recover(r.image,z,b,a)
        obj=r.objects
        ok=obj&(r.truth.sum(2)>0.02)
        jo=j[ok][::4]; to=r.truth[ok][::4]
        tn=to/np.linalg.norm(to,axis=1,keepdims=True)
        best=(1e9,0)
        for d in np.arange(0,15.01,0.5):
            o=jo*np.exp(b*d); on=o/np.maximum(np.linalg.norm(o,axis=1,keepdims=True),1e-12)
            ang=np.median(np.degrees(np.arccos(np.clip((on*tn).sum(1),-1,1))))
            if ang<best[0]: best=(ang,d)
        res[wn][cond].append(best[0]); res[wn+"_d"][cond].append(best[1])
for k in res: print(k, {c: round(float(np.median(v)),2) for c,v in res[k].items()})
