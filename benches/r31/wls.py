"""Weighted least squares regularisation of a transmission (Berman, Treibitz &
Avidan, CVPR 2016, Eq. of the regularisation step), from the equations:

    min_t  sum_x w(x) (t(x) - t0(x))^2 + lam sum_x sum_{y in N4(x)} (t(x) - t(y))^2 / (|I(x) - I(y)|^2 + e)
"""
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl


def laplacian(guide, e=1e-4, power=2.0):
    h, w = guide.shape[:2]
    g = guide.reshape(h, w, -1).astype(np.float64)
    idx = np.arange(h * w).reshape(h, w)
    # horizontal and vertical edges
    dh = ((g[:, 1:] - g[:, :-1]) ** 2).sum(-1)
    dv = ((g[1:, :] - g[:-1, :]) ** 2).sum(-1)
    wh = 1.0 / (dh ** (power / 2) + e)
    wv = 1.0 / (dv ** (power / 2) + e)
    i = np.concatenate([idx[:, :-1].ravel(), idx[:-1, :].ravel()])
    j = np.concatenate([idx[:, 1:].ravel(), idx[1:, :].ravel()])
    ww = np.concatenate([wh.ravel(), wv.ravel()])
    n = h * w
    A = sp.coo_matrix((np.concatenate([-ww, -ww]), (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(n, n)).tocsr()
    d = np.asarray(-A.sum(axis=1)).ravel()
    return A + sp.diags(d), ww.mean()


def solve(t0, wdata, L, lam):
    n = t0.size
    M = sp.diags(wdata.ravel()) + lam * L
    b = wdata.ravel() * t0.ravel()
    x = spl.spsolve(M.tocsc(), b)
    return x.reshape(t0.shape)
