"""Hindsight for what a run writes at its end: the keyframe planes smoothed over the whole
drive, and the poses re-scaled with them (docs/algorithm.md section 9, "The trajectory in
hindsight").

Every keyframe's plane is the MAP of what was known when it was anchored
(:mod:`monovo_cli.core.plane.belief`): the plane carried from the previous keyframe, the
images' normal and the mounting prior. The planes of the first keyframes are the least
certain, and frame 0's is init.yaml's: when the camera was at a crest of its suspension,
the first keyframes' scale is off by the crest's height over the distance. The backward pass
of the Rauch-Tung-Striebel smoother (:func:`~monovo_cli.core.plane.belief.smoothed_corrections`,
with the gains and innovations each re-anchor left in its
:class:`~monovo_cli.core.plane.belief.PlaneLink`) gives each keyframe's plane with the
knowledge of the keyframes after it.

The images fix a motion against a plane only through the plane-induced homography (a
keyframe ray ``x`` to ``R^T (I - t n^T / d) x`` in the frame camera): the motions of a
keyframe's segment, measured against its plane ``(n, d)``, are re-read against its smoothed
plane ``(n', d')`` (:func:`reread_motions`). Where only the distance changed that is exact
and simple: the translations scale by ``d' / d``, rotations unchanged. Where the tilt
changed too, no motion against the new plane maps every ray as before (the tilt's change
times the translation is a rank-one term a rotation cannot take), so the motion re-read is
the one whose homography comes closest, in the image, at the keyframe's own observation
points (its ``samples``): the least squares the images themselves would have solved, had
the tracker had the smoothed plane then. (On a drive whose frame 0 was a nominal mount, the
first keyframes' tilts move by tenths of a degree in hindsight, and their motions with
them: a rotation of the whole trajectory of 20-50 mdeg without this; benchmarks.initial_pose.)
A keyframe without samples (its points lifted off its plane by a terrain grid, or a record
from elsewhere), and every keyframe of a drive whose ground the re-anchors did not see as a
plane (:func:`smooth_drive`'s ``tilts``), has its translations scaled alone. Each
keyframe's pose is its predecessor's re-read pose composed with the re-read motion between
the two, and every frame's pose its keyframe's composed with its own re-read motion from
it, so the trajectory stays one rigid chain.

The distances. The backward pass smooths the keyframes' planes with the mounting prior as
the filter had it (centred on the mean mount: a declared one, or the latent one as far as
the drive had shown it): one sample of the ground's departure per keyframe, at the keyframe's own
frame. But the prior holds in every camera frame, and every frame's distance to its
keyframe's plane is known at the keyframe's scale (``d_f = d_k - n . c_f``, ``c_f`` the frame
camera's centre in the keyframe's): the suspension bobs over tens of frames, and a keyframe
drawn at a crest is a sample as far from the mean as the bobbing goes. So the distances are
solved again over the whole chain (:func:`smoothed_distances`): the carried distances of the
links with the variance the carrying added, and the mounting prior on the mean of
``log d_f`` over each keyframe's segment (:func:`segment_log_distance_ratios`) with the prior's own std
(the frames of a segment are not independent samples: together they weigh as one). A latent
mean mount's distance is one more unknown of that solution, so the segments' mean sets it and
frame 0's exact distance sets the scale. The tilts keep the backward pass's (they hardly move).

``motion.csv`` is written as frames are done and stays causal; trajectory.csv, .tum and the
terrain products (:mod:`monovo_cli.mapping.terrain_map`) are written with these poses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from monovo_cli.core.plane.belief import PlaneLink, from_chart, smoothed_corrections
from monovo_cli.geometry.lie import se3_inv, so3_exp_rows
from monovo_cli.geometry.plane import Plane

#: motions re-read at once (:func:`_reread_all`): a drive's peak memory stays flat with its
#: length (a chunk's arrays are about 1 MB), and the batch still amortises the calls (6000
#: motions re-read in the same time in chunks of 64 to 512 as all at once)
REREAD_CHUNK = 128


class Anchored(Protocol):
    """What hindsight needs of a keyframe (a :class:`~monovo_cli.core.keyframe.Keyframe`
    or a record of one): its pose, its plane (its camera) and its plane's link."""

    world_from_key: np.ndarray
    plane: Plane
    link: PlaneLink | None
    #: (m, 3) a few of its observation points, in its camera (None: none kept)
    samples: np.ndarray | None


