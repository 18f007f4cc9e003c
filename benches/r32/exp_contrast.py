import numpy as np, common as C, fit as F, sys
from collections import defaultdict
from scipy.ndimage import convolve
conds=sys.argv[1].split(",")
snr=float(sys.argv[2]) if len(sys.argv)>2 else 4
def noise_var(img):
    L=np.array([[0,1,0],[1,-4,1],[0,1,0]],float)
    out=[]
    for c in range(3):
        l=convolve(img[:,:,c].astype(float),L)[2:-2,2:-2]
        out.append((1.4826*np.median(np.abs(l)))**2/20)
    return np.array(out)
def wlad_line(x,y,w):
    # LAD line y = a + b x via grid over b
    best=(np.inf,0,0)
    for b in np.linspace(-3,1,801):
        e=y-b*x; a=F.wmedian_rows(e[None,:],w)[0]; c=(w*np.abs(e-a)).sum()
        if c<best[0]: best=(c,a,b)
    return best[2]
E=defaultdict(list)
for r in C.renders("tune"):
    if f"{r.stats}/{r.light}" not in conds: continue
    z=C.variants(r)["distance"]; bt=C.beta_true(r)
    ts=F.tile_stats(r.image,z)
    s2=noise_var(r.image)
    v=ts["vr"]; zm=ts["zm"]
    res=[]
    for c in (0,1):
        ok=(v[:,c]>snr*s2[c])&(v[:,2]>snr*s2[2])
        q=np.log(v[ok,c]-s2[c])-np.log(v[ok,2]-s2[2])
        slope=wlad_line(zm[ok],q,np.ones(ok.sum()))
        d_est=-slope/2; d_true=bt[c]-bt[2]
        res.append((d_est,d_true,ok.sum()))
    print(f"{r.name:44s} s {np.sqrt(s2).round(4)} dR est {res[0][0]:.3f} true {res[0][1]:.3f} ({res[0][2]}) dG est {res[1][0]:.3f} true {res[1][1]:.3f} ({res[1][2]})")
