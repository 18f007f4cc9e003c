"""Independent NumPy/SciPy reference implementation of uwhl.

Underwater single-image color restoration with haze-lines (Berman, Levy,
Avidan & Treibitz, TPAMI 2020), following ../shared/docs/METHOD.md and every
detail pinned down in docs/METHOD.md.  Written for clarity, not speed:
it is the cross-check for the Rust core and the performance baseline.

Conventions: images are H x W x 3 float arrays (R, G, B), masks are bool
H x W arrays (True = the pixel is used for estimation, None = all True).
Everything is computed in float64.
"""

import math

import numpy as np
from scipy import ndimage

# ---------------------------------------------------------------------------
# S1 water types: (name, beta_BR, beta_BG)
# ---------------------------------------------------------------------------

WATER_TYPES = [
    ("I", 0.1118, 0.4566),
    ("IA", 0.1452, 0.5499),
    ("IB", 0.1745, 0.6341),
    ("II", 0.2773, 0.7937),
    ("III", 0.4051, 0.9539),
    ("1C", 0.4642, 1.0930),
    ("3C", 0.6515, 1.1244),
    ("5C", 1.0000, 1.2725),
    ("7C", 1.4500, 1.4022),
    ("9C", 2.0708, 1.5942),
]

K_NOISE = 0.6
EDGE_TAU_MIN = 0.005
EDGE_TARGET_SIZE = 512
VL_MIN_FRACTION = 0.001
A_MIN = 1e-4
T_TILDE_MIN = 0.01
T_TILDE_SCALE = 0.9
T_LB_MIN = 0.1


# ---------------------------------------------------------------------------
# Input checks
# ---------------------------------------------------------------------------

def _as_image(img):
    img = np.asarray(img)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image must be H x W x 3, got shape {img.shape}")
    h, w = img.shape[:2]
    if h * w < 2:
        raise ValueError(f"image must have at least 2 pixels, got {h} x {w}")
    img = img.astype(np.float64)
    if not np.all(np.isfinite(img)):
        raise ValueError("image contains NaN or Inf")
    return img


def _as_mask(mask, shape):
    if mask is None:
        return np.ones(shape, dtype=bool)
    mask = np.asarray(mask)
    if mask.shape != tuple(shape):
        raise ValueError(f"mask must have shape {tuple(shape)}, got {mask.shape}")
    return mask.astype(bool)


# ---------------------------------------------------------------------------
# P. percentiles
# ---------------------------------------------------------------------------

def pct(values, q):
    """Linear-interpolation percentile for a fraction q (METHOD conventions, percentiles)."""
    x = np.sort(np.asarray(values, dtype=np.float64).ravel())
    n = x.size
    if n == 0:
        raise ValueError("pct of an empty set")
    h = q * (n - 1)
    lo = int(math.floor(h))
    hi = int(math.ceil(h))
    return float(x[lo] + (h - lo) * (x[hi] - x[lo]))


# ---------------------------------------------------------------------------
# S3.1 contrast stretch and the guide image
# ---------------------------------------------------------------------------

def _global_minmax(img):
    """(I - min) / (max - min) over all pixels and channels; 0 if flat."""
    img = np.asarray(img, dtype=np.float64)
    lo = img.min()
    hi = img.max()
    if hi == lo:
        return np.zeros_like(img)
    return (img - lo) / (hi - lo)


def _masked_minmax(x, m):
    """Global min-max normalisation with min and max taken over the pixels
    where m is True (METHOD conventions, masks)."""
    sel = x[m]
    lo, hi = sel.min(), sel.max()
    if hi == lo:
        return np.zeros_like(x)
    return (x - lo) / (hi - lo)


def stretch_image(img, mask=None):
    img = _as_image(img)
    m = _as_mask(mask, img.shape[:2])
    x = _masked_minmax(img, m)
    out = x.copy()
    for c in range(3):
        lo = pct(x[:, :, c][m], 0.01)
        hi = pct(x[:, :, c][m], 0.99)
        if hi - lo > 1e-12:
            out[:, :, c] = np.clip((x[:, :, c] - lo) / (hi - lo), 0.0, 1.0)
    return out


def guide_image(img, mask=None):
    g = stretch_image(img, mask) ** (1.0 / 2.2)
    m = _as_mask(mask, g.shape[:2])
    g[~m] = 0.0
    return g


# ---------------------------------------------------------------------------
# Box filters (clipped windows)
# ---------------------------------------------------------------------------

