"""NumPy prototype of METHOD §13.2 (the tile-slope fit along the Jerlov curve) and variants.

Only for research on issue 32: the reference is src/method/distance.rs; `fit_tiles` mirrors it
(f = 1 at 360 px) so that variants can be compared against the same baseline.
"""

from __future__ import annotations

import numpy as np

from uwhl_rs import synth

TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
JER = np.array([synth.JERLOV[t] for t in TYPES])  # (beta_BR, beta_BG)
LNJ = np.log(JER)
GRID = np.exp(np.linspace(np.log(1e-3), np.log(5.0), 481))
LNG = np.log(GRID)
U = -1.0 + 0.05 * np.arange(221)
TILE = 8


def curve(u):
    u = np.asarray(u, dtype=np.float64)
    i = np.clip(np.floor(np.maximum(u, 0)).astype(int), 0, len(TYPES) - 2)
    f = u - i
    return LNJ[i] + (LNJ[i + 1] - LNJ[i]) * f[..., None]


def known(z):
    return np.isfinite(z) & (z > 0) & (z <= 1000)


def usable(img, z, mask=None):
    """The pixels the fit may use: a known distance, a finite image, inside the mask."""
    ok = known(z) & np.all(np.isfinite(img), axis=2)
    return ok if mask is None else ok & mask


def tiles(ok, tile=TILE, stride=None):
    """(y0, x0, usable pixels of the tile, their count) for the full tiles of `ok`
    with at least half their pixels usable, in raster order."""
    h, w = ok.shape
    stride = stride or tile
    for y0 in range(0, h - tile + 1, stride):
        for x0 in range(0, w - tile + 1, stride):
            k = ok[y0:y0 + tile, x0:x0 + tile]
            n = k.sum()
            if n >= tile * tile // 2:
                yield y0, x0, k, n


def grown_window(ok, z, y0, x0, tile, win):
    """The plane design (1, dy, dx from the tile's centre) and the known z
    over the tile at (y0, x0) grown by ``win`` pixels (clipped)."""
    h, w = z.shape
    ya, yb, xa, xb = max(0, y0 - win), min(h, y0 + tile + win), max(0, x0 - win), min(w, x0 + tile + win)
    kw = ok[ya:yb, xa:xb]
    gy, gx = np.mgrid[ya:yb, xa:xb].astype(np.float64)
    gy -= y0 + (tile - 1) / 2
    gx -= x0 + (tile - 1) / 2
    return np.stack([np.ones(kw.sum()), gy[kw], gx[kw]], 1), z[ya:yb, xa:xb][kw].astype(np.float64)


def tile_slope(ii, zz, zm, vz, n):
    """One tile's means, least-squares slopes on z (variance ``vz``),
    residual variances and weight (METHOD §13.2 step 2)."""
    im = ii.mean(0)
    s = ((zz - zm)[:, None] * (ii - im)).mean(0) / vz
    r = ii - im - s * (zz - zm)[:, None]
    vr = (r ** 2).mean(0)
    return im, s, vr, np.sqrt(np.median(n * vz / np.maximum(vr, 1e-8)))


def tile_stats(img, z, mask=None, tile=TILE, plane=True, stride=None, eiv=False, win=0, eiv_min=0.25):
    """Per tile: means m (n,3), slopes s (n,3), weight w (n,), z-bar, var z, residual var (n,3), centre (y,x).

    eiv: subtract the plane's own noise from var(z) (errors in variables): the planed z holds
    2 sigma^2 / n of noise variance, sigma^2 from the plane's residual; tiles whose corrected
    var(z) is below eiv_min of the raw one are dropped. win: fit the plane over the tile grown
    by win pixels on each side (more pixels against noise in z)."""
    h, w = z.shape
    ok = usable(img, z, mask)
    dy, dx = np.mgrid[0:tile, 0:tile].astype(np.float64) - (tile - 1) / 2
    out = {k: [] for k in ("m", "s", "w", "zm", "vz", "vr", "yx", "n")}
    for y0, x0, k, n in tiles(ok, tile, stride):
        zz = z[y0:y0 + tile, x0:x0 + tile][k].astype(np.float64)
        ii = img[y0:y0 + tile, x0:x0 + tile][k].astype(np.float64)
        noise_v = 0.0
        if plane:
            X = np.stack([np.ones(n), dy[k], dx[k]], 1)
            if win:
                Xw, zw = grown_window(ok, z, y0, x0, tile, win)
                coef, *_ = np.linalg.lstsq(Xw, zw, rcond=None)
                res = zw - Xw @ coef
                s2 = (res ** 2).sum() / max(len(zw) - 3, 1)
                cov = s2 * np.linalg.inv(Xw.T @ Xw)
            else:
                coef, *_ = np.linalg.lstsq(X, zz, rcond=None)
                res = zz - X @ coef
                s2 = (res ** 2).sum() / max(n - 3, 1)
                cov = s2 * np.linalg.inv(X.T @ X)
            zz = X @ coef
            # noise variance of the planed z about its mean: the slope coefficients' noise
            Xc = X[:, 1:] - X[:, 1:].mean(0)
            noise_v = np.trace(Xc.T @ Xc @ cov[1:, 1:]) / n
        zm = zz.mean()
        vz = ((zz - zm) ** 2).mean()
        if vz <= 1e-12:
            continue
        if eiv:
            vc = vz - noise_v
            if vc < eiv_min * vz:
                continue
            vz_raw, vz = vz, vc
        im, s, vr, w = tile_slope(ii, zz, zm, vz, n)
        out["m"].append(im)
        out["s"].append(s)
        out["w"].append(w)
        out["zm"].append(zm)
        out["vz"].append(vz)
        out["vr"].append(vr)
        out["yx"].append((y0 + tile / 2, x0 + tile / 2))
        out["n"].append(n)
    return {k: np.array(v) for k, v in out.items()}


