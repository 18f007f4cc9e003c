import numpy as np, uwhl_rs, sys, os, pickle
sys.path.insert(0,'../..')
import truth as T
split = sys.argv[1]
out = f'out/cache/{split}'; os.makedirs(out, exist_ok=True)
for i, r in enumerate(T.scenes(split, 360)):
    res = uwhl_rs.restore(r.image)
    rt = uwhl_rs.restore(r.image, water_types=[r.water_type])
    np.savez(f'{out}/{i:03d}.npz', image=r.image, truth=r.truth, objects=r.objects, D=res.image, J=res.radiance,
             tb=res.transmission, vm=res.veiling_mask, conf=res.confidence, a=np.array(res.veiling_light),
             Dt=rt.image, Jt=rt.radiance, tbt=rt.transmission, conft=rt.confidence, at=np.array(rt.veiling_light),
             dist=r.distance, light=r.light_rgb, atrue=r.a,
             meta=np.array([r.name, r.stats+'/'+r.light, r.water_type, res.water_type, r.content]))
    print(i, r.name, flush=True)
