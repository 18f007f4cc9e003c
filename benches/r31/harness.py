"""Issue 31 research harness: the revised profile's transmission stages from
the frozen build's `_core._stage_*` hooks, and the downstream steps
(recovery §7, white balance §12.1, fallback §12.5) in NumPy, so that a
candidate transmission can be scored exactly as the default would show it.

Throwaway research code (not part of the library).
"""
from __future__ import annotations

import numpy as np
from uwhl_rs import _core as C
from uwhl_rs import synth

JER = synth.JERLOV
TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
FLOOR = JER["3C"]
N_POINTS = 500
_PTS = None


def sphere_points():
    global _PTS
    if _PTS is None:
        _PTS, _ = C._stage_sphere(N_POINTS, np.zeros((1, 3), np.float32))
    return _PTS


def conditioned(wt):
    br, bg = JER[wt]
    return max(br, FLOOR[0]), max(bg, FLOOR[1])


class Image:
    """Per-image state: A, VL, matting weights, guide."""

    def __init__(self, img, a=None, water_mask=None):
        self.img = np.ascontiguousarray(img, np.float32)
        self.h, self.w = img.shape[:2]
        a_est, vl, flags = C._stage_veiling(self.img, None, water_mask, None if a is None else tuple(float(x) for x in a))
        self.a = np.array(a_est, np.float64)
        self.vl = np.asarray(vl, bool)
        self.flags = flags
        m = C._stage_matting(self.img, self.vl) if self.vl.sum() >= 2 else None
        self.wmat = None if m is None else np.asarray(m[1], np.float64)
        self.guide = np.asarray(C._stage_guide(self.img, None))
        self.radius = int(np.floor(min(self.h, self.w) / 4 + 0.5))
        self.objects = ~self.vl
        self.sigma = noise_sigma(self.img)

    def haze(self, wt):
        """Compensated radius, cluster and t_LB with the 3C floor's ratios (§4, §5, §12.3)."""
        br, bg = conditioned(wt)
        a = self.a
        d = a[None, None, :] - self.img.astype(np.float64)
        v = np.stack([np.sign(d[..., 0]) * np.abs(d[..., 0]) ** br,
                      np.sign(d[..., 1]) * np.abs(d[..., 1]) ** bg, d[..., 2]], axis=-1)
        r = np.linalg.norm(v, axis=-1)
        u = (v / np.maximum(r, 1e-12)[..., None]).reshape(-1, 3).astype(np.float32)
        _, near = C._stage_sphere(N_POINTS, u)
        k = np.asarray(near, np.int64).reshape(self.h, self.w)
        k[r <= 0] = -1
        lb = np.asarray(C._stage_lower_bound(self.img, tuple(float(x) for x in a), br, bg), np.float64)
        return v, r, k, lb

    def t_tilde(self, r, k, rmax):
        t = np.ones_like(r)
        ok = k >= 0
        t[ok] = np.clip(r[ok] / np.maximum(rmax[k[ok]], 1e-12), 0.01, 1.0)
        return t

    def blend(self, tt, lb, scale=0.9):
        """p of METHOD §5: max(scale t~, t_LB), pulled to t_LB by the matting weight."""
        t = np.maximum(tt * scale, lb)
        if self.wmat is not None:
            t = self.wmat * lb + (1 - self.wmat) * t
        return t

    def guided(self, p):
        return np.asarray(C._stage_guided(self.guide, np.ascontiguousarray(p, np.float32), self.radius, 1e-3), np.float64)

    def default_q(self, wt):
        v, r, k, lb = self.haze(wt)
        rmax = np.zeros(N_POINTS)
        np.maximum.at(rmax, k[k >= 0], r[k >= 0])
        p = self.blend(self.t_tilde(r, k, rmax), lb)
        return self.guided(p)


def noise_sigma(img):
    """METHOD §12.5 step 1 (no subsampling at these sizes)."""
    x = img.astype(np.float64)
    out = np.zeros(3)
    for c in range(3):
        z = x[..., c]
        corners = z[:-2, :-2] + z[:-2, 2:] + z[2:, :-2] + z[2:, 2:]
        edges = z[:-2, 1:-1] + z[2:, 1:-1] + z[1:-1, :-2] + z[1:-1, 2:]
        out[c] = np.median(np.abs(corners - 2 * edges + 4 * z[1:-1, 1:-1])) / (6 * 0.6745)
    return out


