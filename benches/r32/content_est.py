import numpy as np, common as C, displab as D, fit as F
from uwhl_rs import synth
T=C.T
for cname in T.SPLITS['tune']+T.SPLITS['held']:
    rho, zmap = T.content(cname, 360)
    ed = D.edges(rho,1.0)
    px = rho.reshape(-1,3); ex = ed.reshape(-1,3)
    ests = {"gw":D.minkowski(px,1),"sog4":D.minkowski(px,4),"ge1":D.minkowski(ex,1),"ge6":D.minkowski(ex,6),"wp":np.percentile(px,99.5,0)}
    line=[]
    for wt in ["I","III","5C","9C"]:
        br,bg=synth.JERLOV[wt]; bb=T.BETA_B[wt]; beta=np.array([bb/br,bb/bg,bb])
        b=beta-beta.mean(); bn=b/np.linalg.norm(b)
        s=[]
        for k,e in ests.items():
            le=np.log(e); le-=le.mean()
            d=-np.dot(le,b)/np.dot(b,b); orth=np.linalg.norm(le-np.dot(le,bn)*bn)
            s.append(f"{k}:d={d:5.1f},o={orth:.2f}")
        line.append(wt+" "+" ".join(s))
    print(cname, "\n  "+"\n  ".join(line))
