import numpy as np, common as C, fit as F, sys
from collections import defaultdict
conds=sys.argv[1].split(",") if len(sys.argv)>1 else ["gray/white"]
E=defaultdict(list)
for r in C.renders("tune"):
    if f"{r.stats}/{r.light}" not in conds: continue
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    ts=F.tile_stats(r.image,z)
    b0,a0,_=F.fit_tiles(r.image,z,ts=ts)
    out={"core":b0}
    for k in (2.0,3.0):
        out[f"sp_lad{k}"]=F.second_pass(ts,b0,k)[0]
        out[f"sp_ls{k}"]=F.second_pass(ts,b0,k,mode="ls")[0]
    out["norm"]=F.norm_search(ts,ts["w"])[0]
    out["w2"]=F.fit_tiles(r.image,z,ts=ts,weights=ts["w"]**2)[0]
    out["w0.5"]=F.fit_tiles(r.image,z,ts=ts,weights=ts["w"]**0.5)[0]
    for k,b in out.items():
        e=np.max(np.abs(b/bt-1)); E[(k,r.geometry)].append(e); E[(k,"all")].append(e)
for k in dict.fromkeys(x[0] for x in E):
    print(f"{k:10s}", " ".join(f"{g}: {sum(np.array(E[(k,g)])<=.1):2d}/{len(E[(k,g)])} med {np.median(E[(k,g)]):.2f}" for g in ("floor","floor_water","wall","all")))
