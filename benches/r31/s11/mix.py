"""A fixed share m of the input's shades-of-gray balance mixed into every
displayed pixel on top of the fallback of METHOD §12.5 (the blend's weight
becomes 1 - (1 - w)(1 - m)): does averaging two estimates with partly
independent errors beat both on the renders and the charts?"""
import sys, os
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s10"))
import common

MS = (0.0, 0.15, 0.3, 0.5, 1.0)

def make(r, obj, m):
    D = np.asarray(r.image, np.float64)
    I = np.asarray(r.input if hasattr(r, "input") else make.inp, np.float64)
    e = np.array([np.mean(np.maximum(I[..., c][obj], 0) ** 4) ** 0.25 for c in range(3)])
    B = I / np.maximum(e, 1e-9)
    B = B * (D.sum(2, keepdims=True) / np.maximum(B.sum(2, keepdims=True), 1e-9))
    return np.clip((1 - m) * D + m * B, 0, 1)

if __name__ == "__main__":
    import uwhl_rs
    orig = uwhl_rs.restore
    def restore(img, **k):
        make.inp = img
        return orig(img, **k)
    uwhl_rs.restore = restore
    common.uwhl_rs.restore = restore
    if sys.argv[1] == "charts":
        common.charts(MS, make)
    else:
        common.renders(sys.argv[1], MS, make)