def smoothed_distances(keys: Sequence[Anchored],
                       log_ratios: Sequence[float] | None = None) -> np.ndarray:
    """(K,) each keyframe's distance (m) solved over the whole chain, NaN where its links did
    not record what that takes (module docstring, "The distances").

    ``keys`` oldest first; ``log_ratios[k]`` the mean over the frames of keyframe k's segment
    (itself included) of ``log(d_f / d_k)``, a frame's distance to the keyframe's plane over
    the keyframe's (None: zeros, the keyframes alone). Unknowns ``u_k = log(d'_k / d_k)``;
    linear least squares over: each link's carried distance, ``u_{k+1} - u_k = log(d_c /
    d_{k+1})`` with std ``sqrt(propagated_variance) / d_c``; the mounting prior on each segment,
    ``u_k + log_ratios[k] - v = log(D_0 / d_k)`` with std ``sigma / D_0``, where ``D_0`` is the
    reference distance the links record and ``v = log(D / D_0)`` the mean mount's distance
    ``D`` relative to it: 0 for a declared mount, an unknown of its own for a latent one (with
    the prior ``v = 0`` of the same std only when no keyframe is held, so that the system stays
    determined); and a chain's first keyframe held at its distance with its own variance where
    that is much tighter than the prior's (frame 0's exact plane; not a nominal one, whose
    distance the images cannot confirm). The normal equations are tridiagonal, bordered by ``v``'s row
    and column when it is unknown (Thomas' algorithm and a Schur complement)."""
    K = len(keys)
    lift = np.zeros(K) if log_ratios is None else np.asarray(log_ratios, dtype=float)
    d = np.array([k.plane.distance for k in keys])
    diag, off, rhs = np.zeros(K), np.zeros(K), np.zeros(K)  # off[k]: between k-1 and k
    border, corner, rhs_v = np.zeros(K), 0.0, 0.0  # v's column, diagonal and right-hand side
    known = np.zeros(K, bool)
    latent = held = False
    prior_weight = 0.0
    for k in range(1, K):
        link = keys[k].link
        if link is None or not np.isfinite(link.propagated_distance):
            continue
        D0, sigma = link.mounting
        w = link.propagated_distance ** 2 / max(link.propagated_variance, 1e-12 * D0 ** 2)
        c = np.log(link.propagated_distance / d[k])
        diag[k - 1] += w
        diag[k] += w
        off[k] -= w
        rhs[k] += w * c
        rhs[k - 1] -= w * c
        before = keys[k - 1].link
        starts = k == 1 or before is None or not np.isfinite(before.propagated_distance)
        if starts and link.previous_variance < 1e-2 * sigma ** 2:  # held (exact)
            wp = d[k - 1] ** 2 / max(link.previous_variance, 1e-18)
            diag[k - 1] += wp
            held = True
        latent = latent or link.latent_mount
        for j in ((k - 1,) if starts else ()) + (k,):
            wp = (D0 / sigma) ** 2
            target = np.log(D0 / d[j]) - lift[j]
            diag[j] += wp
            rhs[j] += wp * target
            known[j] = True
            if link.latent_mount:
                border[j] -= wp
                corner += wp
                rhs_v -= wp * target
                prior_weight = wp
    diag = diag + np.where(known, 0.0, 1.0)
    if not latent:
        u = _tridiagonal(diag, off, rhs)
    else:
        if not held:
            corner += prior_weight
        x1 = _tridiagonal(diag, off, rhs)
        x2 = _tridiagonal(diag, off, border)
        v = (rhs_v - border @ x1) / (corner - border @ x2)
        u = x1 - x2 * v
    return np.where(known, d * np.exp(u), np.nan)


