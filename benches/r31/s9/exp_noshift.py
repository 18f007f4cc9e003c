"""The artifact clamp's shift (METHOD §7: J -= max(min J, -0.08)) adds the
same amount to every channel; the balance of §12.1 then multiplies it by
each channel's gain, so a channel the water emptied (chart_calib_2_under's
red) becomes a flat colour over the whole frame. Displays (`finish`'s
`shift`): True today's; "neutral" the same gains, the lift added gray;
False J = max(J, 0) without a lift; "E<f>[L|M]" gains from J >= 0 with each
channel's estimate at least f x the largest, the lift added gray times the
mean (L) or median (M) gain. Modes: no third argument, the type chosen on
each display's own J; "x" the first three; "E" the E displays.

    python3 benches/r31/s9/exp_noshift.py tune 2 E
"""
import os
import sys
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import exp
import harness as H
import uwhl_rs


def recovered(st, wt, q):
    """METHOD §7 before the clamp: (t_B, t_c, the input, J)."""
    br, _ = H.JER[wt]
    tb = np.clip(q, 0.1 ** br, 1.0)
    t = H.channel_t(tb, wt)
    img = st.img.astype(np.float64)
    return tb, t, img, st.a + (img - st.a) / t


def finish(st, wt, q, shift=True, fallback=True):
    if shift is True:
        return H.finish(st, wt, q, fallback=fallback)
    tb, t, img, j = recovered(st, wt, q)
    obj = st.objects
    if shift == "neutral":
        # today's clamp and gains; the pedestal made neutral in display space
        lo, hi = j.min(), j.max()
        sh = max(lo, -0.08)
        div = min(max(hi - sh, 0), 1.6)
        jc = np.minimum(np.maximum(j - sh, 0) / div, 1)
        g = H.gains_from(H.sog(jc, obj))
        pct = np.array([np.quantile(jc[..., c], 0.99) for c in range(3)])
        tp = (g * pct).max()
        k = g * (1 / tp if tp > 0 else 1)
        ped = -sh / div  # in clamped-J units
        image = np.clip((jc - ped) * k + ped * k.mean(), 0, 1)
    elif isinstance(shift, str) and shift.startswith("E"):
        # E<floor>[L]: gains from J >= 0 (no lift in the estimate), each
        # channel's estimate at least floor x the largest; L: the clamp's lift added gray
        fl = float(shift[1:].rstrip("LM"))
        lo, hi = j.min(), j.max()
        sh = max(lo, -0.08)
        div = min(max(hi - sh, 0), 1.6)
        jz = np.minimum(np.maximum(j, 0) / div, 1)
        e = H.sog(jz, obj)
        e = np.maximum(e, fl * e.max())
        g = H.gains_from(e)
        pct = np.array([np.quantile(jz[..., c], 0.99) for c in range(3)])
        tp = (g * pct).max()
        k = g * (1 / tp if tp > 0 else 1)
        ped = -sh / div if shift.endswith(("L", "M")) else 0.0
        kk = np.median(k) if shift.endswith("M") else k.mean()
        image = np.clip(jz * k + max(ped, 0) * kk, 0, 1)
        jc = np.minimum(np.maximum(j - sh, 0) / div, 1)
    else:
        jc = np.maximum(j, 0)
        top = jc.max()
        if top > 0:
            jc = jc / min(top, 1.6)
        jc = np.minimum(jc, 1)
        g = H.gains_from(H.sog(jc, obj))
        pct = np.array([np.quantile(jc[..., c], 0.99) for c in range(3)])
        tp = (g * pct).max()
        k = g * (1 / tp if tp > 0 else 1)
        image = np.clip(jc * k, 0, 1)
    image, ve = H.trust_blend(st, image, j, t, g, fallback)
    return image, jc, tb, ve


def steps(wt, r):
    return abs(H.TYPES.index(wt) - H.TYPES.index(r.water_type))


def make(shift, choose):
    def f(r, st):
        if choose == "true":
            wt = r.water_type
            q = st.default_q(wt)
            im, jc, tb, ve = finish(st, wt, q, shift)
        elif choose == "core":
            wt = uwhl_rs.restore(r.image).water_type
            q = st.default_q(wt)
            im, jc, tb, ve = finish(st, wt, q, shift)
        else:  # own choice: §12.2 on this J
            best = None
            for wt in H.TYPES:
                q = st.default_q(wt)
                im, jc, tb, ve = finish(st, wt, q, shift)
                sp = H.spread(jc, st.objects)
                if best is None or sp < best[0]:
                    best = (sp, wt, im, tb)
            _, wt, im, tb = best
        return im, {"rho": exp.rho(r, tb), "steps": steps(wt, r)}
    return f


if __name__ == "__main__":
    split = sys.argv[1] if len(sys.argv) > 1 else "tune"
    every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    if len(sys.argv) > 3 and sys.argv[3] == "E":
        c = {"shift_core": make(True, "core"), "neutral_core": make("neutral", "core")}
        for m in (("E0.2", "E0.1L", "E0.2L") if split == "fresh" else ("E0.1", "E0.2", "E0.1L", "E0.2L", "E0.35L")):
            c[m + "_core"] = make(m, "core")
        exp.run(c, split=split, every=every, out=f"/tmp/s9/r/E_{split}.json")
        sys.exit()
    if len(sys.argv) > 3:
        exp.run({"shift_core": make(True, "core"), "noshift_core": make(False, "core"), "neutral_core": make("neutral", "core"),
                 "shift_true": make(True, "true"), "noshift_true": make(False, "true"), "neutral_true": make("neutral", "true")},
                split=split, every=every, out=f"/tmp/s9/r/noshift3_{split}.json")
        sys.exit()
    exp.run({"shift_core": make(True, "core"), "noshift_core": make(False, "core"),
             "shift_own": make(True, "own"), "noshift_own": make(False, "own"),
             "shift_true": make(True, "true"), "noshift_true": make(False, "true")},
            split=split, every=every, out=f"/tmp/s9/r/noshift_{split}.json")
