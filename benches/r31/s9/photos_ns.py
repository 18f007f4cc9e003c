import sys, numpy as np
sys.path.insert(0, "/work/main/benches"); sys.path.insert(0, "/work/main/benches/r31"); sys.path.insert(0, __import__("os").path.dirname(__file__))
import harness as H, uwhl_rs
from exp_noshift import finish
from uwhl_rs import images
from PIL import Image, ImageDraw
def srgb(x):
    x = np.clip(x, 0, 1); return (np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255).astype(np.uint8)
rows = []
for name in sys.argv[2:]:
    img, _ = images.read_image(f"/work/shared/data/images/{name}")
    s = int(np.ceil(max(img.shape[:2]) / float(__import__("os").environ.get("SIDE", "400")))); h, w = (img.shape[0] // s) * s, (img.shape[1] // s) * s
    img = np.ascontiguousarray(img[:h, :w].reshape(h // s, s, w // s, s, 3).mean((1, 3)), np.float32)
    res = uwhl_rs.restore(img); wt = res.water_type
    st = H.Image(img); q = st.default_q(wt)
    tiles = [img, res.image] + [finish(st, wt, q, m)[0] for m in ("neutral", "E0.1M", "E0.2M")]
    print(name, wt, [float(np.abs(tiles[1] - tiles[2]).max())], file=sys.stderr)
    rows.append((name, wt, [Image.fromarray(srgb(t)) for t in tiles]))
W = 260
labels = ["input", "core", "neutral", "E0.1M", "E0.2M"]
hs = [int(r[2][0].height * W / r[2][0].width) + 14 for r in rows]
S = Image.new("RGB", (5 * W, sum(hs)), "white"); y = 0
for (name, wt, ims), hh in zip(rows, hs):
    d = ImageDraw.Draw(S)
    for i, im in enumerate(ims):
        S.paste(im.resize((W, hh - 14)), (i * W, y + 14)); d.text((i * W + 2, y + 1), f"{labels[i]} {name[:18] if i == 0 else wt}", fill="black")
    y += hh
S.save(sys.argv[1])
