import time, numpy as np, sys
sys.path.insert(0,'..')
import truth as T, harness as H, wls
r = next(T.scenes('tune',360)); st = H.Image(r.image)
t0=time.time(); L,_=wls.laplacian(st.guide); t1=time.time()
w=np.ones(st.h*st.w); x=wls.solve(np.random.rand(st.h,st.w), w.reshape(st.h,st.w), L, 1.0); t2=time.time()
print(st.h, st.w, t1-t0, t2-t1, _)
