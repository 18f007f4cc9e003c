"""The water type from how edges fade with distance (METHOD §12.6, measured, not adopted).

Across an edge between neighbours at one distance, I_p - I_q = t_c (J_p - J_q): the veiling
light cancels. Over the object pixels binned by a distance proxy (12 quantile bins), the
RMS of neighbour differences per channel (less the noise's 2 sigma^2) falls as
ln C_c = -beta_c x + content; the slopes s_c over the bins are compared with each type's
(1/beta_BR, 1/beta_BG, 1): by direction (no content trend) or in the span of it and
(1, 1, 1) (a trend shared by the channels).

    python3 benches/r31/s12/edge_type.py SPLIT [true|lnt|rows] [true|none|mad|p10] [K]

proxy: the true distance (an oracle), -ln t_B of the default's restoration, or the row;
noise: the render's own sigma (an oracle), none, the MAD of a 2 x 2 second difference,
or the 10th percentile of 4 x 4 block RMS; K: block-average by K first."""
import sys, numpy as np
sys.path.insert(0, "/work/main/benches")
import truth as T
import uwhl_rs
INST = sys.argv[2] if len(sys.argv) > 2 else "true"
from uwhl_rs import synth
TY = T.TYPES
V = {t: np.array([1 / synth.JERLOV[t][0], 1 / synth.JERLOV[t][1], 1.0]) for t in TY}
split = sys.argv[1] if len(sys.argv) > 1 else "tune"
res = {}
for r in T.scenes(split, 360):
    I, z = r.image.astype(np.float64), r.distance; obj = np.isfinite(z)
    cond = f"{r.stats}/{r.light}"
    if INST != "true":
        rr = uwhl_rs.restore(r.image)
        tb = np.clip(rr.transmission, 1e-3, 1)
        z = np.where(obj & ~rr.veiling_mask, -np.log(tb), np.nan) if INST == "lnt" else np.where(obj & ~rr.veiling_mask, np.arange(z.shape[0])[::-1, None] * np.ones_like(z), np.nan)
    K = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    if K > 1:
        hh, ww = I.shape[0] // K * K, I.shape[1] // K * K
        I = I[:hh, :ww].reshape(hh // K, K, ww // K, K, 3).mean((1, 3))
        with np.errstate(invalid="ignore"):
            z = z[:hh, :ww].reshape(hh // K, K, ww // K, K).mean((1, 3))
    # horizontal and vertical neighbour differences at the same distance (same row: floor; wall varies along x)
    dx = I[:, 1:] - I[:, :-1]; zx = 0.5 * (z[:, 1:] + z[:, :-1]); mx = np.isfinite(z[:, 1:]) & np.isfinite(z[:, :-1])
    dy = I[1:] - I[:-1]; zy = 0.5 * (z[1:] + z[:-1]); my = np.isfinite(z[1:]) & np.isfinite(z[:-1])
    D = np.concatenate([dx[mx], dy[my]]); Z = np.concatenate([zx[mx], zy[my]])
    ok = np.isfinite(Z); D, Z = D[ok], Z[ok]
    NOISE = sys.argv[3] if len(sys.argv) > 3 else "true"
    if NOISE == "true":
        sig2 = 2 * r.noise ** 2 / K ** 2
    elif NOISE == "none":
        sig2 = 0.0
    elif NOISE == "p10":
        d2 = (I[:-1, :-1] - I[:-1, 1:] - I[1:, :-1] + I[1:, 1:]) / 2
        hh, ww = d2.shape[:2]
        b = d2[:hh // 4 * 4, :ww // 4 * 4].reshape(hh // 4, 4, ww // 4, 4, 3)
        sig = np.percentile(np.sqrt((b ** 2).mean((1, 3))).reshape(-1, 3), 10, axis=0) / 0.75
        sig2 = 2 * sig ** 2
    else:
        d2 = (I[:-1, :-1] - I[:-1, 1:] - I[1:, :-1] + I[1:, 1:]) / 2
        sig = 1.4826 * np.median(np.abs(d2.reshape(-1, 3)), axis=0)
        sig2 = 2 * sig ** 2
    qs = np.quantile(Z, np.linspace(0, 1, 13))
    zb, lc = [], []
    for a, b in zip(qs[:-1], qs[1:]):
        m = (Z >= a) & (Z <= b)
        if m.sum() < 200: continue
        ms = (D[m] ** 2).mean(0) - sig2
        if np.any(ms <= 1e-8): continue
        zb.append(np.median(Z[m])); lc.append(0.5 * np.log(ms))
    if len(zb) < 4:
        res.setdefault(cond, []).append((None, None)); continue
    zb = np.array(zb); lc = np.array(lc)
    s = -np.polyfit(zb, lc, 1)[0]  # per channel slope, = beta_c (+ content trend)
    # rule 1: direction of s against v (no shared trend)
    def ang(u, v): return np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))
    c1 = min(TY, key=lambda t: ang(s, V[t]))
    # rule 2: s = a v + g 1, residual
    def res2(t):
        M = np.stack([V[t], np.ones(3)], 1); co, *_ = np.linalg.lstsq(M, s, rcond=None); return np.linalg.norm(M @ co - s)
    c2 = min(TY, key=res2)
    res.setdefault(cond, []).append((T.type_steps(c1, r.water_type), T.type_steps(c2, r.water_type)))
    print(r.name, np.round(s, 3), r.water_type, c1, c2, file=sys.stderr)
for cond, v in res.items():
    n = len(v)
    w1 = sum(1 for a, b in v if a is not None and a <= 1); w2 = sum(1 for a, b in v if b is not None and b <= 1)
    e1 = sum(1 for a, b in v if a == 0)
    print(cond, n, "dir within1", w1, "exact", e1, "| affine within1", w2)
