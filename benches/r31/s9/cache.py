"""Cache per render: default output + scores, each type's display, truth."""
import sys, os, numpy as np, time
sys.path.insert(0, "/work/main/benches")
import truth as T
import uwhl_rs
split = sys.argv[1]
out = f"/tmp/s9/cache_{split}"
os.makedirs(out, exist_ok=True)
TY = T.TYPES
for i, r in enumerate(T.scenes(split, 360)):
    fn = f"{out}/{i:03d}.npz"
    if os.path.exists(fn):
        continue
    res = uwhl_rs.restore(r.image)
    disp = np.stack([uwhl_rs.restore(r.image, water_types=[t]).image for t in TY]).astype(np.float16)
    np.savez_compressed(fn, default=res.image.astype(np.float32), disp=disp,
        scores=np.array([res.scores[t] for t in TY]), chosen=res.water_type, true=r.water_type,
        truth=r.truth.astype(np.float32), obj=r.objects, image=r.image.astype(np.float32),
        cond=f"{r.stats}/{r.light}", name=r.name, gw=T.ev.grayworld(r.image).astype(np.float32))
    print(i, r.name, file=sys.stderr)
