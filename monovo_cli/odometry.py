"""The sequence loop: keyframes, pose chaining, re-anchoring, loss detection.

Owns the state; does no I/O and no printing. Frames come in one at a time and a
:class:`FrameResult` goes out for each, so memory does not grow with the sequence.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from monovo_cli.errors import TrackingError
from monovo_cli.estimate import (
    Estimate,
    EstimatorOptions,
    KeyLevel,
    coarse_search,
    estimate_motion,
    inlier_fraction,
)
from monovo_cli.geometry import PinholeCamera, orthonormalize, se3_inv
from monovo_cli.ground import (
    Plane,
    default_threshold,
    estimate_noise_sigma,
    rectangle_corners,
    require_points,
    select_points,
)
from monovo_cli.pyramid import build_pyramid, num_levels


@dataclass(frozen=True)
class TrackOptions:
    """Tracking settings.

    ``threshold`` is the paper's delta_1 (Sobel magnitude, grey levels/px; None: from the
    keyframe's noise); ``max_points`` caps the finest level's observation points (coarser
    levels get a quarter per level); ``reanchor_fraction``: re-anchor when fewer of the
    keyframe's points than this stay in view, or the model covers < ``min_footprint`` of
    the image.
    """

    levels: int | None = None
    threshold: float | None = None
    max_points: int = 20000
    min_points: int = 50
    reanchor_fraction: float = 0.6
    min_footprint: float = 0.2
    min_inliers: float = 0.3
    estimator: EstimatorOptions = field(default_factory=EstimatorOptions)


@dataclass(frozen=True)
class Keyframe:
    """A ground model anchored on one frame: plane and points in that frame's camera."""

    index: int
    world_from_key: np.ndarray
    plane: Plane
    corners: np.ndarray
    levels: tuple[KeyLevel, ...]
    noise_sigma: float
    threshold: float


@dataclass(frozen=True)
class FrameResult:
    """One frame's output. Poses are 4x4; ``std`` (6,) m and rad of (tx..rz) of ``prev_from_cur``."""

    index: int
    timestamp: float
    world_from_cam: np.ndarray
    prev_from_cur: np.ndarray
    msd: float
    iterations: int
    points: int
    status: str
    std: np.ndarray
    covariance: np.ndarray


