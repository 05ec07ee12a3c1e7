"""Robust statistics of intensity differences: M-estimator weights and cost, scale, inliers.

The estimator's iteratively reweighted least squares weights each difference by a Huber (or
Tukey) M-estimator with the scale from the differences' median absolute deviation; a
difference within :func:`inlier_bound` of zero counts as an inlier (the tracker's checks,
the rotation search's score, the overlay's colours). docs/algorithm.md section 3, "Robust
weights", and section 4, "Loss".
"""

from __future__ import annotations

import numpy as np

MAD_SAMPLES = 5000  # the robust scale's median is taken over at most about this many residuals


def mad_scale(r: np.ndarray, valid: np.ndarray | None = None) -> float:
    """Robust scale of residuals ``r`` (N,) (at ``valid``): 1.4826 x median |r|, over an evenly
    strided subset of about MAD_SAMPLES when N is larger (the scale only sets the weights' knee)."""
    step = max(1, len(r) // MAD_SAMPLES)
    sub = r[::step] if valid is None else r[::step][valid[::step]]
    return max(1.4826 * float(np.median(np.abs(sub))), 1e-3) if len(sub) else 1e-3


def robust_weights(r: np.ndarray, kind: str, *, huber_k: float, tukey_c: float,
                   scale: float | None = None) -> tuple[np.ndarray, float]:
    """IRLS weights (N,) float32 for residuals ``r`` and the robust scale (MAD, grey levels)."""
    if len(r) == 0:
        return np.ones(0, np.float32), 0.0
    if scale is None:
        scale = mad_scale(r)
    if kind == "none":
        return np.ones(len(r), np.float32), scale
    a = np.abs(r) * np.float32(1.0 / scale)
    if kind == "huber" and a.dtype == np.float32:  # the same operations, in place
        np.maximum(a, np.float32(1e-12), out=a)
        np.divide(np.float32(huber_k), a, out=a)
        w = np.minimum(a, np.float32(1.0), out=a)
    elif kind == "huber":
        w = np.minimum(np.float32(1.0), np.float32(huber_k) / np.maximum(a, np.float32(1e-12)))
    elif kind == "tukey":
        q = np.clip(1.0 - a * a * np.float32(1.0 / tukey_c ** 2), 0.0, None)
        w = q * q
    else:
        raise ValueError(f"unknown robust estimator {kind!r}")
    return w.astype(np.float32, copy=False), scale


def rho_sum(r: np.ndarray, scale: float, kind: str, *, huber_k: float, tukey_c: float) -> float:
    """Total robust cost of residuals ``r`` at a fixed ``scale`` (rho(0) = 0); ``kind`` and the
    tuning constants as for :func:`robust_weights`."""
    a = np.abs(r)
    a *= np.float32(1.0 / scale)
    if kind == "huber":
        m = np.minimum(a, np.float32(huber_k))
        a -= 0.5 * m
        a *= m
        rho = a  # m (a - m / 2): 0.5 a^2 inside k, k a - 0.5 k^2 outside
    elif kind == "tukey":
        c = tukey_c
        q = np.clip(1.0 - (a / c) ** 2, 0.0, None)
        rho = (c * c / 6.0) * (1.0 - q ** 3)
    else:
        rho = 0.5 * a * a
    return float(np.sum(rho, dtype=np.float64))


def inlier_bound(noise_sigma: float) -> float:
    """The largest intensity difference (grey levels) of an inlier: ``3 sqrt(2) sigma`` (the
    difference of two images with noise ``sigma`` each), sigma at least one grey level."""
    return 3.0 * np.sqrt(2.0) * max(noise_sigma, 1.0)


def inlier_fraction(r: np.ndarray, valid: np.ndarray, noise_sigma: float) -> float:
    """Share of all points that are in view with ``|r| <`` :func:`inlier_bound`."""
    if len(r) == 0:
        return 0.0
    return float(np.count_nonzero(valid & (np.abs(r) < inlier_bound(noise_sigma))) / len(r))
