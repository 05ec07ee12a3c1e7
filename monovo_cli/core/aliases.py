"""The motions the images cannot tell apart: a repetitive texture's periods and the rival
minima of low texture.

On a periodic texture (a checkerboard, tiles, a grating) a camera moved by one period along
the ground sees the same image: the intensity differences have a minimum at every period as
deep as the right one, and the fit converges to whichever its start reaches.
:func:`ground_periods` finds a keyframe's periods once (the normalised autocorrelation of its
image over the model region, peaks away from the central lobe) as shifts along the plane;
:func:`alias_variance` refits an accepted fit moved by each and, where one fits as well and
the prediction does not pick between them, adds the difference to the row's covariance.

On low texture the landscape is flat: where no prediction picks the minimum
(:func:`unpinned`), :func:`rivals` fits from starts around the fit and
:func:`rival_variance` adds the spread of those that fit as well.
docs/algorithm.md section 4 ("Repetitive texture", "Rival minima") gives the rules.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import cv2
import numpy as np

from monovo_cli.core.estimator.estimate import estimate_motion
from monovo_cli.core.estimator.ground import in_front
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import motion_change, so3_exp, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.pyramid import build_pyramid

PEAK = 0.5  # a normalised autocorrelation peak this high away from the centre: a period
CENTRAL_LOBE = 0.25  # the central lobe ends where the autocorrelation first falls below this
MAX_SIDE = 256  # the periods are found at the finest level no larger than this
MAX_LAG_SHARE = 0.35  # lags up to this share of the region's size (beyond: too few overlaps)
MAX_PERIODS = 2  # a lattice's basis
ALIAS_SHARE = 0.25  # an alias fits within this share of the way from the fit's msd to chance


def _level_within(pyramid: list[np.ndarray], levels: int, side: int) -> int:
    """The finest of the first ``levels`` levels of ``pyramid`` no larger than ``side`` px
    (the coarsest of them if none is)."""
    lv = 0
    while lv + 1 < levels and max(pyramid[lv].shape) > side:
        lv += 1
    return lv


def _turned(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (rad) between the cameras of poses ``a`` and ``b`` (4x4 ``cur_from_key``)."""
    return float(np.linalg.norm(so3_log(a[:3, :3] @ b[:3, :3].T)))


def _apart(a: np.ndarray, b: np.ndarray) -> float:
    """How far (m) the camera of pose ``b`` (4x4 ``cur_from_key``) is from that of ``a``."""
    return float(np.linalg.norm(np.linalg.solve(a, b)[:3, 3]))


