"""A feature-based motion hypothesis over the known ground plane: the direct search's capture
range (docs/algorithm.md section 7).

The direct estimator converges from within a few pixels of the answer; a rover step of 0.75 m
or an 18 deg turn moves the ground by a large part of the image. Features do not care how far
they moved: ORB corners of the keyframe's ground and of the current frame are matched, a
RANSAC homography keeps the matches that agree with one plane, and the pose follows from that
homography and the *known* plane (no choice among ``cv2.decomposeHomographyMat``'s four
solutions). The result is a starting point for the direct estimator, not a replacement.

Pose from the homography and the known plane
--------------------------------------------
The plane is ``{X : n . X = d}`` in the keyframe camera (``n`` unit, camera to ground, d > 0 m)
and ``X_cur = R X_key + t``. On the plane ``n^T X_key / d = 1``, so

    X_cur = (R + t n^T / d) X_key        and, for pixels,   x_cur ~ K (R + t' n^T) K^-1 x_key

with ``t' = t / d``. The estimated ``H`` (undistorted pixels, any scale and sign) gives the
normalised ``H_n = K^-1 H K = (R + t' n^T) / lambda`` for an unknown ``lambda != 0``.

1. Sign. A point of the plane in front of the keyframe is ``X_key = rho r`` with ``rho > 0``
   along its ray ``r``; its depth in the current camera is ``rho lambda (H_n r)_z``, which must
   be positive (cheirality). The sign of ``lambda`` is therefore the sign of ``(H_n r)_z`` on
   the inliers' rays (their majority); ``H_n`` is flipped so that ``lambda > 0``.
2. Rotation. For any ``v`` orthogonal to ``n`` the translation term vanishes:
   ``lambda H_n v = R v``. With an orthonormal basis ``E = [e1 e2]`` (3x2) of the plane's
   tangent directions and ``A = H_n E``, ``R`` minimises ``|R E - lambda A|_F`` (orthogonal
   Procrustes): with the SVD ``A E^T = U S V^T``, ``R = U diag(1, 1, det(U V^T)) V^T`` (``A E^T``
   has rank 2; the determinant fixes the third axis, ``R n``). ``R`` does not depend on
   ``lambda > 0``.
3. Scale. ``lambda = <R E, A> / <A, A>`` (least squares for the fixed ``R``); for an exact
   homography ``A``'s two singular values are both ``1 / lambda``. Their ratio (``<= 1``) is
   reported as ``planarity``: far below 1 means the matched surface is not the plane.
4. Translation. Applying ``lambda H_n`` to ``n`` itself: ``lambda H_n n = R n + t'``, so
   ``t' = (lambda H_n - R) n`` and ``t = d t'`` (the known distance fixes the metric scale).
5. Checks. Cheirality: the inliers' plane points ``X_key`` must lie in front of both cameras.
   The plane's side: the current camera must stay on the camera side of the plane,
   ``d_cur = d + (R n) . t > 0`` (the plane in the current frame, :meth:`Plane.in_frame`).

The homography's 8 parameters carry 2 the known plane does not need; the pose above is then
refined on the same inliers by Levenberg-Marquardt on the 6 pose parameters (the inliers'
keyframe points lifted onto the plane, reprojected into the current frame:
``cv2.solvePnPRefineLM``), which uses the plane as a constraint rather than a check.

Determinism: ORB and brute-force matching are deterministic; RANSAC draws from OpenCV's RNG,
which is seeded (``cv2.setRNGSeed(options.seed)``) before every call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from monovo_cli.core.options import FeatureOptions
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose
from monovo_cli.geometry.plane import Plane, tangent_basis

MASK_GRID_PX = 8  # the plane-visibility mask is evaluated on this grid and interpolated
CUR_DEPRESSION_DEG = -5.0  # current-frame features: up to 5 deg above the keyframe's horizon


@dataclass(frozen=True)
class Features:
    """Keypoints of one image: ``uv`` (N, 2) full-resolution pixels as detected (distorted),
    ``rays`` (N, 3) their undistorted viewing rays (z = 1), ``descriptors`` (N, 32) uint8 (ORB;
    float descriptors are matched by Euclidean distance)."""

    uv: np.ndarray
    rays: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.uv)


@dataclass(frozen=True)
class FeatureMotion:
    """A feature-based motion hypothesis.

    ``cur_from_key`` 4x4 (``X_cur = R X_key + t``, m); ``homography`` 3x3 maps undistorted
    keyframe pixels to undistorted current pixels (full resolution, scale 1 at [2, 2]);
    ``matches`` the matches given to RANSAC, ``inliers`` the ones kept; ``rms_px`` the inliers'
    reprojection error under ``cur_from_key`` (undistorted full-resolution pixels);
    ``planarity`` in (0, 1], 1 for an exact plane homography; ``key_rays`` /
    ``cur_rays`` (inliers, 3) the inliers' undistorted viewing rays (z = 1) in either frame.
    """

    cur_from_key: np.ndarray
    homography: np.ndarray
    matches: int
    inliers: int
    rms_px: float
    planarity: float
    key_rays: np.ndarray
    cur_rays: np.ndarray

    @property
    def inlier_ratio(self) -> float:
        """The share of the matches RANSAC kept (0 without matches)."""
        return self.inliers / self.matches if self.matches else 0.0


# --------------------------------------------------------------------------- detection


def _to_uint8(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    return np.clip(np.rint(np.nan_to_num(image)), 0, 255).astype(np.uint8)


def _pyramid_level(image: np.ndarray, level: int) -> np.ndarray:
    img = _to_uint8(np.asarray(image))
    for _ in range(level):
        img = cv2.pyrDown(img)
    return img


def ground_mask(camera: PinholeCamera, plane: Plane, *, level: int = 0,
                min_depression_deg: float = 1.0, region: tuple[int, int, int, int] | None = None,
                usable: np.ndarray | None = None) -> np.ndarray:
    """uint8 mask (height, width) of pyramid level ``level``: 255 where the ray meets ``plane``
    in front of the camera at least ``min_depression_deg`` below its horizon, inside
    ``region`` (``[x0, y0, x1, y1]`` full-resolution pixels, x1/y1 exclusive) and where
    ``usable`` (full-resolution (H, W), non-zero = usable) is set; 0 elsewhere.

    The ray/plane angle is evaluated on a grid of ``MASK_GRID_PX`` pixels and interpolated
    (it is smooth; the lens model's undistortion is the expensive part).
    """
    cam = camera.scaled(level)
    w, h = cam.width, cam.height
    xs = np.unique(np.append(np.arange(0, w, MASK_GRID_PX), w - 1)).astype(float)
    ys = np.unique(np.append(np.arange(0, h, MASK_GRID_PX), h - 1)).astype(float)
    gx, gy = np.meshgrid(xs, ys)
    rays = cam.rays(np.stack([gx.ravel(), gy.ravel()], axis=1))
    sin_dep = (rays @ plane.normal) / np.linalg.norm(rays, axis=1)
    coarse = sin_dep.reshape(len(ys), len(xs)).astype(np.float32)
    # a bilinear resize between grid nodes; the grid's nodes sit at xs, ys
    mx = np.interp(np.arange(w, dtype=float), xs, np.arange(len(xs), dtype=float)).astype(np.float32)
    my = np.interp(np.arange(h, dtype=float), ys, np.arange(len(ys), dtype=float)).astype(np.float32)
    fine = cv2.remap(coarse, np.broadcast_to(mx, (h, w)).copy(),
                     np.broadcast_to(my[:, None], (h, w)).copy(), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)
    ok = fine >= math.sin(math.radians(min_depression_deg))
    if region is not None:
        s = 0.5 ** level
        x0, y0, x1, y1 = region
        box = np.zeros_like(ok)
        box[max(0, math.ceil(y0 * s)):max(0, math.ceil(y1 * s)),
            max(0, math.ceil(x0 * s)):max(0, math.ceil(x1 * s))] = True
        ok &= box
    if usable is not None:
        u = (np.asarray(usable) != 0).astype(np.uint8) * 255
        for _ in range(level):
            u = cv2.pyrDown(u)
        ok &= u >= 255  # a pixel near an unusable one is not usable either
    return ok.astype(np.uint8) * 255


def detect_features(image: np.ndarray, camera: PinholeCamera, *, mask: np.ndarray | None = None,
                    options: FeatureOptions = FeatureOptions()) -> Features:
    """ORB keypoints of ``image`` (H, W) grey (uint8, or float in grey levels) at pyramid level
    ``options.level_for(camera)``, only where ``mask`` (uint8 of that level, e.g.
    :func:`ground_mask`) is non-zero; positions in full-resolution pixels (pixel j of level l
    is pixel j 2**l)."""
    level = options.level_for(camera)
    img = _pyramid_level(image, level)
    orb = cv2.ORB_create(nfeatures=options.features, fastThreshold=options.fast_threshold)
    kps, desc = orb.detectAndCompute(img, mask)
    if desc is None or not kps:
        return Features(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 32), np.uint8))
    uv = np.array([k.pt for k in kps], dtype=float) * 2.0 ** level
    return Features(uv, camera.rays(uv), desc)


def _match(key: Features, cur: Features, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (M,), (M,) of matched keyframe / current features (Hamming distance for
    binary descriptors such as ORB's, Euclidean for float ones)."""
    if len(key) < 2 or len(cur) < 2 or key.descriptors.dtype != cur.descriptors.dtype:
        return np.zeros(0, int), np.zeros(0, int)
    norm = cv2.NORM_HAMMING if key.descriptors.dtype == np.uint8 else cv2.NORM_L2
    if ratio <= 0.0:
        matches = cv2.BFMatcher(norm, crossCheck=True).match(key.descriptors, cur.descriptors)
        pairs = [(m.queryIdx, m.trainIdx) for m in matches]
    else:
        knn = cv2.BFMatcher(norm).knnMatch(key.descriptors, cur.descriptors, k=2)
        pairs = [(m[0].queryIdx, m[0].trainIdx) for m in knn
                 if len(m) == 2 and m[0].distance < ratio * m[1].distance]
    if not pairs:
        return np.zeros(0, int), np.zeros(0, int)
    a = np.array(pairs, dtype=int)
    return a[:, 0], a[:, 1]


# --------------------------------------------------------------------------- pose


def pose_from_homography(H_n: np.ndarray, plane: Plane, key_rays: np.ndarray
                         ) -> tuple[np.ndarray, float] | None:
    """``(cur_from_key 4x4, planarity)`` from a normalised plane homography.

    ``H_n`` (3x3, any scale and sign) maps keyframe rays to current rays,
    ``H_n ~ R + t n^T / d``; ``key_rays`` (N, 3) are rays of keyframe points on ``plane``
    (the inliers), which fix the sign and are checked for cheirality. None when the
    homography is degenerate, fewer than 95 % of the points are in front of both cameras,
    or the current camera is on the far side of the plane. Derivation: module docstring.
    """
    n, d = np.asarray(plane.normal, dtype=float), float(plane.distance)
    H_n = np.asarray(H_n, dtype=float)
    key_rays = np.asarray(key_rays, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(H_n)) or not len(key_rays):
        return None
    front = key_rays @ n > 1e-9  # the ray meets the plane in front of the keyframe
    if front.mean() < 0.95:
        return None
    key_rays = key_rays[front]
    depth_sign = np.sign(np.median((key_rays @ H_n.T)[:, 2]))  # step 1
    if depth_sign == 0:
        return None
    H_n = H_n * depth_sign
    E = tangent_basis(n)
    A = H_n @ E
    sv = np.linalg.svd(A, compute_uv=False)
    if sv[0] <= 0.0 or not np.isfinite(sv[0]):
        return None
    consistency = float(sv[1] / sv[0])
    if consistency < 1e-6:
        return None
    U, _, Vt = np.linalg.svd(A @ E.T)  # step 2
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    lam = float(np.sum((R @ E) * A) / np.sum(A * A))  # step 3
    t = d * ((lam * H_n - R) @ n)  # step 4
    T = make_pose(R, t)
    if not _physical(T, plane, key_rays):  # step 5
        return None
    return T, consistency


def _physical(cur_from_key: np.ndarray, plane: Plane, key_rays: np.ndarray) -> bool:
    """Cheirality (>= 95 % of the rays' plane points in front of both cameras) and the plane's side."""
    if plane.in_frame(cur_from_key).distance <= 0.0:
        return False
    X = plane.intersect(key_rays)
    z = X @ cur_from_key[2, :3] + cur_from_key[2, 3]
    return bool(np.mean(np.nan_to_num(z, nan=-1.0) > 0.0) >= 0.95)


def _refine(T: np.ndarray, X_key: np.ndarray, uv_cur: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Levenberg-Marquardt on the 6 pose parameters: reprojection of ``X_key`` (N, 3) onto
    the undistorted ``uv_cur`` (N, 2)."""
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    tvec = T[:3, 3].reshape(3, 1).copy()
    try:
        rvec, tvec = cv2.solvePnPRefineLM(X_key, uv_cur, K, None, rvec, tvec)
    except cv2.error:  # degenerate point sets: keep the homography's pose
        return T
    R, _ = cv2.Rodrigues(rvec)
    return make_pose(R, tvec.ravel())


# --------------------------------------------------------------------------- the hypothesis


def motion_from_features(key: Features, cur: Features, camera: PinholeCamera, plane: Plane, *,
                         options: FeatureOptions = FeatureOptions()) -> FeatureMotion | None:
    """The motion hypothesis from keypoints already detected (:func:`detect_features`) in the
    keyframe (on ``plane``'s region) and the current frame; None when there is too little to
    go on. ``plane`` is in the keyframe camera."""
    ki, ci = _match(key, cur, options.ratio)
    if len(ki) < max(options.min_inliers, 4):
        return None
    K = camera.K
    src = key.rays[ki] @ K.T  # undistorted full-resolution pixels (homogeneous, z = 1)
    dst = cur.rays[ci] @ K.T
    if not (np.all(np.isfinite(src)) and np.all(np.isfinite(dst))):
        return None
    cv2.setRNGSeed(options.seed)
    try:
        H, inl = cv2.findHomography(src[:, :2], dst[:, :2], cv2.RANSAC,
                                    options.ransac_px * 2.0 ** options.level_for(camera),
                                    maxIters=options.ransac_iterations, confidence=0.999)
    except cv2.error:  # degenerate point sets
        return None
    if H is None or inl is None:
        return None
    inl = inl.ravel().astype(bool)
    count = int(inl.sum())
    if count < options.min_inliers or count < options.min_inlier_ratio * len(ki):
        return None
    if not np.all(np.isfinite(H)) or abs(np.linalg.det(H)) < 1e-12:
        return None
    H_n = np.linalg.solve(K, H @ K)
    got = pose_from_homography(H_n, plane, key.rays[ki][inl])
    if got is None or got[1] < options.min_planarity:
        return None
    T, consistency = got
    X_key = plane.intersect(key.rays[ki][inl])
    ok = np.all(np.isfinite(X_key), axis=1)
    X_key, uv_cur = X_key[ok], dst[inl][ok, :2]
    if options.refine:
        T_lm = _refine(T, X_key, uv_cur, K)
        if np.all(np.isfinite(T_lm)) and _physical(T_lm, plane, key.rays[ki][inl]):
            T = T_lm
    X_cur = X_key @ T[:3, :3].T + T[:3, 3]
    proj = X_cur[:, :2] / X_cur[:, 2:3] * [K[0, 0], K[1, 1]] + K[:2, 2]
    rms = float(np.sqrt(np.mean(np.sum((proj - uv_cur) ** 2, axis=1))))
    return FeatureMotion(T, H / H[2, 2], len(ki), count, rms, consistency, key.rays[ki][inl],
                         cur.rays[ci][inl])


def feature_motion(key_image: np.ndarray, cur_image: np.ndarray, camera: PinholeCamera,
                   plane: Plane, *, mask: np.ndarray | None = None,
                   region: tuple[int, int, int, int] | None = None,
                   options: FeatureOptions = FeatureOptions()) -> FeatureMotion | None:
    """Motion hypothesis ``cur_from_key`` between two grey frames (H, W) over the known ground.

    ``plane`` is the ground in the keyframe camera; ``camera`` the frames' camera (its lens
    distortion is removed from the keypoints). Keyframe features come from where the plane
    is seen (:func:`ground_mask`: in ``region`` ``[x0, y0, x1, y1]`` if given, where ``mask``
    (H, W), non-zero = usable, is set); current-frame features from the part of the image
    below the keyframe plane's horizon (with a 5 deg margin above it for a pitch change)
    where ``mask`` is set. None when there is too little to go on (few features, matches
    or inliers, a degenerate homography, or one that is not this plane's); never raises
    for such images. Deterministic (module docstring).
    """
    level = options.level_for(camera)
    key_mask = ground_mask(camera, plane, level=level,
                           min_depression_deg=options.min_depression_deg, region=region,
                           usable=mask)
    cur_mask = ground_mask(camera, plane, level=level, min_depression_deg=CUR_DEPRESSION_DEG,
                           usable=mask)
    if not key_mask.any() or not cur_mask.any():
        return None
    key = detect_features(key_image, camera, mask=key_mask, options=options)
    cur = detect_features(cur_image, camera, mask=cur_mask, options=options)
    return motion_from_features(key, cur, camera, plane, options=options)
