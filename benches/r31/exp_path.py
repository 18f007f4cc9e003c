"""Balance along the water's own light curve (one unknown) instead of free shades-of-gray gains."""
import sys, numpy as np
sys.path.insert(0, '..')
import uwhl_rs, exp, harness as H

CORE = {}
def core(r, true_type):
    key = (r.name, true_type)
    if key not in CORE:
        CORE.clear() if len(CORE) > 4 else None
        res = uwhl_rs.restore(r.image, **({'water_types': [r.water_type]} if true_type else {}))
        CORE[key] = res
    return CORE[key]

def make(bal, true_type):
    def f(r, st):
        res = core(r, true_type)
        im, jc, tb, ve = H.finish(st, res.water_type, np.asarray(res.transmission, np.float64), balance=bal)
        facts = {} if true_type else {"steps": abs(H.TYPES.index(res.water_type) - H.TYPES.index(r.water_type))}
        return im, facts
    return f

cands = {"default (harness)": make('sog', False), "default, path p4": make('path:4', False), "default, path p1": make('path:1', False),
         "true type (harness)": make('sog', True), "true type, path p4": make('path:4', True), "true type, path p1": make('path:1', True)}
if __name__ == "__main__":
    exp.run(cands, every=1, out="out/path_1.json")