def _box_sum_axis(x, r, axis):
    """Sum over [i - r, i + r] clipped to [0, n - 1] along one axis."""
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    n = x.shape[0]
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)], axis=0)
    i = np.arange(n)
    lo = np.maximum(i - r, 0)
    hi = np.minimum(i + r, n - 1)
    out = c[hi + 1] - c[lo]
    return np.moveaxis(out, 0, axis)


def box_sum(x, r):
    x = np.asarray(x, dtype=np.float64)
    return _box_sum_axis(_box_sum_axis(x, r, 0), r, 1)


def box_count(shape, r):
    return box_sum(np.ones(shape), r)


def box_mean(x, r):
    x = np.asarray(x, dtype=np.float64)
    return box_sum(x, r) / box_count(x.shape, r)


# ---------------------------------------------------------------------------
# S6 guided filter (He et al., color guide)
# ---------------------------------------------------------------------------

def default_radius(h, w):
    """round(min(H, W) / 4), halves away from zero."""
    return int(math.floor(min(h, w) / 4.0 + 0.5))


def guide_stats(guide, r, eps):
    """Everything that depends only on the guide: means and (Sigma + eps U)^-1."""
    guide = np.asarray(guide, dtype=np.float64)
    h, w = guide.shape[:2]
    n = box_count((h, w), r)

    def mean(x):
        return box_sum(x, r) / n

    mean_i = np.stack([mean(guide[:, :, c]) for c in range(3)], axis=-1)
    sigma = np.empty((h, w, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            v = mean(guide[:, :, i] * guide[:, :, j]) - mean_i[:, :, i] * mean_i[:, :, j]
            sigma[:, :, i, j] = v
            sigma[:, :, j, i] = v
    inv = np.linalg.inv(sigma + eps * np.eye(3))
    return {"guide": guide, "r": r, "n": n, "mean_i": mean_i, "inv": inv}


def guided_filter_stats(stats, p):
    guide, r, n = stats["guide"], stats["r"], stats["n"]
    mean_i, inv = stats["mean_i"], stats["inv"]
    p = np.asarray(p, dtype=np.float64)

    def mean(x):
        return box_sum(x, r) / n

    mean_p = mean(p)
    cov_ip = np.stack([mean(guide[:, :, c] * p) - mean_i[:, :, c] * mean_p
                       for c in range(3)], axis=-1)
    a = np.einsum("hwij,hwj->hwi", inv, cov_ip)
    b = mean_p - np.sum(a * mean_i, axis=-1)
    mean_a = np.stack([mean(a[:, :, c]) for c in range(3)], axis=-1)
    mean_b = mean(b)
    return np.sum(mean_a * guide, axis=-1) + mean_b


def guided_filter(guide, p, r, eps):
    return guided_filter_stats(guide_stats(guide, r, eps), p)


# ---------------------------------------------------------------------------
# S3 edge map helpers
# ---------------------------------------------------------------------------

def downscale(img, s):
    """Block averages of s x s pixels; partial border blocks average what they hold."""
    img = np.asarray(img, dtype=np.float64)
    if s == 1:
        return img.copy()
    h, w = img.shape[:2]
    ys = np.arange(0, h, s)
    xs = np.arange(0, w, s)
    sums = np.add.reduceat(np.add.reduceat(img, ys, axis=0), xs, axis=1)
    ones = np.ones((h, w))
    counts = np.add.reduceat(np.add.reduceat(ones, ys, axis=0), xs, axis=1)
    if img.ndim == 3:
        counts = counts[:, :, None]
    return sums / counts


def gaussian_kernel(sigma, radius):
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-x ** 2 / (2.0 * sigma ** 2))
    return k / k.sum()


def _correlate_axis_replicate(x, k, axis):
    """1-D correlation along `axis` with odd kernel k, replicate border."""
    r = (len(k) - 1) // 2
    x = np.moveaxis(x, axis, 0)
    n = x.shape[0]
    out = np.zeros_like(x)
    for j, kj in enumerate(k):
        idx = np.clip(np.arange(n) + j - r, 0, n - 1)
        out += kj * x[idx]
    return np.moveaxis(out, 0, axis)


def gaussian_blur(img, sigma, radius):
    """Separable Gaussian: along rows (x) first, then along columns (y)."""
    img = np.asarray(img, dtype=np.float64)
    k = gaussian_kernel(sigma, radius)
    out = _correlate_axis_replicate(img, k, 1)
    return _correlate_axis_replicate(out, k, 0)


def sobel_magnitude(img2d):
    """sqrt(gx^2 + gy^2) / 8 with replicate border for one channel."""
    p = np.pad(np.asarray(img2d, dtype=np.float64), 1, mode="edge")
    h, w = img2d.shape
    def sh(dy, dx):
        return p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
    gx = (sh(-1, 1) - sh(-1, -1)) + 2.0 * (sh(0, 1) - sh(0, -1)) + (sh(1, 1) - sh(1, -1))
    gy = (sh(1, -1) - sh(-1, -1)) + 2.0 * (sh(1, 0) - sh(-1, 0)) + (sh(1, 1) - sh(-1, 1))
    return np.sqrt(gx ** 2 + gy ** 2) / 8.0


def noise_sigma(small):
    """Immerkaer Laplacian noise estimate (robust, lower-quartile form), max over channels."""
    small = np.asarray(small, dtype=np.float64)
    h, w = small.shape[:2]
    if h < 3 or w < 3:
        return 0.0
    m = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
    best = 0.0
    for c in range(small.shape[2]):
        x = small[:, :, c]
        lap = np.zeros((h - 2, w - 2))
        for i in range(3):
            for j in range(3):
                lap += m[i, j] * x[i:i + h - 2, j:j + w - 2]
        sig = pct(np.abs(lap), 0.25) / (6.0 * 0.3186393639643752)
        best = max(best, sig)
    return best


def edge_map(img):
    """Returns (E, tau, s): small-size edge strength (max over channels),
    threshold, downscale factor."""
    img = _as_image(img)
    h, w = img.shape[:2]
    n = _global_minmax(img)
    s = max(1, int(math.ceil(max(h, w) / EDGE_TARGET_SIZE)))
    small = downscale(n, s)
    blurred = gaussian_blur(small, 1.0, 3)
    e = np.max(np.stack([sobel_magnitude(blurred[:, :, c]) for c in range(3)]), axis=0)
    tau = min(max(EDGE_TAU_MIN, K_NOISE * noise_sigma(small)), 0.02)
    return e, tau, s


def largest_component(binary):
    """Largest 8-connected component; ties go to the earliest first pixel (raster)."""
    binary = np.asarray(binary, dtype=bool)
    labels, count = ndimage.label(binary, structure=np.ones((3, 3), dtype=int))
    if count == 0:
        return np.zeros_like(binary)
    flat = labels.ravel()
    sizes = np.bincount(flat, minlength=count + 1)
    first = np.full(count + 1, flat.size, dtype=np.int64)
    np.minimum.at(first, flat, np.arange(flat.size))
    best = None
    for lab in range(1, count + 1):
        key = (-sizes[lab], first[lab])
        if best is None or key < best[0]:
            best = (key, lab)
    return labels == best[1]


# ---------------------------------------------------------------------------
# S3 veiling light A and the water region VL
# ---------------------------------------------------------------------------

def luminance(img):
    img = np.asarray(img, dtype=np.float64)
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def detect_vl_region(img, mask=None):
    """Steps 1-8: VL at full size (before the size test of step 9)."""
    img = _as_image(img)
    h, w = img.shape[:2]
    m = _as_mask(mask, (h, w))
    e, tau, s = edge_map(img)
    hs = e.shape[0]
    textureless = e < tau
    textureless[int(math.ceil(hs / 4.0)):, :] = False
    small_vl = largest_component(textureless)
    ys = np.arange(h) // s
    xs = np.arange(w) // s
    vl = small_vl[ys[:, None], xs[None, :]]
    return vl & m


def fallback_veiling_light(img):
    img = _as_image(img)
    h, w = img.shape[:2]
    s = max(1, int(math.ceil(max(h, w) / EDGE_TARGET_SIZE)))
    small = downscale(img, s)
    hs, ws = small.shape[:2]
    sigma = max(hs, ws) / 20.0
    radius = int(math.ceil(3.0 * sigma))
    blurred = gaussian_blur(small, sigma, radius)
    top = blurred[:int(math.ceil(hs / 2.0))].reshape(-1, 3)
    y = luminance(top)
    n = y.size
    order = np.lexsort((np.arange(n), -y))
    k = max(1, int(math.ceil(VL_MIN_FRACTION * n)))
    return top[order[:k]].mean(axis=0)


def detect_veiling(img, mask=None, water_mask=None, veiling_light=None):
    img = _as_image(img)
    h, w = img.shape[:2]
    m = _as_mask(mask, (h, w))
    flags = []
    if water_mask is not None:
        vl = _as_mask(water_mask, (h, w)) & m
    else:
        vl = detect_vl_region(img, m)
    region_a = None
    if vl.any():
        pix = img[vl]
        y = luminance(pix)
        idx = np.flatnonzero(vl.ravel())
        order = np.lexsort((idx, y))
        region_a = pix[order[(len(order) - 1) // 2]].copy()
        if water_mask is None:
            # METHOD §3 step 9: a detected region darker than 0.2 x the
            # median luminance of the masked-in pixels is a shadow.
            ym = luminance(img[m].reshape(-1, 3))
            med = np.sort(ym)[(ym.size - 1) // 2]
            if luminance(region_a[None, :])[0] < 0.2 * med:
                region_a = None
    if vl.sum() < max(2.0, VL_MIN_FRACTION * h * w) or region_a is None:
        vl = np.zeros((h, w), dtype=bool)
        region_a = None
        flags.append("no_water_region")

    if veiling_light is not None:
        a = np.asarray(veiling_light, dtype=np.float64).reshape(-1)
        if a.size != 3 or not np.all(np.isfinite(a)) or np.any(a <= 0) or np.any(a > 1):
            raise ValueError("veiling_light must be 3 values in (0, 1]")
    elif region_a is not None:
        a = region_a
    else:
        flags.append("veiling_fallback")
        a = fallback_veiling_light(img)

    clamped = np.maximum(a, A_MIN)
    if np.any(clamped != a):
        flags.append("veiling_light_clamped")
    if not clamped[0] < max(clamped[1], clamped[2]):
        flags.append("veiling_light_not_water")  # the project's diagnostic (METHOD §3), no pixel changes
    return {"A": [float(v) for v in clamped], "vl": vl, "flags": flags}


# ---------------------------------------------------------------------------
# S4 haze-lines
# ---------------------------------------------------------------------------

def sphere_points(n):
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    rho = np.sqrt(1.0 - z ** 2)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def nearest_point(points, u, chunk=4096):
    """Brute force: index of the nearest point (squared Euclidean distance)
    for every row of u; ties go to the lowest index (np.argmin)."""
    points = np.asarray(points, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    out = np.empty(u.shape[0], dtype=np.int64)
    for start in range(0, u.shape[0], chunk):
        uc = u[start:start + chunk]
        d = ((uc[:, None, 0] - points[None, :, 0]) ** 2
             + (uc[:, None, 1] - points[None, :, 1]) ** 2
             + (uc[:, None, 2] - points[None, :, 2]) ** 2)
        out[start:start + chunk] = np.argmin(d, axis=1)
    return out


def fill_masked(t, mask):
    """Normalised convolution with growing radius (1, 2, 4, ...)."""
    t = np.asarray(t, dtype=np.float64).copy()
    mask = np.asarray(mask, dtype=bool)
    if mask.all():
        return t
    if not mask.any():
        raise ValueError("fill_masked: no masked-in pixel to fill from")
    wgt = mask.astype(np.float64)
    wt = np.where(mask, t, 0.0)
    unfilled = ~mask
    rad = 1
    while unfilled.any():
        num = box_sum(wt, rad)
        den = box_sum(wgt, rad)
        sel = unfilled & (den > 0)
        t[sel] = num[sel] / den[sel]
        unfilled &= ~sel
        rad *= 2
    return t


def _compensated(img, a, beta_br, beta_bg):
    d = np.asarray(a, dtype=np.float64)[None, None, :] - img
    v = np.empty_like(d)
    v[..., 0] = np.sign(d[..., 0]) * np.abs(d[..., 0]) ** beta_br
    v[..., 1] = np.sign(d[..., 1]) * np.abs(d[..., 1]) ** beta_bg
    v[..., 2] = d[..., 2]
    return v


def haze_lines(img, A, beta_br, beta_bg, n_points=500, mask=None):
    img = _as_image(img)
    h, w = img.shape[:2]
    m = _as_mask(mask, (h, w))
    v = _compensated(img, A, beta_br, beta_bg)[m]
    r = np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2 + v[:, 2] ** 2)
    t_in = np.ones(r.size)
    pos = r > 0
    if pos.any():
        u = v[pos] / r[pos, None]
        k = nearest_point(sphere_points(n_points), u)
        rmax = np.zeros(n_points)
        np.maximum.at(rmax, k, r[pos])
        t_in[pos] = np.clip(r[pos] / rmax[k], T_TILDE_MIN, 1.0)
    t = np.zeros((h, w))
    t[m] = t_in
    t = fill_masked(t, m)
    return t * T_TILDE_SCALE


# ---------------------------------------------------------------------------
# S5 lower bound and matting
# ---------------------------------------------------------------------------

def lower_bound(img, A, beta_br, beta_bg):
    img = _as_image(img)
    a = np.asarray(A, dtype=np.float64)
    lr = np.maximum(1.0 - img[..., 0] / a[0], 0.0) ** beta_br
    lg = np.maximum(1.0 - img[..., 1] / a[1], 0.0) ** beta_bg
    lb = np.maximum(1.0 - img[..., 2] / a[2], 0.0)
    return np.maximum(np.maximum(np.maximum(lr, lg), lb), T_LB_MIN)


def mahalanobis_sq(img, vl, mask=None):
    img = _as_image(img)
    h, w = img.shape[:2]
    sel = np.asarray(vl, dtype=bool) & _as_mask(mask, (h, w))
    if sel.sum() < 2:
        return None
    x = img[sel]
    mu = x.mean(axis=0)
    c = np.cov(x, rowvar=False, ddof=1)
    lam = 1e-6 * np.trace(c) / 3.0 + 1e-12
    cinv = np.linalg.inv(c + lam * np.eye(3))
    d = img - mu[None, None, :]
    return np.einsum("hwi,ij,hwj->hw", d, cinv, d)


def matting_weights(img, vl, mask=None):
    d = mahalanobis_sq(img, vl, mask)
    if d is None:
        return None
    img = np.asarray(img)
    sel = np.asarray(vl, dtype=bool) & _as_mask(mask, img.shape[:2])
    dv = d[sel]
    m = dv.mean()
    s = dv.std(ddof=1)
    big = dv.max()
    thr_water = m + 2.0 * s
    thr_notwater = big + s
    if thr_notwater > thr_water:
        return 1.0 - np.clip((d - thr_water) / (thr_notwater - thr_water), 0.0, 1.0)
    return np.where(d <= thr_water, 1.0, 0.0)


# ---------------------------------------------------------------------------
# S6 masked-out regions after the filter
# ---------------------------------------------------------------------------

def chart_fill(q, mask):
    q = np.asarray(q, dtype=np.float64).copy()
    mask = np.asarray(mask, dtype=bool)
    h, w = mask.shape
    labels, count = ndimage.label(~mask, structure=np.ones((3, 3), dtype=int))
    for lab in range(1, count + 1):
        region = labels == lab
        below = np.zeros_like(mask)
        below[1:, :] = region[:-1, :]
        below &= mask
        src = below
        if not src.any():
            above = np.zeros_like(mask)
            above[:-1, :] = region[1:, :]
            src = above & mask
        if not src.any():
            src = ndimage.binary_dilation(region, structure=np.ones((3, 3), bool)) & mask
        if src.any():
            q[region] = q[src].mean()
    return q


# ---------------------------------------------------------------------------
# S7 recovery, S8 display stretch
# ---------------------------------------------------------------------------

def recover(img, A, t_refined, beta_br, beta_bg, mask=None):
    img = _as_image(img)
    m = _as_mask(mask, img.shape[:2])
    a = np.asarray(A, dtype=np.float64)
    t_b = np.clip(np.asarray(t_refined, dtype=np.float64), 0.1 ** beta_br, 1.0)
    t_r = np.clip(t_b ** (1.0 / beta_br), 0.1, 1.0)
    t_g = np.clip(t_b ** (1.0 / beta_bg), 0.1, 1.0)
    t = np.stack([t_r, t_g, t_b], axis=-1)
    d = a[None, None, :] - img
    j = a[None, None, :] - d / t
    j = j - max(j[m].min(), -0.08)
    j = np.maximum(j, 0.0)
    top = j[m].max()
    if top > 0:
        j = j / min(top, 1.6)
    j = np.minimum(j, 1.0)
    return {"J": j, "t_B": t_b, "t_R": t_r, "t_G": t_g}


def display_stretch(J, mask=None):
    J = np.asarray(J, dtype=np.float64)
    m = _as_mask(mask, J.shape[:2])
    x = _masked_minmax(J, m)
    out = np.empty_like(x)
    for c in range(3):
        lo = min(pct(x[..., c][m], 0.001), 0.2)
        hi = max(pct(x[..., c][m], 0.999), 0.9 if c == 0 else 0.8)
        out[..., c] = np.clip((x[..., c] - lo) / (hi - lo), 0.0, 1.0)
    return out


# ---------------------------------------------------------------------------
# S9 selection
# ---------------------------------------------------------------------------

def select(stretched_list, tR_list, vl, mask, names):
    vl = np.asarray(vl, dtype=bool)
    m = _as_mask(mask, vl.shape)
    vl = vl & m
    has_vl = bool(vl.any())
    counted = m & ~vl
    flags = []
    scores = {}
    score_list = []
    for name, img in zip(names, stretched_list):
        img = np.asarray(img, dtype=np.float64)
        if counted.any():
            means = img[counted].mean(axis=0)
            sc = float(np.std(means, ddof=1))
        else:
            sc = float("nan")
        scores[name] = sc
        score_list.append(sc)

    n = len(names)
    survive = [True] * n
    if has_vl:
        diffs = []
        for tr in tR_list:
            tr = np.asarray(tr, dtype=np.float64)
            dc = tr[counted].mean() if counted.any() else float("nan")
            diffs.append(dc - tr[vl].mean())
        thr = 0.1
        found = False
        for _ in range(31):
            cand = [not (dd < thr) for dd in diffs]
            if any(cand):
                survive = cand
                found = True
                break
            thr /= 2.0
        if not found:
            survive = [True] * n
            flags.append("exclusion_relaxed")

    winner = None
    best = None
    for i in range(n):
        if not survive[i]:
            continue
        sc = score_list[i]
        key = sc if np.isfinite(sc) else float("inf")
        if best is None or key < best:
            best = key
            winner = i
    excluded = [names[i] for i in range(n) if not survive[i]]
    return {"winner": names[winner], "winner_index": winner, "scores": scores,
            "excluded": excluded, "flags": flags}


# ---------------------------------------------------------------------------
# The whole method
# ---------------------------------------------------------------------------

def _resolve_types(water_types):
    if water_types is None:
        return list(WATER_TYPES)
    table = {name: (name, br, bg) for name, br, bg in WATER_TYPES}
    out = []
    for wt in water_types:
        if isinstance(wt, str):
            if wt not in table:
                raise ValueError(f"unknown water type {wt!r}")
            out.append(table[wt])
        else:
            name, br, bg = wt
            if not (br > 0 and bg > 0):
                raise ValueError("water type ratios must be positive")
            out.append((str(name), float(br), float(bg)))
    if not out:
        raise ValueError("no water type given")
    return out


def restore(img, water_types=None, veiling_light=None, water_mask=None, mask=None,
            guided_radius=None, guided_eps=1e-3, sphere_points=500):
    img = _as_image(img)
    h, w = img.shape[:2]
    m = _as_mask(mask, (h, w))
    if not m.any():
        raise ValueError("mask has no True pixel")
    types = _resolve_types(water_types)
    radius = default_radius(h, w) if guided_radius is None else int(guided_radius)

    det = detect_veiling(img, m, water_mask, veiling_light)
    a, vl = det["A"], det["vl"]
    flags = list(det["flags"])
    if vl.sum() >= m.sum():
        raise ValueError("water_mask covers every pixel used for estimation")

    wgt = matting_weights(img, vl, m)
    stats = guide_stats(guide_image(img, m), radius, guided_eps)
    has_holes = not m.all()

    names, stretched, t_rs, results = [], [], [], []
    for name, br, bg in types:
        t_tilde = haze_lines(img, a, br, bg, n_points=sphere_points, mask=m)
        t_lb = lower_bound(img, a, br, bg)
        t = np.maximum(t_tilde, t_lb)
        if wgt is not None:
            t = wgt * t_lb + (1.0 - wgt) * t
        q = guided_filter_stats(stats, t)
        if has_holes:
            q = chart_fill(q, m)
        rec = recover(img, a, q, br, bg, m)
        names.append(name)
        stretched.append(display_stretch(rec["J"], m))
        t_rs.append(rec["t_R"])
        results.append(rec)

    sel = select(stretched, t_rs, vl, m, names)
    i = sel["winner_index"]
    flags += sel["flags"]
    return {
        "image": stretched[i],
        "radiance": results[i]["J"],
        "transmission": results[i]["t_B"],
        "transmission_red": results[i]["t_R"],
        "water_type": names[i],
        "scores": sel["scores"],
        "veiling_light": a,
        "veiling_mask": vl,
        "flags": flags,
        "excluded": sel["excluded"],
    }
