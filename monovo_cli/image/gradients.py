"""Image gradients (Sobel, cubic B-spline) and the camera noise estimate.
"""

from __future__ import annotations

import cv2
import numpy as np


def sobel_gradient(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sobel derivatives ``(gx, gy)``, each (H, W) float32 in grey levels per pixel, of the
    float32 ``image`` (H, W) (3x3 kernel scaled by 1/8, borders replicated)."""
    gx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    return gx, gy


def with_sobel_gradient(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32: ``image`` (H, W) and its :func:`sobel_gradient` as the planes of one
    image, to be sampled at once (:func:`~monovo_cli.image.sampling.sample_bilinear`)."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    return cv2.merge([image, *sobel_gradient(image)])


_BSPLINE_POLE = np.sqrt(3.0) - 2.0


def _bspline_prefilter_kernel(half: int = 8) -> np.ndarray:
    """FIR form of the cubic B-spline interpolation prefilter (the inverse of [1, 4, 1]/6),
    truncated at ``half`` taps each side (the pole's power 0.27^9 < 1e-5) and renormalised."""
    z = _BSPLINE_POLE
    k = np.arange(-half, half + 1)
    c = (-6.0 * z / (1.0 - z * z)) * z ** np.abs(k)
    return (c / c.sum()).astype(np.float32)


_PREFILTER = _bspline_prefilter_kernel()
_SPLINE_VALUE = np.array([1.0, 4.0, 1.0], np.float32) / 6.0
_SPLINE_SLOPE = np.array([-0.5, 0.0, 0.5], np.float32)


def bspline_coefficients(image: np.ndarray) -> np.ndarray:
    """Coefficients (H, W) float32 of the cubic B-spline that interpolates ``image``."""
    return cv2.sepFilter2D(np.asarray(image, np.float32), cv2.CV_32F, _PREFILTER, _PREFILTER,
                           borderType=cv2.BORDER_REFLECT)


def spline_gradient(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact derivatives (gx, gy) at the pixels of the cubic B-spline interpolating ``image``.

    The estimator's finest-level observation matrix uses them: they are closer to the
    gradient of the band-limited image than Sobel's smoothed difference (the frame itself
    is sampled with OpenCV's bicubic remap, whose derivative is not continuous).
    """
    c = bspline_coefficients(image)
    gx = cv2.sepFilter2D(c, cv2.CV_32F, _SPLINE_SLOPE, _SPLINE_VALUE, borderType=cv2.BORDER_REFLECT)
    gy = cv2.sepFilter2D(c, cv2.CV_32F, _SPLINE_VALUE, _SPLINE_SLOPE, borderType=cv2.BORDER_REFLECT)
    return gx, gy


def estimate_noise_sigma(image: np.ndarray) -> float:
    """Standard deviation (grey levels) of white image noise, by Immerkaer's Laplacian-difference method."""
    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float32)
    resp = cv2.filter2D(image.astype(np.float32), -1, k, borderType=cv2.BORDER_REFLECT)[1:-1, 1:-1]
    return float(np.sqrt(np.pi / 2.0) / 6.0 * np.mean(np.abs(resp)))


NOISE_CAP = 12.0  # grey levels: the most current-frame noise the loss checks allow for


def difference_sigma(key_sigma: float, image: np.ndarray) -> float:
    """Noise sigma (grey levels) that intensity differences between a keyframe of noise
    ``key_sigma`` and ``image`` (H, W) carry.

    The two need not be alike (a noise-free or well-lit keyframe, a darker, noisier frame
    later): the result is sqrt((s_key^2 + s_cur^2) / 2), with s_cur measured on the central
    quarter of ``image`` and capped at max(12, 3 s_key) grey levels so that a frame of pure
    noise does not excuse itself.
    """
    h, w = image.shape
    s_cur = estimate_noise_sigma(image[h // 4: h - h // 4, w // 4: w - w // 4])
    s_cur = min(s_cur, max(NOISE_CAP, 3.0 * key_sigma))
    return float(np.sqrt(0.5 * (key_sigma ** 2 + s_cur ** 2)))
