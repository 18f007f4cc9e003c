"""Three candidates for the default's display and fallback (METHOD §12.8,
"Measured on 2026-12-05"), scored as the default would show them.

- ``family``: §12.1's free shades-of-gray gains replaced by gains along the
  chosen type's light curve, g_c = exp(x / beta_Bc), x from the estimate of
  the light's colour (gray world, gray edge, white patch) nearest that curve
  in log chromaticity, gray world's residual halved: §13.4's rule without a
  known distance. ``family_neg`` lets x go below 0 (a t_B too low casts red).
- ``local:p:frac``: §12.5's input balance B taken locally: each pixel
  divided by the Minkowski-p mean colour of the object pixels in a box of
  side frac x min(H, W) around it, for a cast that changes across the frame
  (uwhl_Ancuti2_input's green left and whiter right).
- ``clamp``: B's log chromaticity kept from going past neutral against the
  input's own cast (its component along that cast at least 0).

Usage (from this folder, RAYON_NUM_THREADS=1, a build with `internals`):
  python3 display_s7.py tune [STEP]    # medians per condition; out/display_s7_tune.json
  python3 display_s7.py photos OUT.png  # the four photos of issue 31, side by side
Throwaway research code (not part of the library).
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np
from scipy.ndimage import uniform_filter

sys.path.insert(0, '..')
sys.path.insert(0, '../r32')
import harness as H  # noqa: E402
from harness import JER, channel_t, gains_from, sog  # noqa: E402
from displab import box_edges, project  # noqa: E402


def family_gains(jc, obj, wt, lo=0.0, margin=0.5):
    br, bg = JER[wt]
    b = np.array([1 / br, 1 / bg, 1.0])
    px = jc[obj][::3]
    est = {'gw': px.mean(0), 'ge': box_edges(jc)[obj][::3].mean(0), 'wp': np.percentile(px, 99, axis=0)}
    best = None
    for k, v in est.items():
        x, res = project(np.maximum(v, 1e-9), b)
        res = res * margin if k == 'gw' else res
        if best is None or res < best[0]:
            best = (res, x)
    x = best[1] if lo is None else max(best[1], lo)
    g = np.exp(b * x)
    return g / g.mean()


def logchroma(x):
    lx = np.log(np.maximum(x, 1e-6))
    return lx - lx.mean(-1, keepdims=True)


def local_balance(img, obj, frac, p):
    size = max(3, int(min(img.shape[:2]) * frac) | 1)
    m = obj.astype(float)
    cnt = uniform_filter(m, size, mode='nearest')
    loc = np.stack([uniform_filter((np.maximum(img[..., c], 0) ** p) * m, size, mode='nearest') for c in range(3)], -1)
    loc = np.maximum(loc / np.maximum(cnt, 1e-6)[..., None], 1e-12) ** (1 / p)
    return img * (loc.mean(-1, keepdims=True) / loc)


def clamp_cast(base, cast, tau=0.0):
    u = logchroma(cast[None, :])[0]
    u = u / max(np.linalg.norm(u), 1e-9)
    lb = logchroma(base)
    d = np.minimum(lb @ u + tau, 0.0)
    e = np.exp(lb - d[..., None] * u)
    return e / e.sum(-1, keepdims=True) * base.sum(-1, keepdims=True)


def finish(st, wt, q, variant='today'):
    """§7, §12.1 and §12.5 as the core runs them (harness.finish), with one step swapped."""
    tb = np.clip(q, 0.1 ** JER[wt][0], 1.0)
    t = channel_t(tb, wt)
    img = st.img.astype(np.float64)
    j = st.a + (img - st.a) / t
    shift = max(j.min(), -0.08)
    div = min(max(j.max() - shift, 0), 1.6)
    jc = np.maximum(j - shift, 0)
    jc = np.minimum(jc / div if div > 0 else jc, 1)
    obj = st.objects
    if variant.startswith('family'):
        g = family_gains(jc, obj, wt, lo=None if variant == 'family_neg' else 0.0)
    else:
        g = gains_from(sog(jc, obj))
    pct = np.array([np.quantile(jc[..., c], 0.99) for c in range(3)])
    top = (g * pct).max()
    image = np.clip(jc * g * (1 / top if top > 0 else 1), 0, 1)
    ve = ((t * j) < -st.sigma).any(axis=-1)[obj].mean()
    wp = np.clip((ve - 0.02) / 0.18, 0, 1)
    shown = np.sqrt(((g * np.maximum(j, 0)) ** 2).sum(-1)).clip(1e-6)
    theta = np.sqrt(2 / 3 * ((g * st.sigma / t) ** 2).sum(-1)) / shown
    wgt = 1 - (1 - wp) * (1 - 0.3 * (1 - 1 / (1 + (theta / 0.15) ** 2)))
    cast = sog(img, obj)
    base = np.maximum(img * gains_from(cast), 0)
    if variant.startswith('local'):
        _, p, frac = variant.split(':')
        base = np.maximum(local_balance(img, obj, float(frac), float(p)), 0)
    elif variant == 'clamp':
        base = clamp_cast(base, cast)
    scale = image.sum(-1) / np.maximum(base.sum(-1), 1e-9)
    return np.clip((1 - wgt[..., None]) * image + wgt[..., None] * base * scale[..., None], 0, 1)


VARIANTS = ['today', 'family', 'family_neg', 'local:1:1.0', 'local:4:1.0', 'local:1:0.5', 'local:1:2.0', 'clamp']


def renders(split, step):
    import truth as T
    import uwhl_rs
    from uwhl_rs import truth as tr
    rows = []
    for i, r in enumerate(T.scenes(split, 360)):
        if i % step:
            continue
        res = uwhl_rs.restore(r.image)
        st = H.Image(r.image)
        row = {'name': r.name, 'cond': f'{r.stats}/{r.light}'}
        for tag, wt in (('', res.water_type), ('true ', r.water_type)):
            q = st.default_q(wt)
            for v in VARIANTS:
                if tag and not v.startswith(('today', 'family')):
                    continue
                row[tag + v] = tr.score(finish(st, wt, q, v), r.truth, r.objects, gains=False)['median']
        rows.append(row)
        print(i, r.name, file=sys.stderr)
    os.makedirs('out', exist_ok=True)
    json.dump(rows, open(f'out/display_s7_{split}.json', 'w'))
    conds = ['gray/white', 'gray/tinted', 'own/white', 'own/tinted']
    for k in [k for k in rows[0] if k not in ('name', 'cond')]:
        print(f'{k:18s}', ' | '.join(f"{np.median([r[k] for r in rows if r['cond'] == c]):5.1f}" for c in conds))


def photos(out):
    import uwhl_rs
    from PIL import Image

    def lin(u):
        return np.where(u <= 0.04045, u / 12.92, ((u + 0.055) / 1.055) ** 2.4)

    def srgb(x):
        x = np.clip(x, 0, 1)
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    rows = []
    for name in ('uwhl_Ancuti2_input.jpg', 'uwhl_ship_highres_input.jpg', 'uieb_616.png', 'udc_hazed5.jpg'):
        u = np.asarray(Image.open(os.path.join(H_DATA, name)).convert('RGB').resize((400, 300)), np.float32) / 255
        im = lin(u).astype(np.float32)
        wt = uwhl_rs.restore(im).water_type
        st = H.Image(im)
        q = st.default_q(wt)
        rows.append(np.concatenate([u] + [srgb(finish(st, wt, q, v)) for v in ('today', 'family', 'local:1:1.0', 'clamp')], 1))
    Image.fromarray((np.concatenate(rows, 0) * 255).astype(np.uint8)).save(out)


H_DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'shared', 'data', 'images')

if __name__ == '__main__':
    if sys.argv[1] == 'photos':
        photos(sys.argv[2])
    else:
        renders(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1)
