import numpy as np, common as C, fit as F, sys
rows=[]
for r in C.renders("tune"):
    if r.stats!="gray" or r.light!="white": continue
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    ts=F.tile_stats(r.image,z)
    cs=[F.lad_costs(ts["s"][:,c],ts["m"][:,c],ts["w"]) for c in range(3)]
    ind=np.array([F.GRID[np.argmin(cs[c][0])] for c in range(3)])
    beta,a,_,tot=F.curve_search([c[0] for c in cs],[c[1] for c in cs])
    # cost at truth vs at fit
    pos=lambda b: np.interp(np.log(b), F.LNG, np.arange(481))
    ct=sum(np.interp(pos(bt[c]),np.arange(481),cs[c][0]) for c in range(3))
    cf=sum(np.interp(pos(beta[c]),np.arange(481),cs[c][0]) for c in range(3))
    print(f"{r.name:45s} ntiles {len(ts['w'])} indep/true {np.round(ind/bt,2)} curve/true {np.round(beta/bt,2)} A fit {np.round(a,3)} true {np.round(r.a,3)} cost true/fit {ct/cf:.3f}")