def _tridiagonal(diag: np.ndarray, off: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the symmetric tridiagonal system with ``diag`` (K,) and ``off[k]`` the entry
    between k-1 and k (``off[0]`` unused), positive definite."""
    K = len(diag)
    c, r = np.zeros(K), np.zeros(K)
    for k in range(K):
        m = diag[k] - (off[k] * c[k - 1] if k else 0.0)
        c[k] = off[k + 1] / m if k + 1 < K else 0.0
        r[k] = (rhs[k] - (off[k] * r[k - 1] if k else 0.0)) / m
    x = np.zeros(K)
    for k in range(K - 1, -1, -1):
        x[k] = r[k] - (c[k] * x[k + 1] if k + 1 < K else 0.0)
    return x


def smoothed_planes(keys: Sequence[Anchored], log_ratios: Sequence[float] | None = None
                    ) -> list[Plane]:
    """Each keyframe's plane (its camera) smoothed over the chain, ``keys`` oldest first: the
    tilts from the smoother's backward pass, the distance from :func:`smoothed_distances`
    (the backward pass's where that has none)."""
    delta = smoothed_corrections([k.link for k in keys])
    dist = smoothed_distances(keys, log_ratios)
    out = []
    for k, x, dk in zip(keys, delta, dist):
        if np.isfinite(dk):
            x = np.r_[dk - k.plane.distance, x[1:]]
        out.append(k.plane if not np.any(x) else from_chart(k.plane, x))
    return out


def _segments(index: Sequence[int], world_from_cam: np.ndarray,
              keys: Sequence[tuple[int, Anchored]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per keyframe of ``keys`` (``(frame index, keyframe)``, oldest first): the rows of the
    frames ``index`` in its segment (from it to the next keyframe) and their poses
    ``world_from_cam`` (N, 4, 4) in its camera, ``key_from_cam`` (n, 4, 4)."""
    at = np.array([i for i, _ in keys])
    seg = np.searchsorted(at, np.asarray(index), side="right") - 1
    out = []
    for a, (_, key) in enumerate(keys):
        rows = np.flatnonzero(seg == a)
        out.append((rows, np.einsum("ij,njk->nik", se3_inv(key.world_from_key),
                                    world_from_cam[rows])))
    return out


def _mean_log_distance_ratio(key: Anchored, key_from_cam: np.ndarray) -> float:
    """The mean of ``log(d_f / d_k)`` over a segment's frames at ``key_from_cam`` (n, 4, 4):
    each frame camera's distance to the keyframe's plane over the keyframe's."""
    n, dk = key.plane.normal, key.plane.distance
    r = (dk - key_from_cam[:, :3, 3] @ n) / dk
    r = r[np.isfinite(r) & (r > 0.5) & (r < 2.0)]
    return float(np.mean(np.log(r))) if len(r) else 0.0


def segment_log_distance_ratios(index: Sequence[int], world_from_cam: np.ndarray,
                  keys: Sequence[tuple[int, Anchored]]) -> list[float]:
    """Per keyframe of ``keys`` (``(frame index, keyframe)``, oldest first), the mean over the
    frames ``index`` of its segment, at poses ``world_from_cam`` (N, 4, 4), of ``log(d_f /
    d_k)``: the frame camera's distance to the keyframe's plane over the keyframe's."""
    return [_mean_log_distance_ratio(key, rel) for (_, key), (_, rel) in
            zip(keys, _segments(index, world_from_cam, keys))]


def reread_motions(key_from_cam: np.ndarray, plane: Plane, smoothed: Plane,
                   samples: np.ndarray | None, iterations: int = 2) -> np.ndarray:
    """(n, 4, 4): the motions ``key_from_cam`` (n, 4, 4), measured against a keyframe's
    ``plane``, re-read against its ``smoothed`` plane (module docstring).

    ``samples`` (m, 3): points in the keyframe's camera whose rays carry the image evidence
    (its observation points; only their directions count). Same normal, or no samples: the
    translations scaled by ``d' / d``. Otherwise, from there, Gauss-Newton over each
    motion's rotation (right-multiplied) and translation on the reprojection, in normalised
    image coordinates, of the rays' points on the smoothed plane onto where the motion put
    their points on ``plane``; rays behind either camera are left out."""
    return _reread_all([(key_from_cam, plane, smoothed, samples)], iterations)[0]


def _reread_all(jobs: Sequence[tuple[np.ndarray, Plane, Plane, np.ndarray | None]],
                iterations: int = 2) -> list[np.ndarray]:
    """:func:`reread_motions` of every ``(key_from_cam, plane, smoothed, samples)`` of
    ``jobs``, the Gauss-Newton of their motions REREAD_CHUNK at a time (a drive's few thousand
    frames, re-read at every checkpoint: its arrays are (motions, samples, 2, 6), which over
    all the motions at once grew the run's peak memory with its length)."""
    out, Xo, Xs, where = [], [], [], []
    for j, (motions, plane, smoothed, samples) in enumerate(jobs):
        M = np.array(motions, dtype=float).reshape(-1, 4, 4)
        M[:, :3, 3] *= smoothed.distance / plane.distance
        out.append(M)
        if samples is None or len(samples) < 3 or not len(M) or \
                np.array_equal(smoothed.normal, plane.normal):
            continue
        rays = np.asarray(samples, dtype=float)
        rays = rays[(rays @ plane.normal > 0) & (rays @ smoothed.normal > 0)]
        if len(rays) < 3:
            continue
        Xo.append(rays * (plane.distance / (rays @ plane.normal))[:, None])
        Xs.append(rays * (smoothed.distance / (rays @ smoothed.normal))[:, None])
        where.append(j)
    if not where:
        return out
    m = max(len(x) for x in Xo)
    n = [len(out[j]) for j in where]
    rows = np.repeat(np.arange(len(where)), n)  # the job of every motion to re-read
    pad = np.zeros((len(where), m, 3))
    X, Y, V = pad.copy(), pad.copy(), np.zeros((len(where), m), bool)
    for a, (x, y) in enumerate(zip(Xo, Xs)):
        X[a, :len(x)], Y[a, :len(y)], V[a, :len(x)] = x, y, True
    T = np.concatenate([np.asarray(jobs[j][0], dtype=float).reshape(-1, 4, 4) for j in where])
    M = np.concatenate([out[j] for j in where])
    for lo in range(0, len(M), REREAD_CHUNK):
        at = slice(lo, lo + REREAD_CHUNK)
        M[at] = _reread_chunk(X[rows[at]], Y[rows[at]], V[rows[at]], T[at], M[at], iterations)
    for j, part in zip(where, np.split(M, np.cumsum(n)[:-1])):
        out[j] = part
    return out


def _reread_chunk(X: np.ndarray, Y: np.ndarray, V: np.ndarray, T: np.ndarray, M: np.ndarray,
                  iterations: int) -> np.ndarray:
    """The motions ``M`` (n, 4, 4) re-read: each the pose from which the points ``Y`` (n, m,
    3; on the smoothed plane) project where the points ``X`` (on the keyframe's plane) did
    from ``T`` (n, 4, 4), at the samples ``V`` (n, m) holds; Gauss-Newton from ``M``."""
    R, t = T[:, :3, :3], T[:, :3, 3]
    P = (X - t[:, None]) @ R  # R^T (X - t) per point, (n, m, 3)
    seen = V & (P[..., 2] > 1e-9)
    target = P[..., :2] / np.where(seen, P[..., 2], 1.0)[..., None]
    R2, t2 = M[:, :3, :3].copy(), M[:, :3, 3].copy()
    for _ in range(iterations):
        Q = (Y - t2[:, None]) @ R2
        ok = seen & (Q[..., 2] > 1e-9)
        iz = np.where(ok, 1.0 / np.where(ok, Q[..., 2], 1.0), 0.0)
        u, v = Q[..., 0] * iz, Q[..., 1] * iz
        r = np.stack([u - target[..., 0], v - target[..., 1]], axis=-1) * ok[..., None]
        # the normalised projection's derivatives: R2 <- R2 exp(w) moves Q by Q x w, and
        # t2 <- t2 + R2 e by -e
        J = np.zeros(Q.shape[:-1] + (2, 6))
        J[..., 0, 0], J[..., 0, 1], J[..., 0, 2] = u * v, -(1.0 + u * u), v
        J[..., 1, 0], J[..., 1, 1], J[..., 1, 2] = 1.0 + v * v, -u * v, -u
        J[..., 0, 3], J[..., 0, 5] = -iz, u * iz
        J[..., 1, 4], J[..., 1, 5] = -iz, v * iz
        J *= ok[..., None, None]
        J = J.reshape(len(J), -1, 6)
        Jt = J.transpose(0, 2, 1)
        H = Jt @ J + 1e-12 * np.eye(6)
        step = -np.linalg.solve(H, Jt @ r.reshape(len(J), -1, 1))[..., 0]
        t2 = t2 + (R2 @ step[:, 3:, None])[..., 0]
        R2 = R2 @ so3_exp_rows(step[:, :3])
    out = M.copy()
    out[:, :3, :3], out[:, :3, 3] = R2, t2
    return out


def smoothed_key_poses(keys: Sequence[Anchored], planes: Sequence[Plane],
                       samples: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
    """(K, 4, 4) the keyframes' poses re-read with their smoothed ``planes``: the first
    keeps its pose, each next one is its predecessor's composed with the motion between the
    two re-read against the predecessor's smoothed plane (:func:`reread_motions`, with
    ``samples[k]`` of keyframe k; None: every translation scaled alone)."""
    steps = _reread_all([(se3_inv(prev.world_from_key) @ key.world_from_key, prev.plane,
                          planes[a], None if samples is None else samples[a])
                         for a, (prev, key) in enumerate(zip(keys[:-1], keys[1:]))])
    out = np.empty((len(keys), 4, 4))
    for a, key in enumerate(keys):
        out[a] = key.world_from_key if a == 0 else out[a - 1] @ steps[a - 1][0]
    return out


@dataclass(frozen=True, eq=False)
class SmoothedDrive:
    """A drive's keyframes and poses smoothed in hindsight (module docstring).

    ``key_index`` (K,) the keyframes' frame indices, oldest first; ``planes`` (K) each
    keyframe's smoothed plane in its own camera frame; ``world_from_key`` (K, 4, 4) their
    re-scaled poses; ``world_from_cam`` (N, 4, 4) every frame's re-scaled pose.
    """

    key_index: tuple[int, ...]
    planes: tuple[Plane, ...]
    world_from_key: np.ndarray
    world_from_cam: np.ndarray

    def keyframe(self, index: int) -> tuple[Plane, np.ndarray]:
        """The smoothed plane and pose ``world_from_key`` (4, 4) of the keyframe at frame
        ``index``."""
        a = self.key_index.index(int(index))
        return self.planes[a], self.world_from_key[a]


def smooth_drive(index: Sequence[int], world_from_cam: np.ndarray,
                 keys: Sequence[tuple[int, Anchored]], *, segments: bool = True,
                 tilts: bool = False, planes: Sequence[Plane] | None = None) -> SmoothedDrive:
    """The poses ``world_from_cam`` (N, 4, 4) of frames ``index`` (N,), in order, re-read
    with the smoothed planes of ``keys`` (``(frame index, keyframe)``, oldest first): each
    frame's motion from the latest keyframe at or before it scaled by that keyframe's
    ``d' / d``, and with ``tilts`` re-read against its smoothed tilt too where the keyframe
    kept samples (:func:`reread_motions`; for a ground the re-anchors saw as a plane: on
    terrain the keyframes' tilts are of different ground, and the smoother's, which takes
    them for one plane's, moved the rolling drives' ends 0.25 -> 1.36 %). Frames before the
    first keyframe keep their poses. ``segments`` False: the mounting prior at the keyframes
    alone, as the filter had it (for comparison). ``planes`` (K) given instead of the smoothed
    ones (each keyframe's in its own camera: e.g. the true planes, to tell the re-reading's
    error from the smoother's)."""
    W = np.asarray(world_from_cam, dtype=float)
    if not keys:
        return SmoothedDrive((), (), np.zeros((0, 4, 4)), W.copy())
    anchored = [k for _, k in keys]
    parts = _segments(index, W, keys)
    log_ratios = ([_mean_log_distance_ratio(k, rel) for k, (_, rel) in zip(anchored, parts)]
                  if segments else None)
    planes = smoothed_planes(anchored, log_ratios) if planes is None else list(planes)
    samples = [k.samples if tilts else None for k in anchored]
    key_poses = smoothed_key_poses(anchored, planes, samples)
    out = W.copy()
    reread = _reread_all([(rel, key.plane, planes[a], samples[a])
                          for a, (key, (_, rel)) in enumerate(zip(anchored, parts))])
    for a, ((rows, _), rel) in enumerate(zip(parts, reread)):
        if len(rows):
            out[rows] = np.einsum("ij,njk->nik", key_poses[a], rel)
    return SmoothedDrive(tuple(int(i) for i, _ in keys), tuple(planes), key_poses, out)


def smoothed_keyframes(keys: Sequence[tuple[int, Anchored]]) -> SmoothedDrive:
    """:func:`smooth_drive` of the keyframes ``keys`` (``(frame index, keyframe)``, oldest
    first) alone, the mounting prior at each keyframe's own frame: for a map kept without its
    frames' poses."""
    W = np.array([k.world_from_key for _, k in keys]).reshape(-1, 4, 4)
    return smooth_drive([i for i, _ in keys], W, keys, segments=False)


def smoothed_poses(index: Sequence[int], world_from_cam: np.ndarray,
                   keys: Sequence[tuple[int, Anchored]], *, segments: bool = True) -> np.ndarray:
    """(N, 4, 4): :func:`smooth_drive`'s ``world_from_cam``."""
    return smooth_drive(index, world_from_cam, keys, segments=segments).world_from_cam
