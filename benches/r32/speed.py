import time, numpy as np, common as C, uwhl_rs
from PIL import Image
r=next(iter(C.renders()))
img=np.asarray(Image.fromarray((r.image*255).astype(np.uint8)).resize((2160,1440),Image.BILINEAR),dtype=np.float32)/255
z=np.asarray(Image.fromarray(r.distance.astype(np.float32)).resize((2160,1440),Image.NEAREST))
for k in range(2):
    t=time.time(); a=uwhl_rs.restore(img,distance=z); t1=time.time()-t
    t=time.time(); b=uwhl_rs.restore(img); t2=time.time()-t
print(f"2160x1440 with {t1:.3f}s used {a.distance['used']} without {t2:.3f}s")
