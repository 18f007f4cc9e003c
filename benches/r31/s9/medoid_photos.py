import sys, glob, os, numpy as np
import uwhl_rs
from uwhl_rs import images
from PIL import Image, ImageDraw
TY = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
def chroma(x, m):
    y = np.maximum(x[m].astype(np.float64), 1e-6); return y / y.sum(1, keepdims=True)
def srgb(x):
    x = np.clip(x, 0, 1); return (np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255).astype(np.uint8)
rows = []
for p in sorted(glob.glob("/work/shared/data/images/*")):
    if p.endswith(".mat"): continue
    img, _ = images.read_image(p)
    s = int(np.ceil(max(img.shape[:2]) / 480)); h, w = (img.shape[0] // s) * s, (img.shape[1] // s) * s
    img = np.ascontiguousarray(img[:h, :w].reshape(h // s, s, w // s, s, 3).mean((1, 3)), np.float32)
    r = uwhl_rs.restore(img)
    sc = np.array([r.scores[t] for t in TY]); best3 = np.argsort(sc)[:3]
    disps = {k: uwhl_rs.restore(img, water_types=[TY[k]]).image for k in best3}
    m = np.ones(img.shape[:2], bool)
    ch = {k: chroma(disps[k], m) for k in best3}
    pick = min(best3, key=lambda a: sum(np.median(np.abs(ch[a] - ch[b]).sum(1)) for b in best3))
    name = os.path.basename(p)
    print(name, r.water_type, "->", TY[pick], "fs", round(r.fallback_share or 0, 2))
    if TY[pick] != r.water_type:
        rows.append((name, r.water_type, TY[pick], [srgb(img), srgb(r.image), srgb(disps[pick])]))
W = 240
hs = [int(x[3][0].shape[0] * W / x[3][0].shape[1]) + 14 for x in rows]
S = Image.new("RGB", (3 * W, max(1, sum(hs))), "white"); y = 0
for (name, a, b, ims), hh in zip(rows, hs):
    d = ImageDraw.Draw(S)
    for i, im in enumerate(ims):
        S.paste(Image.fromarray(im).resize((W, hh - 14)), (i * W, y + 14))
    d.text((2, y + 1), name[:22], fill="black"); d.text((W + 2, y + 1), f"today {a}", fill="black"); d.text((2 * W + 2, y + 1), f"medoid {b}", fill="black")
    y += hh
S.save(sys.argv[1] if len(sys.argv) > 1 else "/tmp/s9/medoid_photos.png")