def build_keyframe(index: int, image: np.ndarray, camera: PinholeCamera, plane: Plane,
                   region: tuple[int, int, int, int], world_from_key: np.ndarray,
                   options: TrackOptions, *, mask: np.ndarray | None = None,
                   pyramid: list[np.ndarray] | None = None) -> Keyframe:
    """The ground model of section 10.2.5 on ``image`` (H, W) float32, plane in its camera."""
    n_levels = options.levels or num_levels(camera.width, camera.height)
    pyr = pyramid if pyramid is not None else build_pyramid(image, n_levels)
    sigma = estimate_noise_sigma(image)
    threshold = options.threshold if options.threshold is not None else default_threshold(sigma)
    corners = rectangle_corners(camera, plane, region)
    levels = []
    m = mask
    for lv in range(n_levels):
        cam = camera.scaled(lv)
        if lv > 0 and m is not None:
            m = cv2.resize(m.astype(np.uint8), (cam.width, cam.height),
                           interpolation=cv2.INTER_NEAREST).astype(bool)
        pts = select_points(pyr[lv], cam, plane, corners, level=lv, threshold=threshold,
                            max_points=max(options.max_points // (4 ** lv), 200), mask=m)
        if lv == 0:
            require_points(pts, minimum=options.min_points, threshold=threshold)
        levels.append(KeyLevel.from_points(pts))
    # Coarse levels with too few points are dropped: they cannot constrain 6 DoF.
    while len(levels) > 1 and len(levels[-1].points) < 30:
        levels.pop()
    return Keyframe(index, np.array(world_from_key), plane, corners, tuple(levels), sigma, threshold)


def footprint(camera: PinholeCamera, corners_cur: np.ndarray) -> float:
    """Share of the image covered by the model rectangle (4, 3) given in the current camera."""
    if np.any(corners_cur[:, 2] <= 1e-6):
        # Part of the rectangle is behind the camera: clip by sampling the image instead.
        return 0.0
    poly = camera.project(corners_cur).astype(np.float32)
    img = np.array([[0, 0], [camera.width, 0], [camera.width, camera.height], [0, camera.height]],
                   np.float32)
    area, _ = cv2.intersectConvexConvex(poly, img)
    return float(area) / (camera.width * camera.height)


def _output_covariance(cov_xi: np.ndarray, key_from_cur: np.ndarray) -> np.ndarray:
    """Covariance of (t, rotvec) of ``key_from_cur`` from that of its left-perturbation twist."""
    t = key_from_cur[:3, 3]
    A = np.eye(6)
    A[:3, 3:] = -np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return A @ cov_xi @ A.T


class Odometry:
    """Tracks a sequence frame by frame against keyframes (the paper's moved ground model)."""

    def __init__(self, camera: PinholeCamera, plane: Plane, region: tuple[int, int, int, int],
                 options: TrackOptions | None = None, *, mask: np.ndarray | None = None,
                 first_keyframe: Keyframe | None = None) -> None:
        self.camera = camera
        self.region = region
        self.options = options or TrackOptions()
        self.mask = mask
        self._plane0 = plane
        self._key: Keyframe | None = first_keyframe
        self._world_from_prev = np.eye(4)
        self._cur_from_key_prev = np.eye(4)
        self._velocity: np.ndarray | None = None  # cur_from_prev of the last good frame
        self._levels = self.options.levels or num_levels(camera.width, camera.height)

    @property
    def keyframe(self) -> Keyframe | None:
        return self._key

    def start(self, index: int, timestamp: float, image: np.ndarray) -> FrameResult:
        """Frame 0: the identity pose; builds the first ground model unless one was given."""
        if self._key is None:
            self._key = build_keyframe(index, image, self.camera, self._plane0, self.region,
                                       np.eye(4), self.options, mask=self.mask)
        n = len(self._key.levels[0].points)
        return FrameResult(index, timestamp, np.eye(4), np.eye(4), 0.0, 0, n, "ok",
                           np.zeros(6), np.zeros((6, 6)))

    def step(self, index: int, timestamp: float, image: np.ndarray) -> FrameResult:
        """Estimate frame ``index`` and return its result (status ok, reanchored or lost)."""
        key = self._key
        assert key is not None, "call start() first"
        pyr = build_pyramid(image, len(key.levels))
        if self._velocity is not None:
            guess = self._velocity @ self._cur_from_key_prev
        else:
            guess = coarse_search(key.levels[-1], pyr[-1], self._cur_from_key_prev,
                                  options=self.options.estimator, noise_sigma=key.noise_sigma)
        est = estimate_motion(key.levels, pyr, guess, options=self.options.estimator)
        if not self._good(est, key, pyr) and self._velocity is not None:
            retry_init = coarse_search(key.levels[-1], pyr[-1], guess,
                                       options=self.options.estimator, noise_sigma=key.noise_sigma)
            retry = estimate_motion(key.levels, pyr, retry_init, options=self.options.estimator)
            if self._score(retry, key, pyr) > self._score(est, key, pyr):
                est = retry
        good = self._good(est, key, pyr)
        world_from_prev = self._world_from_prev
        if good:
            cur_from_key = orthonormalize(est.cur_from_key)
            status = "ok"
        else:
            cur_from_key = (self._velocity if self._velocity is not None else np.eye(4)) \
                @ self._cur_from_key_prev
            status = "lost"
        cur_from_key = orthonormalize(cur_from_key)
        world_from_cur = orthonormalize(key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(world_from_prev) @ world_from_cur)
        cov = _output_covariance(est.covariance, se3_inv(cur_from_key)) if good \
            else np.full((6, 6), np.nan)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None)) if good else np.full(6, np.nan)
        msd = est.msd if np.isfinite(est.msd) else 0.0
        self._velocity = se3_inv(prev_from_cur) if good else self._velocity
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        if not good or self._needs_reanchor(est, key, cur_from_key):
            self._reanchor(index, image, pyr, world_from_cur, cur_from_key)
            if good:
                status = "reanchored"
        return FrameResult(index, timestamp, world_from_cur, prev_from_cur, msd, est.iterations,
                           est.points, status, std, cov)

    def _score(self, est: Estimate, key: Keyframe, pyr: list[np.ndarray]) -> float:
        """Share of the in-view points that agree with the estimate within the noise."""
        if est.residuals is None:
            return 0.0
        return inlier_fraction(est.residuals, est.valid, key.noise_sigma) / max(est.valid_fraction, 1e-9)

    def _good(self, est: Estimate, key: Keyframe, pyr: list[np.ndarray]) -> bool:
        if not est.converged or not np.all(np.isfinite(est.cur_from_key)):
            return False
        if not np.all(np.isfinite(est.covariance)):
            return False
        return self._score(est, key, pyr) >= self.options.min_inliers

    def _needs_reanchor(self, est: Estimate, key: Keyframe, cur_from_key: np.ndarray) -> bool:
        corners_cur = key.corners @ cur_from_key[:3, :3].T + cur_from_key[:3, 3]
        return (est.valid_fraction < self.options.reanchor_fraction
                or footprint(self.camera, corners_cur) < self.options.min_footprint)

    def _reanchor(self, index: int, image: np.ndarray, pyr: list[np.ndarray],
                  world_from_cur: np.ndarray, cur_from_key: np.ndarray) -> None:
        key = self._key
        plane = key.plane.in_frame(cur_from_key)
        try:
            self._key = build_keyframe(index, image, self.camera, plane, self.region,
                                       world_from_cur, self.options, mask=self.mask, pyramid=pyr)
        except TrackingError:
            return  # keep the old model (e.g. a blank frame); try again next frame
        self._cur_from_key_prev = np.eye(4)

    def skip(self, index: int, timestamp: float) -> FrameResult:
        """Frame ``index`` has no usable image: record it as lost at the constant-velocity
        prediction (the last good frame's motion repeated) and carry on from there."""
        key = self._key
        assert key is not None, "call start() first"
        velocity = self._velocity if self._velocity is not None else np.eye(4)
        cur_from_key = orthonormalize(velocity @ self._cur_from_key_prev)
        world_from_cur = orthonormalize(key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(self._world_from_prev) @ world_from_cur)
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        return FrameResult(index, timestamp, world_from_cur, prev_from_cur, 0.0, 0, 0, "lost",
                           np.full(6, np.nan), np.full((6, 6), np.nan))


def track(frames: Iterable[tuple[int, float, np.ndarray]], camera: PinholeCamera, plane: Plane,
          region: tuple[int, int, int, int], options: TrackOptions | None = None, *,
          mask: np.ndarray | None = None, first_keyframe: Keyframe | None = None,
          on_keyframe: Callable[[Keyframe], None] | None = None) -> Iterator[FrameResult]:
    """Yield a :class:`FrameResult` per ``(index, timestamp, image)``, frame 0 first."""
    odo = Odometry(camera, plane, region, options, mask=mask, first_keyframe=first_keyframe)
    it = iter(frames)
    try:
        index, ts, image = next(it)
    except StopIteration:
        return
    yield odo.start(index, ts, image)
    if on_keyframe is not None:
        on_keyframe(odo.keyframe)
    for index, ts, image in it:
        yield odo.step(index, ts, image)
