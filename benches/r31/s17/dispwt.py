"""The display's colour estimate (METHOD §12.1) taken where the radiance
can be trusted: the shades-of-gray colour of J weighted by the
transmission, so that far pixels, whose J carries the error of t
multiplied by 1/t, count less. The core's default is re-displayed in
NumPy from its clamped radiance and re-blended (§12.5 step 4) with the
confidence and veil excess it reports; ``today`` reproduces the core.

    python3 benches/r31/s17/dispwt.py tune|held|fresh [variant ...]
"""
import sys, os
import numpy as np
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", ".."))
import uwhl_rs
from uwhl_rs import truth as TR

CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]
Q = 0.99


def wsog(J, w, p):
    w = w / w.sum()
    return np.array([(w * np.maximum(J[:, c], 0) ** p).sum() ** (1 / p) for c in range(3)])


def estimate(J, tb, tc, variant):
    """The illuminant's colour from the object pixels' J (N x 3)."""
    if variant == "today":
        return wsog(J, np.ones(len(J)), 4)
    kind, arg = variant.split(":")
    k = float(arg)
    if kind == "sogtb":  # weight t_B^k, p = 4
        return wsog(J, np.maximum(tb, 1e-6) ** k, 4)
    if kind == "sogtmin":
        return wsog(J, np.maximum(tc.min(1), 1e-6) ** k, 4)
    if kind == "gwtb":
        return wsog(J, np.maximum(tb, 1e-6) ** k, 1)
    if kind == "gwtmin":
        return wsog(J, np.maximum(tc.min(1), 1e-6) ** k, 1)
    if kind == "sog2tb":
        return wsog(J, np.maximum(tb, 1e-6) ** k, 2)
    if kind == "sogp":  # unweighted, power k
        return wsog(J, np.ones(len(J)), k)
    if kind == "near":  # p = 4 over the share k of the pixels with the largest t_B
        keep = tb >= np.quantile(tb, 1 - k)
        return wsog(J[keep], np.ones(keep.sum()), 4)
    raise ValueError(variant)


def display(res, I, variant):
    """The default's displayed image with the colour estimate ``variant``;
    ``fb:P`` keeps the display and balances the input (the fallback's B)
    with shades of gray of power P instead of 4."""
    pin = 4.0
    kloc = 0.3
    if variant.startswith("loc:"):
        kloc, variant = float(variant[4:]), "today"
    if variant.startswith("fb:"):
        pin, variant = float(variant[3:]), "today"
    elif variant.startswith("both:"):
        pin = float(variant[5:])
        variant = "sogp:%g" % pin
    if "veiling_light_not_water" in res.flags:
        return np.asarray(res.image, np.float64)
    J = np.asarray(res.radiance, np.float64)
    tb = np.asarray(res.transmission, np.float64)
    tc = np.asarray(res.channel_transmissions(), np.float64)
    obj = ~np.asarray(res.veiling_mask)
    e = estimate(J[obj], tb[obj], tc[obj], variant)
    g = e.mean() / np.maximum(e, 1e-12)
    top = max(g[c] * np.quantile(J[..., c], Q) for c in range(3))
    D = np.clip(J * (g / top), 0, 1)
    wp_ = float(np.clip((res.veil_excess - 0.02) / 0.18, 0, 1))
    if wp_ >= 1:
        w = np.ones(D.shape[:2])
    else:
        c = np.asarray(res.confidence, np.float64) / (1 - wp_)
        w = 1 - (1 - wp_) * (1 - kloc * (1 - c))
    ein = wsog(I[obj], np.ones(obj.sum()), pin)
    B = I / np.maximum(ein, 1e-12)
    B = B * (D.sum(2, keepdims=True) / np.maximum(B.sum(2, keepdims=True), 1e-12))
    return np.clip((1 - w[..., None]) * D + w[..., None] * B, 0, 1)


def renders(split, variants):
    import truth as T
    out = {v: {} for v in variants}
    gap = []
    shares = []
    for r in T.scenes(split, 360):
        res = uwhl_rs.restore(r.image)
        I = np.asarray(r.image, np.float64)
        sel = r.objects & (r.truth.sum(2) > TR.MIN_TRUTH_SUM)
        for v in variants:
            D = display(res, I, v)
            if v == "today":
                shares.append(res.fallback_share)
                gap.append(np.abs(D - res.image).max())
            a = TR.angle_stats(TR.pixel_angles(D, r.truth, sel))["median"]
            out[v].setdefault(f"{r.stats}/{r.light}", []).append(a)
    print(split, "max |today - core| median %.4f, 90th %.4f" % (np.median(gap), np.quantile(gap, 0.9)))
    sh = np.array(shares).reshape(4, -1)
    print("fallback_share = 1:", [int((x > 0.999).sum()) for x in sh], "of", sh.shape[1])
    for v in variants:
        print(f"{v:12s}", " / ".join(f"{np.median(out[v][c]):5.2f}" for c in CONDS), flush=True)


if __name__ == "__main__":
    vs = ["today"] + sys.argv[2:]
    renders(sys.argv[1], vs)
