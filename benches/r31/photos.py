"""Real photos by eye: today's default against the candidates' transmissions."""
import sys, numpy as np
sys.path.insert(0, '..')
import uwhl_rs, harness as H, viz, exp_final
from uwhl_rs import images

class R:  # what q_for needs of a render
    def __init__(self, name): self.name = name

rows, labels = [], []
for name in ["uwhl_ship_highres_input.jpg", "uieb_616.png", "udc_hazed5.jpg", "uwhl_Ancuti2_input.jpg"]:
    img, _ = images.read_image(f"/work/shared/data/images/{name}")
    sdown = int(np.ceil(max(img.shape[:2]) / 480))
    h, w = (img.shape[0] // sdown) * sdown, (img.shape[1] // sdown) * sdown
    img = np.ascontiguousarray(img[:h, :w].reshape(h // sdown, sdown, w // sdown, sdown, 3).mean((1, 3)), np.float32)
    res = uwhl_rs.restore(img)
    st = H.Image(img)
    wt = res.water_type
    row = [viz.tile(img), viz.tile(res.image)]
    lab = [name[:28], f"default ({wt})"]
    qs = {}
    for kind in ("gf", "ccal1", "p95"):
        q = exp_final.q_for(kind, R(name), st, wt); qs[kind] = q
        im, _, _, ve = H.finish(st, wt, q)
        row.append(viz.tile(im)); lab.append(f"{kind} ({wt}) ve {ve:.2f}")
    row += [viz.tile(qs['gf'], lo=0, hi=1), viz.tile(qs['ccal1'], lo=0, hi=1)]
    lab += ["t_B gf", "t_B ccal1"]
    rows.append(row); labels.append(lab)
    print(name, wt, res.flags, file=sys.stderr)
viz.sheet(rows, "out/photos.png", labels)
