"""The fallback's balance (METHOD §12.5 step 4) with its gains capped by
the brightest object pixels' colour: no channel is raised further than
would make the brightest surfaces neutral (a white glare or a white frame
in green water turned pink under shades of gray). The core's output is
re-blended in NumPy: D' = D + w (B'_new - B'_old), w from the reported
veil excess and confidence (exact where nothing clips).

    python3 benches/r31/s13/wpcap.py tune|held|fresh|charts
"""
import sys, os, json
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "python"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import uwhl_rs
from uwhl_rs import truth as TR

VARIANTS = ("today", "cap1", "gate0.03", "gate0.05", "gate0.08")
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]


def sog(I, obj):
    return np.array([np.mean(np.maximum(I[..., c][obj], 0) ** 4) ** 0.25 for c in range(3)])


def brightest(I, obj, q=0.01):
    v = I[obj]
    s = v.sum(1)
    k = max(1, int(q * len(s)))
    idx = np.argpartition(-s, k - 1)[:k]
    return v[idx].mean(0)


def estimate(I, obj, variant):
    e = sog(I, obj)
    if variant == "today":
        return e
    n = e / e.sum()
    wp = brightest(I, obj)
    m = wp / max(wp.sum(), 1e-12)
    if variant.startswith("cap"):
        k = float(variant[3:])
        return np.maximum(n, m / k)
    if variant.startswith("gate"):
        # only when the brightest pixels are near neutral in the input
        # (a lamp's backscatter, a specular highlight: light the water did
        # not filter), and then as the strict cap
        g = float(variant[4:])
        return np.maximum(n, m) if np.abs(m - 1 / 3).max() < g else e
    if variant.startswith("mix"):
        a = float(variant[3:])
        return n ** (1 - a) * np.maximum(m, 1e-6) ** a
    raise ValueError(variant)


def reblend(res, I, obj, variant):
    D = np.asarray(res.image, np.float64)
    if "veiling_light_not_water" in res.flags:
        return None
    wp_ = float(np.clip((res.veil_excess - 0.02) / 0.18, 0, 1))
    if wp_ >= 1:
        w = np.ones(D.shape[:2])
    else:
        c = np.asarray(res.confidence, np.float64) / (1 - wp_)
        w = 1 - (1 - wp_) * (1 - 0.3 * (1 - c))
    S = D.sum(2, keepdims=True)

    def bprime(e):
        B = I / np.maximum(e, 1e-9)
        return B * (S / np.maximum(B.sum(2, keepdims=True), 1e-9))
    old = bprime(estimate(I, obj, "today"))
    new = bprime(estimate(I, obj, variant))
    return np.clip(D + w[..., None] * (new - old), 0, 1)


def renders(split):
    import truth as T
    res_ = {v: {} for v in VARIANTS}
    for r in T.scenes(split, 360):
        res = uwhl_rs.restore(r.image)
        I = np.asarray(r.image, np.float64)
        obj = ~res.veiling_mask
        sel = r.objects & (r.truth.sum(2) > TR.MIN_TRUTH_SUM)
        for v in VARIANTS:
            out = reblend(res, I, obj, v)
            if out is None:
                out = res.image
            a = TR.angle_stats(TR.pixel_angles(out, r.truth, sel))["median"]
            res_[v].setdefault(f"{r.stats}/{r.light}", []).append(a)
    print(split)
    for v in VARIANTS:
        print(f"{v:10s}", " / ".join(f"{np.median(res_[v][c]):5.2f}" for c in CONDS))


def charts():
    """The charts' mean gray-patch angle of each variant (``../s10/common.py``,
    which restores each chart photo; the input is caught on its way in)."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s10"))
    import common
    orig = uwhl_rs.restore
    seen = {}

    def restore(img, **k):
        seen["input"] = np.asarray(img, np.float64)
        seen["res"] = orig(img, **k)
        return seen["res"]
    common.uwhl_rs.restore = restore

    def make(res, obj, v):
        out = reblend(res, seen["input"], obj, v)
        return res.image if out is None else out
    common.charts(VARIANTS, make)


def photos(outpng):
    """Contact sheet: the four photos of issue 31, today against each variant."""
    from uwhl_rs import images
    from PIL import Image
    names = ["uwhl_ship_highres_input.jpg", "uieb_616.png", "udc_hazed5.jpg", "uwhl_Ancuti2_input.jpg",
             "chart_calib_1_under.png", "chart_calib_2_under.jpg", "chart_calib_3_under.jpg"]
    rows = []
    for n in names:
        img, _ = images.read_image(os.path.join("/work/shared/data/images", n))
        s = max(1, int(np.ceil(max(img.shape[:2]) / 480)))
        img = np.ascontiguousarray(img[::s, ::s])
        res = uwhl_rs.restore(img)
        I = np.asarray(img, np.float64)
        tiles = [np.clip(img, 0, 1) ** (1 / 2.2)]
        for v in ("today", "cap1", "gate0.05"):
            out = reblend(res, I, ~res.veiling_mask, v)
            out = res.image if out is None else out
            tiles.append(np.clip(out, 0, 1) ** (1 / 2.2))
        h = 200
        row = [np.asarray(Image.fromarray((t * 255).astype(np.uint8)).resize((int(t.shape[1] * h / t.shape[0]), h))) for t in tiles]
        rows.append(np.concatenate(row, 1))
    wmax = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 4), (0, wmax - r.shape[1]), (0, 0))) for r in rows]
    Image.fromarray(np.concatenate(rows, 0)).save(outpng)


if __name__ == "__main__":
    if sys.argv[1] == "charts":
        charts()
    elif sys.argv[1] == "photos":
        photos(sys.argv[2])
    else:
        renders(sys.argv[1])
