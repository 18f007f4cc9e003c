import sys, json, os, numpy as np
sys.path.insert(0, "/work/main/benches"); sys.path.insert(0, "/work/main/benches/r31"); sys.path.insert(0, __import__("os").path.dirname(__file__))
import harness as H, uwhl_rs
from exp_noshift import finish
from uwhl_rs import images, evaluate as ev
man = json.load(open("/work/main/benches/eval/charts.json"))
tot = {}
for e in man["images"]:
    p = os.path.normpath(os.path.join("/work/main/benches/eval", e["path"]))
    img, _ = images.read_image(p)
    res = uwhl_rs.restore(img); wt = res.water_type
    st = H.Image(img); q = st.default_q(wt)
    outs = {"input": img, "gw": ev.grayworld(img), "core": res.image}
    for m in (True, "neutral", "E0.1L", "E0.1M", "E0.2M"):
        outs[str(m)] = finish(st, wt, q, m)[0]
    for ch in e["charts"]:
        c = ev.Chart(ch["name"], [tuple(b) for b in ch["gray_patches"]], [tuple(b) for b in ch["region"]]) if hasattr(ev, "Chart") else None
        line = []
        for k, im in outs.items():
            a = np.mean([ev.angle_deg(ev._patch_mean(im, b)) for b in ch["gray_patches"]])
            tot.setdefault(k, []).append(a); line.append(f"{k}={a:.1f}")
        print(os.path.basename(p), ch["name"], wt, " ".join(line))
print("mean", " ".join(f"{k}={np.mean(v):.1f}" for k, v in tot.items()))
