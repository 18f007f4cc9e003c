"""t_scale from the type's blue attenuation: the nearest surface at z0 metres has t_B = exp(-Kd_B(type) z0)."""
import sys, numpy as np
sys.path.insert(0, '..')
import truth as T, harness as H, exp, exp1, exp4

def make(z0=None, fb=True, oracle=False, ccal=None):
    def f(r, st):
        rr, k, lb = exp4.base(r, st, 500)
        tt = exp4.tt_of(rr, k, exp4.rmax_of(rr, k, 500))
        if ccal is not None:
            c = exp4.cluster_offsets(tt, k, 500, mu=ccal)
            tt = np.where(k >= 0, np.clip(tt * np.exp(c[np.maximum(k, 0)]), 0.01, 1), tt)
        if oracle:
            s = float(np.exp(-T.BETA_B[r.water_type] * np.nanmin(np.where(r.objects, r.distance, np.nan))))
        elif z0 is None:
            s = 0.9
        else:
            s = float(np.exp(-T.BETA_B[r.water_type] * z0))
        q = st.guided(st.blend(tt, lb, s))
        return exp1.fin(r, st, q, fb)
    return f

cands = {"gf": make(), "gf_nofb": make(fb=False), "z1": make(1.0), "z2": make(2.0), "z3": make(3.0), "z2_nofb": make(2.0, fb=False),
         "oracle_near": make(oracle=True), "oracle_near_nofb": make(oracle=True, fb=False), "z2_ccal1": make(2.0, ccal=1.0)}
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/exp6_{every}.json")
