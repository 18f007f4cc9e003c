import sys, glob, os, numpy as np
sys.path.insert(0,'..')
from clpick import pick, block
import uwhl_rs, viz
from uwhl_rs import images
rows, labels = [], []
for p in sorted(glob.glob('../../../../shared/data/images/*')):
    if p.endswith(('.mat', '.md')) or '_above' in p: continue
    img, _ = images.read_image(p)
    small = np.ascontiguousarray(block(np.asarray(img, np.float64), 400), np.float32)
    r0 = uwhl_rs.restore(small)
    pk, sc, n = pick(small, a=np.asarray(r0.veiling_light, float))
    r1 = uwhl_rs.restore(small, water_types=[pk])
    print(os.path.basename(p), 'today', r0.water_type, 'cl', pk, n, ' '.join(f'{sc[t]:.2f}' for t in sc), flush=True)
    if pk != r0.water_type:
        rows.append([viz.tile(small), viz.tile(r0.image), viz.tile(r1.image)])
        labels.append([os.path.basename(p)[:26], f'today {r0.water_type}', f'colour-lines {pk}'])
viz.sheet(rows, 'out/photos_cl.png', labels)