def wmedian_rows(Y, w):
    """Weighted median of each row of Y (same weights), the Rust rule (first reaching half)."""
    order = np.argsort(Y, axis=1, kind="stable")
    ys = np.take_along_axis(Y, order, 1)
    cw = np.cumsum(w[order], axis=1)
    k = np.argmax(cw >= 0.5 * w.sum(), axis=1)
    return ys[np.arange(len(Y)), k]


def lad_costs(s, m, w, grid=GRID):
    Y = s[None, :] + grid[:, None] * m[None, :]
    kap = wmedian_rows(Y, w)
    cost = (w[None, :] * np.abs(Y - kap[:, None])).sum(1)
    return cost, kap


def curve_search(costs, kaps, U=U):
    """Joint search along the curve; costs: list of 3 arrays over GRID. Returns beta, A, total cost."""
    lb = LNG
    pos = lambda l: np.clip((l - LNG[0]) / (LNG[-1] - LNG[0]) * (len(GRID) - 1), 0, len(GRID) - 1)
    idx = np.arange(len(GRID))
    c = curve(U)  # (nu, 2)
    tot = (np.interp(pos(lb[None, :] - c[:, 0:1]), idx, costs[0])
           + np.interp(pos(lb[None, :] - c[:, 1:2]), idx, costs[1]) + costs[2][None, :])
    iu, kb = np.unravel_index(np.argmin(tot), tot.shape)
    bb = GRID[kb]
    beta = np.array([bb / np.exp(c[iu, 0]), bb / np.exp(c[iu, 1]), bb])
    a = np.array([np.interp(pos(np.log(beta[ch])), idx, kaps[ch]) / beta[ch] for ch in range(3)])
    return beta, a, tot.min(), tot


def fit_tiles(img, z, mask=None, weights=None, ts=None, plane=True):
    """The core's fit (METHOD §13.2) in NumPy."""
    if ts is None:
        ts = tile_stats(img, z, mask, plane=plane)
    w = ts["w"] if weights is None else weights
    cs = [lad_costs(ts["s"][:, c], ts["m"][:, c], w) for c in range(3)]
    beta, a, tot, _ = curve_search([c[0] for c in cs], [c[1] for c in cs])
    return beta, a, ts


def beta_true(r, BETA_B):
    bb = BETA_B[r.water_type]
    br, bg = synth.JERLOV[r.water_type]
    return np.array([bb / br, bb / bg, bb])


def nearest_type(beta):
    x = np.log(beta[2] / beta[0]), np.log(beta[2] / beta[1])
    d = np.hypot(LNJ[:, 0] - x[0], LNJ[:, 1] - x[1])
    return TYPES[int(np.argmin(d))]


def tile_pixels(img, z, mask=None, tile=TILE, plane=True):
    """Raw tiles: Z (n,P) planed z, I (n,P,3), K (n,P) known; plus the core's stats (same tiles)."""
    dy, dx = np.mgrid[0:tile, 0:tile].astype(np.float64) - (tile - 1) / 2
    Zs, Is, Ks, yx = [], [], [], []
    for y0, x0, k, n in tiles(usable(img, z, mask), tile):
        zz = np.where(k, z[y0:y0 + tile, x0:x0 + tile], 0).astype(np.float64)
        if plane:
            X = np.stack([np.ones(n), dy[k], dx[k]], 1)
            coef, *_ = np.linalg.lstsq(X, zz[k], rcond=None)
            zz = coef[0] + coef[1] * dy + coef[2] * dx
        zk = zz[k]
        if ((zk - zk.mean()) ** 2).mean() <= 1e-12:
            continue
        Zs.append(zz.ravel())
        Is.append(img[y0:y0 + tile, x0:x0 + tile].reshape(-1, 3).astype(np.float64))
        Ks.append(k.ravel())
        yx.append((y0, x0))
    return np.array(Zs), np.array(Is), np.array(Ks), np.array(yx)


