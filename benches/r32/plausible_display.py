"""Among the plausible waters of the fit (METHOD §13.2 step 6), how good could the colours be (oracle), and does the display's family residual pick a better one? Prototype (no settling, no rejection rules); tune.

    PYTHONPATH=python python3 benches/r32/plausible_display.py
"""
import sys, numpy as np
sys.path.insert(0,'python'); sys.path.insert(0,'benches'); sys.path.insert(0,'benches/r32')
import truth as T, fit as F, common as C, displab as D
from uwhl_rs import truth as sc
Cv=F.curve(F.U)
pos=lambda l: np.clip((l-F.LNG[0])/(F.LNG[-1]-F.LNG[0])*(len(F.GRID)-1),0,len(F.GRID)-1)
idx=np.arange(len(F.GRID))
def display(j, sel, beta):
    px=j[sel][::3]; ed=D.box_edges(j)[sel][::3]
    ests=[(px.mean(0),0.5),(ed.mean(0),1.0),(np.percentile(px,99,axis=0),1.0)]
    best=None
    for e,m in ests:
        d,r=D.project(e,beta); r*=m
        if best is None or r<best[1]: best=(d,r)
    d=float(np.clip(best[0],0,15))
    return C.expose(j,np.exp(beta*d),sel), d, best[1]
res={}
for r in T.scenes("tune",360):
    z=np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
    ts=F.tile_stats(r.image,z,eiv=True)
    if len(ts["w"])<40: continue
    cs=[F.lad_costs(ts["s"][:,c],ts["m"][:,c],ts["w"]) for c in range(3)]
    beta,a,tot,surf=F.curve_search([c[0] for c in cs],[c[1] for c in cs])
    reg=surf<=surf.min()*1.01
    iu,kb=np.nonzero(reg)
    # up to 25 candidates spread over the region, the best first
    order=np.argsort(surf[iu,kb]); pick=[order[0]]+list(order[np.linspace(0,len(order)-1,24).astype(int)])
    sel=r.objects & np.isfinite(z)
    cond=f"{r.stats}/{r.light}"
    angs=[]
    for k in pick:
        bb=F.GRID[kb[k]]; bet=np.array([bb/np.exp(Cv[iu[k],0]),bb/np.exp(Cv[iu[k],1]),bb])
        A=np.array([np.interp(pos(np.log(bet[c])),idx,cs[c][1])/bet[c] for c in range(3)])
        j=C.recover(r.image,z,bet,A)
        img,d,resid=display(j,sel,bet)
        angs.append((sc.score(img,r.truth,r.objects,gains=False)["median"],resid))
    a_=np.array(angs)
    res.setdefault(cond,[]).append((a_[0,0],a_[:,0].min(),np.median(a_[:,0]),a_[np.argmin(a_[:,1]),0]))
for c,v in res.items():
    v=np.array(v); print(c,len(v),"fit %.1f  oracle %.1f  median of plausible %.1f  least family residual %.1f"%(np.median(v[:,0]),np.median(v[:,1]),np.median(v[:,2]),np.median(v[:,3])))
