import numpy as np
from PIL import Image, ImageDraw
def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
def tile(x, gray=False, lin=True, lo=None, hi=None):
    x = np.asarray(x, np.float64)
    if x.ndim == 2:
        lo = np.nanmin(x) if lo is None else lo; hi = np.nanmax(x) if hi is None else hi
        x = np.clip((x - lo) / max(hi - lo, 1e-9), 0, 1)
        x = np.repeat(x[..., None], 3, axis=2)
        lin = False
    if lin: x = srgb(x)
    return (np.clip(x, 0, 1) * 255).astype(np.uint8)
def sheet(rows, path, labels=None):
    """rows: list of lists of uint8 tiles (same size)."""
    h, w = rows[0][0].shape[:2]
    nc = max(len(r) for r in rows)
    out = np.full((len(rows) * (h + 14), nc * (w + 4), 3), 255, np.uint8)
    im = Image.fromarray(out); d = ImageDraw.Draw(im)
    for i, r in enumerate(rows):
        for j, t in enumerate(r):
            t = np.asarray(Image.fromarray(t).resize((w, h)))
            im.paste(Image.fromarray(t), (j * (w + 4), i * (h + 14) + 14))
            if labels and i < len(labels) and j < len(labels[i]):
                d.text((j * (w + 4) + 2, i * (h + 14)), labels[i][j], fill=(0, 0, 0))
    im.save(path)