def _correlate(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The circular autocorrelation of ``a`` zero-padded to ``shape``, lag 0 at [0, 0]."""
    pad = np.zeros(shape, np.float32)
    pad[:a.shape[0], :a.shape[1]] = a
    f = cv2.dft(pad, flags=cv2.DFT_COMPLEX_OUTPUT)
    return cv2.idft(cv2.mulSpectrums(f, f, 0, conjB=True), flags=cv2.DFT_REAL_OUTPUT)


@lru_cache(maxsize=8)
def _window(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The Hann window (h, w) and its autocorrelation at lags up to MAX_LAG_SHARE of it."""
    win = cv2.createHanningWindow((w, h), cv2.CV_32F)
    return win, _lags(_correlate(win, _dft_shape(h, w)), h, w)


def _dft_shape(h: int, w: int) -> tuple[int, int]:
    """The transform's size: no padding beyond OpenCV's next fast size. The window takes
    the patch to zero at its edges, so the wrap-around of a circular correlation adds
    little at the lags kept (MAX_LAG_SHARE of the size)."""
    return cv2.getOptimalDFTSize(h), cv2.getOptimalDFTSize(w)


def _lags(r: np.ndarray, h: int, w: int) -> np.ndarray:
    """The lags -my..my, -mx..mx (MAX_LAG_SHARE of h, w) of a circular correlation, lag 0 at
    the centre."""
    my, mx = int(MAX_LAG_SHARE * h), int(MAX_LAG_SHARE * w)
    rows = np.r_[r.shape[0] - my:r.shape[0], 0:my + 1]
    cols = np.r_[r.shape[1] - mx:r.shape[1], 0:mx + 1]
    return r[np.ix_(rows, cols)].astype(np.float64)


def _autocorrelation(patch: np.ndarray) -> np.ndarray:
    """The normalised autocorrelation of ``patch`` (h, w) at lags up to MAX_LAG_SHARE of its
    size, lag 0 at the centre, each lag's sum divided by the window's at that lag (an
    unbiased estimate)."""
    h, w = patch.shape
    win, rw = _window(h, w)
    x = (patch - patch.mean()).astype(np.float32) * win
    r = _lags(_correlate(x, _dft_shape(h, w)), h, w) / np.maximum(rw, 1e-12)
    return r / max(r[r.shape[0] // 2, r.shape[1] // 2], 1e-12)


def image_periods(patch: np.ndarray) -> list[tuple[float, float, float]]:
    """``(du, dv, height)``: the lags (px) of ``patch``'s strongest autocorrelation peaks
    beyond the central lobe, each at least PEAK high, at most MAX_PERIODS, one of each
    +- pair (dv > 0, or dv == 0 and du > 0)."""
    h, w = patch.shape
    if h < 16 or w < 16 or float(np.std(patch)) < 1e-3:
        return []
    r = _autocorrelation(patch)
    cy, cx = r.shape[0] // 2, r.shape[1] // 2
    # the central lobe: the connected part above CENTRAL_LOBE around lag 0
    above = (r > CENTRAL_LOBE).astype(np.uint8)
    _, labels = cv2.connectedComponents(above, connectivity=8)
    lobe = labels == labels[cy, cx]
    r = r.astype(np.float32)  # (the local maxima compared in one precision)
    peaks = (r >= cv2.dilate(r, np.ones((3, 3), np.uint8))) & (r >= PEAK) & ~lobe
    vs, us = np.nonzero(peaks)
    # the lattice's basis: the shortest lag, then the shortest not along it
    out: list[tuple[float, float, float]] = []
    for v, u in sorted(zip(vs, us), key=lambda p: (p[0] - cy) ** 2 + (p[1] - cx) ** 2):
        du, dv = float(u - cx), float(v - cy)
        if dv < 0 or (dv == 0 and du < 0):
            continue
        if any(abs(du * b - dv * a) < 0.3 * np.hypot(du, dv) * np.hypot(a, b) for a, b, _ in out):
            continue
        out.append((du, dv, float(r[v, u])))
        if len(out) == MAX_PERIODS:
            break
    return out


def ground_periods(pyramid: list[np.ndarray], camera: PinholeCamera, plane: Plane,
                   corners: np.ndarray) -> np.ndarray:
    """(K, 3) m: the ground texture's periods as shifts along ``plane`` in the keyframe's
    camera, found in the keyframe's image (``pyramid``, finest first) over the model
    rectangle ``corners`` (4, 3); (0, 3) for a texture without one."""
    lv = _level_within(pyramid, len(pyramid), MAX_SIDE)
    cam, img = camera.scaled(lv), pyramid[lv]
    uv = cam.project(corners)
    if not np.all(np.isfinite(uv)):
        return np.zeros((0, 3))
    x0, y0 = np.clip(np.floor(uv.min(axis=0)).astype(int), 0, [cam.width, cam.height])
    x1, y1 = np.clip(np.ceil(uv.max(axis=0)).astype(int), 0, [cam.width, cam.height])
    patch = img[y0:y1, x0:x1]
    found = image_periods(patch)
    if not found:
        return np.zeros((0, 3))
    c = np.array([(x0 + x1 - 1) / 2.0, (y0 + y1 - 1) / 2.0])
    out = []
    for du, dv, _ in found:
        X = plane.intersect(cam.rays(np.array([c, c + (du, dv)])))
        if in_front(X):
            out.append(X[1] - X[0])
    return np.array(out).reshape(-1, 3)


def with_periods(key, image: np.ndarray, camera: PinholeCamera):
    """``key`` (a Keyframe) with its periods, found in ``image`` (its frame, (H, W) float32)
    where it has none yet (a model written by ``monovo init``)."""
    if key.periods is not None:
        return key
    pyr = build_pyramid(image, len(key.levels))
    return replace(key, periods=ground_periods(pyr, camera, key.plane, key.corners))


def shifted(cur_from_key: np.ndarray, period: np.ndarray) -> np.ndarray:
    """``cur_from_key`` (4x4) seeing every ground point where the point one ``period`` (3,)
    along lies: the same image on a texture of that period."""
    shift = np.eye(4)
    shift[:3, 3] = period
    return cur_from_key @ shift


def alias_variance(key, pyramid: list[np.ndarray], est, prediction_std: np.ndarray,
                   motion_to, motion: np.ndarray, options) -> np.ndarray:
    """(6, 6): the variance the texture's periods add to an accepted fit ``est`` against
    ``key`` (``pyramid`` the frame's, finest first) whose motion is ``motion`` (4x4, as
    motion.csv's; ``motion_to(cur_from_key)`` the motion of another pose); ``options`` the
    estimator's.

    Each alias (the fit moved by one of ``key``'s periods either way, refined at the finest
    level, still at least half a period away) whose msd lies within ALIAS_SHARE of the way
    from the fit's to chance (the points' intensity variance) is a motion the images cannot
    tell from the fit's. Which of them is right then rests on the prediction: where its std
    ``prediction_std`` (6,) along the difference ``d`` (6,) is below a third of ``d``, the
    nearest minimum is the fit's and nothing is added; else the motion is known only as
    well as the prediction knows it, and its variance along ``d`` is the prediction's (at
    least ``|d|^2``)."""
    cov = np.zeros((6, 6))
    if not key.periodic:
        return cov
    chance = key.levels[0].intensity_variance
    for period in key.periods:
        for sign in (1.0, -1.0):
            alias = estimate_motion(key.levels, pyramid, shifted(est.cur_from_key, sign * period),
                                    options=options, gain=est.gain, bias=est.bias, first_level=0)
            if not alias.converged or \
                    _apart(est.cur_from_key, alias.cur_from_key) < 0.5 * np.linalg.norm(period) or \
                    alias.msd - est.msd > ALIAS_SHARE * max(chance - est.msd, 0.0):
                continue
            d = motion_change(motion_to(alias.cur_from_key), motion)
            size2 = float(d @ d)
            s2 = float(prediction_std ** 2 @ (d * d)) / max(size2, 1e-30)
            if s2 >= size2 / 9.0:
                cov += np.outer(d, d) * max(s2, size2) / max(size2, 1e-30)
            break  # one of the +- pair: the same direction
    return cov


RIVAL_STEPS = (0.25, 0.5)  # the starts around a fit: these shares of the ground's distance
RIVAL_DIRECTIONS = 8  # ... in as many directions along the plane
RIVAL_SIDE = 64  # the rivals are fitted down to the finest pyramid level no larger than this
RIVAL_ITERATIONS = 10  # ... with at most this many iterations a level
RIVAL_TOLERANCE_PX = 0.05  # ... stopping at this step (px), bilinear: a coarse look, not a fit
UNPINNED_SHARE = 0.1  # a prediction whose translation std is beyond this share of the
#                       ground's distance does not pick the fit's minimum (a standing start,
#                       a loss, a row that inherits either)
UNPINNED_DEG = 5.0  # ... nor one whose rotation std is beyond this: half the nearest turned
#                     start, so the prediction cannot tell the turned minima from the fit's
MOVED_SHARE = 0.1  # a rival this share of the distance from the fit is another minimum
RIVAL_TURNS_DEG = (10.0, 20.0)  # and starts turned by these about each camera axis
TURNED_DEG = 3.0  # ... a rival turned this far from the fit is another minimum
RIVAL_MSD_RATIO = 10.0  # a rival fitting this many times worse than the best is told apart
#                         (a real shelf, nearly noiseless: views turned 20 deg fit 36-500
#                         times worse than the fit, yet within a quarter of the way to chance)


def unpinned(prediction_std: np.ndarray, distance: float) -> bool:
    """Whether a prediction of std ``prediction_std`` (6,: m, rad) leaves the minimum open:
    its translation beyond UNPINNED_SHARE of the ground's ``distance``, or its rotation
    beyond UNPINNED_DEG (a camera that jerks by degrees from frame to frame: seed 40's
    scenario 51, frame 21, a minimum 12 deg off with a lower msd than the truth's, whose
    prediction was 10-15 deg uncertain)."""
    return float(np.linalg.norm(prediction_std[:3])) > UNPINNED_SHARE * distance or \
        float(np.linalg.norm(prediction_std[3:])) > np.radians(UNPINNED_DEG)


def rivals(key, pyramid: list[np.ndarray], est, options) -> list[np.ndarray]:
    """Where no prediction picks the minimum, the other minima the images leave around the
    fit ``est`` against ``key`` (``pyramid`` the frame's, finest first): the
    ``cur_from_key`` (4x4) of those that fit as well as it.

    Fits start from ``est``'s pose moved along ``key``'s plane by RIVAL_STEPS of its distance
    in RIVAL_DIRECTIONS directions, and turned by RIVAL_TURNS_DEG either way about each
    camera axis (a narrow view trades a turn for a step: the minima 10-40 deg off that a
    moved start does not reach), and run down to the finest level no larger than
    RIVAL_SIDE (``est``'s own pose refitted there too, for a like msd). Those that end at
    least MOVED_SHARE of the distance or TURNED_DEG from the fit, within ALIAS_SHARE of the
    way from the best msd to chance and within RIVAL_MSD_RATIO of the best fit as well: on
    low texture the landscape is flat, and the fit's minimum is one of many. None replaces
    the fit: a coarse msd a little lower is no evidence (on the soak, switching to a
    clearly lower one mended as many scenarios as it broke); the row says how far the
    others lie instead."""
    h = key.plane.distance
    basis = np.linalg.svd(np.eye(3) - np.outer(key.plane.normal, key.plane.normal))[0][:, :2]
    starts = [est.cur_from_key]
    for k in RIVAL_STEPS:
        for a in np.arange(RIVAL_DIRECTIONS) * (2 * np.pi / RIVAL_DIRECTIONS):
            starts.append(shifted(est.cur_from_key, k * h * (basis @ (np.cos(a), np.sin(a)))))
    for deg in RIVAL_TURNS_DEG:
        for axis in np.eye(3):
            for sign in (-1.0, 1.0):
                turn = np.eye(4)
                turn[:3, :3] = so3_exp(np.radians(sign * deg) * axis)
                starts.append(turn @ est.cur_from_key)
    coarse = replace(options, interpolation="linear", relaxation=1.0, max_iterations=RIVAL_ITERATIONS,
                     step_tolerance_px=RIVAL_TOLERANCE_PX)
    lv = _level_within(pyramid, len(key.levels), RIVAL_SIDE)
    levels, pyr = key.levels[lv:], pyramid[lv:]
    fits = [estimate_motion(levels, pyr, s, options=coarse, gain=est.gain, bias=est.bias)
            for s in starts]
    ok = [f for f in fits if f.converged and np.isfinite(f.msd)]
    if not ok or not fits[0].converged:
        return []
    best = min(f.msd for f in ok)
    chance = levels[0].intensity_variance
    return [f.cur_from_key for f in ok
            if (_apart(est.cur_from_key, f.cur_from_key) >= MOVED_SHARE * h
                or _turned(est.cur_from_key, f.cur_from_key) >= np.radians(TURNED_DEG))
            and f.msd - best <= ALIAS_SHARE * max(chance - best, 0.0)
            and f.msd <= RIVAL_MSD_RATIO * best]


def rival_variance(poses: list[np.ndarray], motion_to, motion: np.ndarray) -> np.ndarray:
    """(6, 6) diagonal: per axis, the largest square of the differences (6,) between the
    motions of the rival ``poses`` (``motion_to(cur_from_key)``) and the fit's ``motion``
    (4x4): the farthest of the minima the images cannot tell from the fit's may be the
    truth (their mean outer product let the near ones dilute a far one: seed 40's
    scenario 193, 1.3 m off at 5-8.5 std)."""
    if not poses:
        return np.zeros((6, 6))
    d = np.array([motion_change(motion_to(pose), motion) for pose in poses])
    return np.diag(np.max(d ** 2, axis=0))


def pose_doubt(key, pyramid: list[np.ndarray], est, prediction_std: np.ndarray, motion_to,
               motion: np.ndarray, found, options) -> np.ndarray:
    """(6, 6) the doubt on which minimum an accepted fit ``est`` is: its aliases'
    (:func:`alias_variance`) and its rivals' (``found``, :func:`rival_variance`) variances, the
    arguments theirs."""
    return alias_variance(key, pyramid, est, prediction_std, motion_to, motion, options) \
        + rival_variance(found, motion_to, motion)
