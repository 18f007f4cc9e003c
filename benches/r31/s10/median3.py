"""Three estimates of the light on the core's display, combined by their
median (prototype): shades of gray (p = 4; the display is already
balanced by it, so its gains are near 1), gray world (p = 1) and the
brightest TOP of object pixels (`bright.py`); each channel's log gain is
the median of the three, exposure kept. Renders of a split, or `charts`."""
import sys, os, numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bright import bright_gains

def gains(e):
    e = np.maximum(e, 1e-9)
    return e.mean() / e

def combined(img, objects, top, how):
    px = img[objects & (img.max(-1) < 0.995)]
    if len(px) < 20:
        return img
    g_sog = gains((px ** 4).mean(0) ** 0.25)
    g_gw = gains(px.mean(0))
    g_br = bright_gains(img, objects, top)
    L = np.log(np.stack([g_sog, g_gw, g_br]))
    if how == "median":
        g = np.exp(np.median(L, 0))
    else:  # medoid: the estimate nearest the other two
        D = np.abs(L[:, None, :] - L[None, :, :]).sum(-1).sum(-1)
        g = np.exp(L[int(np.argmin(D))])
    out = img * g
    k = np.quantile(img.max(-1), 0.99) / max(np.quantile(out.max(-1), 0.99), 1e-9)
    return np.clip(out * k, 0, 1)

VARIANTS = [None, (0.05, "median"), (0.05, "medoid"), (0.02, "median")]
if __name__ == "__main__":
    from common import renders, charts
    make = lambda r, objects, v: r.image if v is None else combined(r.image, objects, *v)
    charts(VARIANTS, make) if sys.argv[1] == "charts" else renders(sys.argv[1], VARIANTS, make)
