import numpy as np, common as C, fit as F
for r in C.renders("tune"):
    if not (r.stats=="gray" and r.light=="white" and r.geometry in("floor","floor_water")): continue
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    # noise-free content-only check: render with no noise
    ts=F.tile_stats(r.image,z)
    clean = r.t*(r.truth*r.light_rgb/ r.light_rgb.max()*0+r.truth*r.light_rgb) + (1-r.t)*r.a  # light_rgb includes k
    clean = np.where(np.isfinite(r.distance)[:,:,None], clean, r.a)
    tc=F.tile_stats(clean.astype(np.float32),z)
    for nm,t in (("noisy",ts),("clean",tc)):
        cs=[F.lad_costs(t["s"][:,c],t["m"][:,c],t["w"]) for c in range(3)]
        ind=np.array([F.GRID[np.argmin(cs[c][0])] for c in range(3)])
        b,a,_,_=F.curve_search([c[0] for c in cs],[c[1] for c in cs])
        # unweighted
        cs2=[F.lad_costs(t["s"][:,c],t["m"][:,c],np.ones(len(t["w"]))) for c in range(3)]
        b2,_,_,_=F.curve_search([c[0] for c in cs2],[c[1] for c in cs2])
        # residual of y at truth vs m correlation
        y=t["s"]+bt*t["m"]; res=y-bt*r.a
        cor=[np.corrcoef(res[:,c],t["m"][:,c])[0,1] for c in range(3)]
        print(f"{r.name:42s} {nm:5s} curve {np.round(b/bt,2)} indep {np.round(ind/bt,2)} unweighted {np.round(b2/bt,2)} corr(res,m) {np.round(cor,2)}")
