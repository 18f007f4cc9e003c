import numpy as np, common as C, uwhl_rs, sys, os
split=sys.argv[1]
os.makedirs("cache",exist_ok=True)
out={}
for r in C.renders(split):
    res=uwhl_rs.restore(r.image)
    out[r.name]=C.score(res.image,r)
import pickle; pickle.dump(out,open(f"cache/default_{split}.pkl","wb"))
