"""Where the error lives (true type): true t with estimated / true A, calibrated estimates."""
import sys, numpy as np
import harness as H, exp, exp1
from scipy.ndimage import gaussian_filter

def affine(r, q):
    obj = r.objects
    x = -np.log(np.clip(q[obj], 1e-6, 1)); y = T_BB(r) * r.distance[obj]
    s, o = np.polyfit(x, y, 1)
    out = q.copy(); out[obj] = np.exp(-np.maximum(s * x + o, 0))
    return out
def scale_only(r, q):
    obj = r.objects
    x = -np.log(np.clip(q[obj], 1e-6, 1)); y = T_BB(r) * r.distance[obj]
    s = (x @ y) / (x @ x)
    out = q.copy(); out[obj] = np.exp(-s * x)
    return out
import truth as T
T_BB = lambda r: T.BETA_B[r.water_type]

def true_tb(r):
    return np.where(r.objects, r.t[..., 2], 1.0)

def c_true_t(fb):
    def f(r, st):
        return exp1.fin(r, st, true_tb(r), fb)
    return f
def c_true_t_trueA(r, st):
    st2 = H.Image(r.image, a=np.clip(r.a, 1e-4, 1))
    return exp1.fin(r, st2, true_tb(r), False)
def c_aff(smooth=0, fb=False, fn=affine):
    def f(r, st):
        q = exp1.parts(r, st); q = exp1.gf(fb=fb)  # placeholder
        cs = exp1.parts(r, st)
        qq = np.asarray(H.C._stage_guided(st.guide, np.ascontiguousarray(cs['p'], np.float32), st.radius, 1e-3), np.float64)
        if smooth:
            qq = np.exp(-gaussian_filter(-np.log(np.clip(qq, 1e-3, 1)), smooth))
        return exp1.fin(r, st, fn(r, qq), fb)
    return f
def c_smooth(s, fb=True):
    def f(r, st):
        cs = exp1.parts(r, st)
        qq = np.asarray(H.C._stage_guided(st.guide, np.ascontiguousarray(cs['p'], np.float32), st.radius, 1e-3), np.float64)
        qq = np.exp(-gaussian_filter(-np.log(np.clip(qq, 1e-3, 1)), s))
        return exp1.fin(r, st, qq, fb)
    return f

cands = {"gf": exp1.gf(), "gf_nofb": exp1.gf(fb=False),
         "true_t_nofb": c_true_t(False), "true_t_fb": c_true_t(True), "true_t_trueA_nofb": c_true_t_trueA,
         "affine_nofb": c_aff(), "scale_nofb": c_aff(fn=scale_only), "smooth20_affine_nofb": c_aff(20), "smooth20": c_smooth(20), "smooth20_nofb": c_smooth(20, False)}
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/exp2_{every}.json")
