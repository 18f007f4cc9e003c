import json, sys, numpy as np
import fit as F
recs = json.load(open(sys.argv[1]))
def err(b, bt): return np.max(np.abs(np.array(b)/np.array(bt)-1))
d = [r for r in recs if r['var']=='distance']
print("numpy vs core beta max rel diff:", max(np.max(np.abs(np.array(r['bnp'])/np.array(r['bf'])-1)) for r in d if 'bf' in r))
conds = ["gray/white","gray/tinted","own/white","own/tinted"]
print("per cond medians: core | oracle(true water, core search) | oracle(true water, true d) | np fit dcore | np fit true d")
for c in conds:
    s=[r for r in d if r['cond']==c]
    print(c, *[f"{np.median([r[k] for r in s]):.1f}" for k in ['core','oracle_t_dcore','oracle_t_dtrue','np_dcore','np_dtrue']],
          "used", sum(r['used'] for r in s))
print("beta err by geometry (distance var, np fit): median, share<=10%")
for g in sorted(set(r['geom'] for r in d)):
    s=[err(r['bnp'],r['bt']) for r in d if r['geom']==g]
    print(g, len(s), f"{np.median(s):.2f}", sum(e<=.1 for e in s))
print("by type")
for t in F.TYPES:
    s=[r for r in d if r['type']==t]
    e=[err(r['bnp'],r['bt']) for r in s]
    ch=np.median([np.array(r['bnp'])/np.array(r['bt']) for r in s],0)
    print(t, f"{np.median(e):.2f}", sum(x<=.1 for x in e), "median ratio per ch", np.round(ch,2), "types", [F.nearest_type(np.array(r['bnp'])) for r in s])
for v in ['distance','distance_holes','distance_noise']:
    s=[r for r in recs if r['var']==v and 'bf' in r]
    print(v, "core beta err<=10%", sum(err(r['bf'],r['bt'])<=.1 for r in s), "of", len(s), "median ratio", np.round(np.median([np.array(r['bf'])/np.array(r['bt']) for r in s],0),2))
print("d chosen: core on tinted", np.percentile([r['d_np'] for r in d if 'tinted' in r['cond']],[10,50,90]), "white", np.percentile([r['d_np'] for r in d if 'white' in r['cond']],[10,50,90]))
for c in conds:
    s=[r for r in d if r['cond']==c]
    print(c, "d_np by content", {k: [r['d_np'] for r in s if r['content']==k] for k in sorted(set(r['content'] for r in s))})
