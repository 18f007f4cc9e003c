"""Scores against a known radiance: per-pixel angles to the truth (METHOD §11).

A restored image is compared with the true radiance J of the scene (the
object's colours under white light), pixel by pixel, as the angle between the
two RGB vectors. The angle ignores each pixel's brightness but not its colour,
so a white balance is part of what is scored. ``best_gains`` gives the floor
that any global per-channel balance of the same output could reach.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pixel_angles", "angle_stats", "best_gains", "score"]

#: Truth pixels darker than this (sum of R, G, B, linear) carry no colour
#: worth scoring: their angle is dominated by quantisation and noise.
MIN_TRUTH_SUM = 0.02


def pixel_angles(out: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Angles in degrees between ``out`` and ``truth`` (both H x W x 3) at the valid pixels.

    A black output pixel (all channels 0) has no colour and scores 90
    degrees: a restoration that loses a pixel is not rewarded for it.
    """
    o = np.asarray(out, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    if valid is not None:
        keep = np.asarray(valid, dtype=bool).reshape(-1)
        o, t = o[keep], t[keep]
    on = np.linalg.norm(o, axis=1)
    tn = np.linalg.norm(t, axis=1)
    cos = np.einsum("ij,ij->i", o, t) / np.maximum(on * tn, 1e-300)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    ang[on <= 0] = 90.0
    return ang


def angle_stats(angles: np.ndarray) -> dict:
    """Median and 90th percentile of per-pixel angles (NaN when empty)."""
    if angles.size == 0:
        return {"median": float("nan"), "p90": float("nan")}
    return {"median": float(np.median(angles)), "p90": float(np.percentile(angles, 90))}


def best_gains(out: np.ndarray, truth: np.ndarray, valid: np.ndarray, samples: int = 4000, seed: int = 0) -> np.ndarray:
    """The global per-channel gains (G fixed at 1) that minimise the median angle.

    Found by Nelder-Mead over log(g_R), log(g_B) from the least-squares
    gains, on at most ``samples`` valid pixels drawn with a fixed seed.
    This is the best any white balance of ``out`` can do.
    """
    from scipy.optimize import minimize

    o = np.asarray(out, dtype=np.float64).reshape(-1, 3)[np.asarray(valid).reshape(-1)]
    t = np.asarray(truth, dtype=np.float64).reshape(-1, 3)[np.asarray(valid).reshape(-1)]
    if len(o) == 0:
        return np.ones(3)
    if len(o) > samples:
        pick = np.random.default_rng(seed).choice(len(o), samples, replace=False)
        o, t = o[pick], t[pick]
    ls = np.einsum("ij,ij->j", o, t) / np.maximum(np.einsum("ij,ij->j", o, o), 1e-300)
    ls = np.where(ls > 0, ls, 1.0)
    ls = ls / ls[1]

    def cost(x):
        g = np.array([np.exp(x[0]), 1.0, np.exp(x[1])])
        return float(np.median(pixel_angles(o * g, t)))

    x0 = np.log(np.clip([ls[0], ls[2]], 1e-6, 1e6))
    best = minimize(cost, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-3, "maxiter": 200})
    x = best.x if best.fun <= cost(x0) else x0
    return np.array([np.exp(x[0]), 1.0, np.exp(x[1])])


def score(out: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None, gains: bool = True) -> dict:
    """Angles of ``out`` to ``truth``: raw and after the best global per-channel gains.

    ``valid`` defaults to the pixels whose truth is bright enough to have a
    colour (``MIN_TRUTH_SUM``). Returns ``median``, ``p90`` and, with
    ``gains``, ``gain_median`` and ``gain_p90``.
    """
    truth = np.asarray(truth, dtype=np.float64)
    ok = truth.sum(axis=2) > MIN_TRUTH_SUM
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool)
    res = angle_stats(pixel_angles(out, truth, ok))
    if gains:
        g = best_gains(out, truth, ok)
        st = angle_stats(pixel_angles(np.asarray(out, dtype=np.float64) * g, truth, ok))
        res["gain_median"], res["gain_p90"] = st["median"], st["p90"]
    return res
