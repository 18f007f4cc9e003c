import json, sys, numpy as np

from clpick import pick
from uwhl_rs import images
d = json.load(open('out/charts/results.json'))
man = json.load(open('../../eval/charts.json'))
tot = {}
for im, ent in zip(d['images'], man['images']):
    img, _ = images.read_image('../../eval/' + ent['path'])
    ign = np.zeros(img.shape[:2], bool)
    for ch in ent['charts']:
        for (x0, y0, x1, y1) in ch['region']: ign[y0:y1, x0:x1] = True
    masked = img.copy(); masked[ign] = np.nan
    a = np.asarray(im['veiling_light'], float)
    p, sc, n = pick(img, a=a)
    rows = {(r['method'], r['chart']): r['psi_deg'] for r in im['charts']}
    for ch in ent['charts']:
        for m in ['input', 'grayworld', 'revised', f'type:{p}']:
            tot.setdefault(m if not m.startswith('type') else 'colour-lines', []).append(rows[(m, ch['name'])])
    print(ent['path'].split('/')[-1], 'revised type', im['water_type'], 'colour-lines', p, n, {k: round(v, 2) for k, v in sc.items()})
for k, v in tot.items(): print(k, np.round(v, 1), 'mean', round(float(np.mean(v)), 2))
