import json, numpy as np
TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
rows = json.load(open('out/types.json'))
def rate(rule, split):
    res = {}
    for r in rows:
        if r['split'] != split: continue
        c = rule(r); k = abs(TYPES.index(c) - TYPES.index(r['true']))
        res.setdefault(r['cond'], []).append((k == 0, k <= 1, TYPES.index(c) - TYPES.index(r['true'])))
    return ' '.join(f"{c}:{sum(a for a,_,_ in v)}/{sum(b for _,b,_ in v)}/{len(v)} bias{np.mean([s for *_,s in v]):+.1f}" for c, v in sorted(res.items()))
def sog(r): return min(TYPES, key=lambda t: r['scores'][t])
def ve_first(th):
    def f(r):
        ok = [t for t in TYPES if r['ve'][t] <= th]
        return ok[0] if ok else TYPES[-1]
    return f
def sog_ve(th):
    def f(r):
        ok = [t for t in TYPES if r['ve'][t] <= th] or [TYPES[-1]]
        return min(ok, key=lambda t: r['scores'][t])
    return f
for split in ['tune', 'held']:
    print(split)
    print(' sog      ', rate(sog, split))
    for th in [0.02, 0.05, 0.1, 0.2]:
        print(f' vefirst{th}', rate(ve_first(th), split))
        print(f' sog_ve{th} ', rate(sog_ve(th), split))
# ve profile for a few
for r in rows[:12]:
    print(r['true'], r['chosen'], ' '.join(f"{r['ve'][t]:.2f}" for t in TYPES))
