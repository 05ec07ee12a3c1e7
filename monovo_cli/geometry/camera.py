"""The pinhole camera with OpenCV distortion: projection, back-projection, per-level copies.

Axes are OpenCV's (x right, y down, z forward); pixel (0, 0) is the centre of the top-left pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole camera with optional OpenCV distortion ``(k1, k2, p1, p2[, k3])``.

    Pixel centres are integers, the top-left pixel's centre is (0, 0).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = field(default=(0.0, 0.0, 0.0, 0.0, 0.0))

    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def has_distortion(self) -> bool:
        """Whether any lens distortion coefficient is non-zero."""
        return any(abs(c) > 0.0 for c in self.distortion)

    def scaled(self, level: int) -> PinholeCamera:
        """The camera of pyramid level ``level`` (each level halves the image, cv2.pyrDown).

        cv2.pyrDown smooths, then keeps the even rows and columns: pixel j of level l sits
        at pixel ``j * 2**l`` of level 0, so ``x_l = x_0 / 2**l`` (no half-pixel shift).
        """
        w, h = self.width, self.height
        for _ in range(level):
            w, h = (w + 1) // 2, (h + 1) // 2
        s = 0.5 ** level
        return replace(self, width=w, height=h, fx=self.fx * s, fy=self.fy * s,
                       cx=self.cx * s, cy=self.cy * s)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of camera-frame points ``X`` (N, 3), metres; z must be > 0."""
        X = np.asarray(X)
        z = X[:, 2]
        xn, yn = X[:, 0] / z, X[:, 1] / z
        if self.has_distortion:
            xn, yn = self.distort_normalized(xn, yn)
        return np.stack([self.fx * xn + self.cx, self.fy * yn + self.cy], axis=1)

    def distort_normalized(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply the OpenCV radial-tangential model to normalised coordinates."""
        k1, k2, p1, p2, *rest = (tuple(self.distortion) + (0.0,) * 5)[:5]
        k3 = rest[0]
        r2 = xn * xn + yn * yn
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
        return xd, yd

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """Viewing rays (N, 3) with z = 1 through pixels ``uv`` (N, 2), distortion removed."""
        uv = np.asarray(uv, dtype=float)
        if self.has_distortion:
            import cv2

            dist = np.asarray(self.distortion, dtype=float)
            pts = cv2.undistortPoints(
                uv.reshape(-1, 1, 2), self.K, dist,
                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12),
            ).reshape(-1, 2)
            return np.concatenate([pts, np.ones((len(pts), 1))], axis=1)
        out = np.empty((len(uv), 3))
        out[:, 0] = (uv[:, 0] - self.cx) / self.fx
        out[:, 1] = (uv[:, 1] - self.cy) / self.fy
        out[:, 2] = 1.0
        return out
