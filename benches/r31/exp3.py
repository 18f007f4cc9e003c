"""Error budget with the true type: transmission x veiling light x balance."""
import sys, numpy as np
import harness as H, exp, exp1
import truth as T

def true_tb(r):
    return np.where(r.objects, r.t[..., 2], 1.0)

QA = {}
def est_q(r, st, trueA=False):
    if trueA:
        if r.name not in QA:
            QA.clear(); s = stA(r); cs = exp1.cluster_stats(s, r.water_type)
            QA[r.name] = np.asarray(H.C._stage_guided(s.guide, np.ascontiguousarray(s.blend(cs['tt'], cs['lb']), np.float32), s.radius, 1e-3), np.float64)
        return QA[r.name]
    cs = exp1.parts(r, st)
    return np.asarray(H.C._stage_guided(st.guide, np.ascontiguousarray(cs['p'], np.float32), st.radius, 1e-3), np.float64)

def recover_plain(st, wt, tb):
    t = H.channel_t(np.clip(tb, 0.1 ** H.JER[wt][0], 1), wt)
    return np.maximum(st.a + (st.img - st.a) / t, 0)

def balance(j, obj, kind):
    if kind == 'none':
        return j
    if kind == 'gw':
        e = j[obj].mean(0)
    elif kind == 'sog':
        e = H.sog(j, obj)
    return j * H.gains_from(e)

STA = {}
def stA(r):
    if r.name not in STA:
        STA.clear(); STA[r.name] = H.Image(r.image, a=np.clip(r.a, 1e-4, 1))
    return STA[r.name]

def cand(tsrc, asrc, bal):
    def f(r, st):
        s = stA(r) if asrc == 'trueA' else st
        tb = true_tb(r) if tsrc == 'true_t' else est_q(r, st, asrc == 'trueA')
        return balance(recover_plain(s, r.water_type, tb), r.objects, bal)
    return f

cands = {}
for t in ('est_t', 'true_t'):
    for a in ('estA', 'trueA'):
        for b in ('sog', 'gw', 'none'):
            cands[f"{t}/{a}/{b}"] = cand(t, a, b)
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/exp3_{every}.json")
