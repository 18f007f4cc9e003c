import numpy as np, fit as F, evalfit as E, json, sys
def mk(**kw):
    def fn(img,z):
        ts=F.tile_stats(img,z,**kw)
        b,a,_=F.fit_tiles(img,z,ts=ts)
        sus,_,_=F.suspect(ts,b,z)
        return b,a,not sus
    return fn
fitters={"core":mk(),"eiv":mk(eiv=True),"win8":mk(win=8),"eiv_win8":mk(eiv=True,win=8),"eiv_win16":mk(eiv=True,win=16)}
recs=E.run(fitters,"tune",("distance","distance_noise"))
json.dump(recs,open("fit_a.json","w"))
print(E.summary(recs))