def channel_t(tb, wt):
    br, bg = JER[wt]
    return np.stack([np.clip(tb ** (1 / br), 0.1, 1), np.clip(tb ** (1 / bg), 0.1, 1), tb], axis=-1)


def sog(x, valid, p=4.0):
    y = np.maximum(x[valid], 0)
    return (y ** p).mean(axis=0) ** (1 / p)


def gains_from(e):
    mu = e.mean()
    return np.where((e > 0) & (mu > 0), mu / np.where(e > 0, e, 1), 1.0)


def finish(st: Image, wt, q, fallback=True, scale_tb=None, balance='sog'):
    """METHOD §7 (clamp of t_B, recovery, artifact clamp), §12.1 (shades of gray,
    exposure) and §12.5 (trust and blend) for type ``wt`` and refined t ``q``.
    Returns (image, J clamped, t_B, veil excess)."""
    br, bg = JER[wt]
    tb = np.clip(q, 0.1 ** br, 1.0)
    if scale_tb is not None:
        tb = np.clip(tb ** scale_tb, 0.1 ** br, 1.0)
    t = channel_t(tb, wt)
    a = st.a
    img = st.img.astype(np.float64)
    j = a + (img - a) / t
    lo, hi = j.min(), j.max()
    shift = max(lo, -0.08)
    top = max(hi - shift, 0)
    div = min(top, 1.6)
    jc = np.maximum(j - shift, 0)
    if div > 0:
        jc = jc / div
    jc = np.minimum(jc, 1)
    obj = st.objects
    if balance == 'sog':
        g = gains_from(sog(jc, obj))
    else:
        g = path_gains(jc, obj, wt, p=float(balance.split(':')[1]))
    pct = np.array([np.quantile(jc[..., c], 0.99) for c in range(3)])
    top = (g * pct).max()
    k = g * (1 / top if top > 0 else 1)
    image = np.clip(jc * k, 0, 1)
    image, ve = trust_blend(st, image, j, t, g, fallback)
    return image, jc, tb, ve


def trust_blend(st: Image, image, j, t, g, fallback=True):
    """METHOD §12.5 on a displayed ``image`` made with the gains ``g`` from
    J (``j``, before the clamp) and the channel transmissions ``t``: the veil
    excess, and with ``fallback`` the blend toward the input's own balance.
    Returns (image, veil excess)."""
    img = st.img.astype(np.float64)
    obj = st.objects
    sig = st.sigma
    exc = ((t * j) < -sig).any(axis=-1)
    ve = exc[obj].mean()
    if fallback:
        wp = np.clip((ve - 0.02) / 0.18, 0, 1)
        kin = gains_from(sog(img, obj))
        shown = np.sqrt(((g * np.maximum(j, 0)) ** 2).sum(-1)).clip(1e-6)
        noise = ((g * sig / t) ** 2).sum(-1)
        theta = np.sqrt(2 / 3 * noise) / shown
        local = 1 / (1 + (theta / 0.15) ** 2)
        wgt = 1 - (1 - wp) * (1 - 0.3 * (1 - local))
        base = np.maximum(img * kin, 0)
        scale = image.sum(-1) / np.maximum(base.sum(-1), 1e-9)
        image = np.clip((1 - wgt[..., None]) * image + wgt[..., None] * base * scale[..., None], 0, 1)
    return image, ve


def path_gains(jc, valid, wt, p=4.0):
    """Gains that undo light which crossed x = beta_B d of the same water
    (E_c = exp(-beta_c d), METHOD §0), x >= 0 chosen so that the p-norm
    colour of the balanced J is grayest: one unknown instead of two."""
    br, bg = JER[wt]
    e = sog(jc, valid, p) if p != 1 else np.maximum(jc[valid], 0).mean(0)
    best = (np.inf, np.ones(3))
    for x in np.linspace(0, 4, 161):
        g = np.exp(x * np.array([1 / br, 1 / bg, 1.0]))
        c = g * e
        sp = np.std(c, ddof=1) / c.mean()
        if sp < best[0]:
            best = (sp, g)
    g = best[1]
    return g * (e.mean() / np.maximum((g * e).mean(), 1e-12))


def spread(jc, valid):
    m = sog(jc, valid)
    return np.std(m, ddof=1) / m.mean() if m.mean() > 0 else np.inf