def exact_y(Z, I, K, beta):
    """y_i(beta) = beta (m_i - b_i ubar_i): the level's intercept at z = inf times beta, with
    b_i the slope of I on u = e^(-beta z) inside tile i (exact form of s + beta m)."""
    Kf = K.astype(np.float64)
    n = Kf.sum(1)
    u = np.exp(-beta * Z) * Kf
    ub = u.sum(1) / n
    du = (u - ub[:, None]) * Kf
    vu = (du ** 2).sum(1) / n
    out = np.empty((len(Z), 3))
    for c in range(3):
        Ic = I[:, :, c] * Kf
        m = Ic.sum(1) / n
        cov = (du * (Ic - m[:, None] * Kf)).sum(1) / n
        b = cov / np.maximum(vu, 1e-300)
        out[:, c] = beta * (m - b * ub)
    return out


def exact_costs(Z, I, K, w, grid=GRID, amax=None):
    """Per channel, per grid beta: LAD cost of y_i(beta) about its (clamped) weighted median, and kappa."""
    Y = np.empty((len(grid), len(Z), 3))
    for k, b in enumerate(grid):
        Y[k] = exact_y(Z, I, K, b)
    costs, kaps = [], []
    for c in range(3):
        kap = wmedian_rows(Y[:, :, c], w)
        if amax is not None:
            kap = np.clip(kap, 0, grid * amax)
        costs.append((w[None, :] * np.abs(Y[:, :, c] - kap[:, None])).sum(1))
        kaps.append(kap)
    return costs, kaps


def lin_costs_clamped(ts, w, amax):
    costs, kaps = [], []
    for c in range(3):
        Y = ts["s"][None, :, c] + GRID[:, None] * ts["m"][None, :, c]
        kap = np.clip(wmedian_rows(Y, w), 0, GRID * amax)
        costs.append((w[None, :] * np.abs(Y - kap[:, None])).sum(1))
        kaps.append(kap)
    return costs, kaps


def suspect(ts, beta, z, w=None):
    """The core's rule: optical depth < 0.3 or residual > 0.995."""
    w = ts["w"] if w is None else w
    fit = null = 0.0
    for c in range(3):
        y = ts["s"][:, c] + beta[c] * ts["m"][:, c]
        k = wmedian_rows(y[None, :], w)[0]
        fit += (w * np.abs(y - k)).sum()
        k0 = wmedian_rows(ts["s"][None, :, c], w)[0]
        null += (w * np.abs(ts["s"][:, c] - k0)).sum()
    zk = z[known(z)]
    od = beta.max() * (np.percentile(zk, 95, method="nearest") - np.percentile(zk, 5, method="nearest"))
    return bool(od < 0.3 or fit / null > 0.995), fit / null, od


def ls_curve(ts, w, keep):
    """Weighted least squares of y = s + beta m against kappa, along the curve (costs = weighted SSE)."""
    costs, kaps = [], []
    ww = w * keep
    for c in range(3):
        Y = ts["s"][None, :, c] + GRID[:, None] * ts["m"][None, :, c]
        kap = (Y * ww).sum(1) / ww.sum()
        costs.append((ww * (Y - kap[:, None]) ** 2).sum(1))
        kaps.append(kap)
    return costs, kaps


def second_pass(ts, beta, k=2.5, mode="lad", wpow=1.0):
    """Tiles whose y at the first fit lies within k robust sigmas of kappa in every channel, refitted."""
    w = ts["w"]
    keep = np.ones(len(w), bool)
    for c in range(3):
        y = ts["s"][:, c] + beta[c] * ts["m"][:, c]
        kap = wmedian_rows(y[None, :], w)[0]
        r = y - kap
        mad = wmedian_rows(np.abs(r)[None, :], w)[0] * 1.4826
        keep &= np.abs(r) <= k * mad
    if mode == "lad":
        cs = [lad_costs(ts["s"][keep, c], ts["m"][keep, c], w[keep] ** wpow) for c in range(3)]
        b, a, _, _ = curve_search([x[0] for x in cs], [x[1] for x in cs])
    else:
        cs, ks = ls_curve(ts, w ** wpow, keep)
        b, a, _, _ = curve_search(cs, ks)
    return b, a, keep


def norm_search(ts, w):
    """Each channel's LAD cost divided by its cost at beta = 0 before the joint search."""
    cs = [lad_costs(ts["s"][:, c], ts["m"][:, c], w) for c in range(3)]
    costs = [x[0] / x[0][0] for x in cs]
    b, a, _, _ = curve_search(costs, [x[1] for x in cs])
    return b, a
