"""The balance of J (METHOD §12.1) is an existing keyword: measured with the core itself."""
import sys, numpy as np
sys.path.insert(0, '..')
import uwhl_rs, exp, harness as H

def core(wb=None, true_type=False, fb=None):
    def f(r, st):
        kw = {}
        if wb: kw['white_balance'] = wb
        if fb: kw['fallback'] = fb
        if true_type: kw['water_types'] = [r.water_type]
        res = uwhl_rs.restore(r.image, **kw)
        facts = {"rho": exp.rho(r, res.transmission)}
        if not true_type:
            facts["steps"] = abs(H.TYPES.index(res.water_type) - H.TYPES.index(r.water_type))
        return res.image, facts
    return f

cands = {"default": core(), "default_gw": core("gray_world"), "default_wp": core("white_patch"),
         "true_type": core(true_type=True), "true_type_gw": core("gray_world", True), "true_type_wp": core("white_patch", True),
         "true_type_gw_nofb": core("gray_world", True, "none")}
if __name__ == "__main__":
    exp.run(cands, every=1, out="out/bal_1.json")
