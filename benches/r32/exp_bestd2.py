import numpy as np, common as C, fit as F, sys, json
out=[]
for r in C.renders("tune"):
    if r.stats!="gray": continue
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    bf,af,_=F.fit_tiles(r.image,z)
    d=5.0 if r.light=="tinted" else 0.0
    sel=r.objects
    ang={}
    for wn,(b,a) in (("fit",(bf,af)),("true",(bt,r.a)),("fitb_trueA",(bf,r.a)),("trueb_fitA",(bt,af))):
        j=C.recover(r.image,z,b,a)
        ang[wn]=C.score(C.expose(j,np.exp(b*d),sel),r)
    # also true beta for display gains but fit for recovery
    j=C.recover(r.image,z,bf,af); ang["fit_gt"]=C.score(C.expose(j,np.exp(bt*d),sel),r)
    print(f"{r.name:42s} ratio {np.round(bf/bt,2)} A/At {np.round(af/r.a,2)} "+" ".join(f"{k}={v:.1f}" for k,v in ang.items()))
