"""Candidates for issue 31 on the tune split, side by side (true type given)."""
import sys, json, time, argparse, numpy as np
sys.path.insert(0, '..')
import truth as T
import harness as H
from uwhl_rs import truth as tr

def table(rows, names):
    conds = ["gray/white", "gray/tinted", "own/white", "own/tinted"]
    lines = ["| row | " + " | ".join(conds) + " |", "|---|" + "---|" * 4]
    for n in names:
        cells = []
        for c in conds:
            sel = [r for r in rows if r["row"] == n and r["cond"] == c]
            if not sel: cells.append('-'); continue
            cell = f"{np.median([r['median'] for r in sel]):.1f} ({np.median([r['gain'] for r in sel]):.1f})"
            st = [r['steps'] for r in sel if r.get('steps') is not None]
            if st: cell += f" type {sum(s==0 for s in st)}/{sum(s<=1 for s in st)}/{len(sel)}"
            rh = [r['rho'] for r in sel if r.get('rho') is not None]
            if rh: cell += f" rho {np.median(rh):.2f}"
            cells.append(cell)
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)

def rho(r, tb):
    obj = r.objects
    return float(np.corrcoef(r.distance[obj], -np.log(np.clip(tb[obj], 1e-6, 1)))[0, 1])

def run(cands, split='tune', every=1, out=None, conds=None, trueA=False):
    rows = []
    n = 0
    for r in T.scenes(split, 360):
        n += 1
        if (n - 1) % every: continue
        if conds and f"{r.stats}/{r.light}" not in conds: continue
        t0 = time.time()
        cond = f"{r.stats}/{r.light}"
        outs = {"input": (r.image, {}), "gray_world": (T.ev.grayworld(r.image), {})}
        st = H.Image(r.image, a=np.clip(r.a, 1e-4, 1) if trueA else None)
        for name, f in cands.items():
            got = f(r, st)
            outs[name] = got if isinstance(got, tuple) else (got, {})
        for name, (img, facts) in outs.items():
            s = tr.score(img, r.truth, r.objects, gains=True)
            row = {"scene": r.name, "cond": cond, "row": name, "median": s["median"], "gain": s["gain_median"], **facts}
            rows.append(row)
        print(r.name, f"{time.time()-t0:.1f}s", " ".join(f"{k}={[x for x in rows if x['scene']==r.name and x['row']==k][0]['median']:.1f}" for k in outs), file=sys.stderr, flush=True)
    if out:
        json.dump(rows, open(out, 'w'))
    print(table(rows, list(dict.fromkeys(r['row'] for r in rows))))
    return rows
