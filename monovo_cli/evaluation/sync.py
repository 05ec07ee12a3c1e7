"""Pairing an estimated trajectory's poses with the ground truth's by time (``monovo eval``).

Each estimated pose is matched to the ground-truth pose nearest in time, within ``max_dt``
(default :func:`default_max_dt`: 0.02 s, or half the estimate's median frame interval if
that is less), each true pose to at most one estimated pose.
"""

from __future__ import annotations

import numpy as np

from monovo_cli.errors import InputError

MAX_DT = 0.02  # s, the default matching tolerance (less for frames closer than 0.04 s)


def default_max_dt(ts_est: np.ndarray) -> float:
    """The default matching tolerance (s): ``MAX_DT``, or half the median interval of the
    estimate's timestamps ``ts_est`` (N,) s if that is less, so that no two frames can
    match one true pose."""
    ts = np.sort(np.asarray(ts_est, dtype=float))
    if len(ts) < 2:
        return MAX_DT
    return float(min(MAX_DT, 0.5 * np.median(np.diff(ts))))


def _span(ts: np.ndarray) -> str:
    return f"{float(ts.min())!r}..{float(ts.max())!r} s"


def match_timestamps(ts_est: np.ndarray, ts_gt: np.ndarray, *, max_dt: float | None = None,
                     names: tuple[str, str] = ("estimate", "ground truth"),
                     hint: str = "max_dt sets the tolerance"
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``(i_est, i_gt)`` pairing each estimated pose with the true pose nearest
    in time, within ``max_dt`` s (None: :func:`default_max_dt`), in the estimate's time order.

    Poses with no partner within ``max_dt`` are left out (a partial run); a true pose nearest
    to two estimated ones goes to the closer. InputError if either holds a timestamp twice
    or no pose matches (the message ends with ``hint``).
    """
    ts_est, ts_gt = np.asarray(ts_est, dtype=float), np.asarray(ts_gt, dtype=float)
    for ts, name in ((ts_est, names[0]), (ts_gt, names[1])):
        if len(ts) == 0:
            raise InputError(f"{name}: no poses")
    for ts, name in ((ts_est, names[0]), (ts_gt, names[1])):
        s = np.sort(ts)
        dup = np.nonzero(np.diff(s) <= 1e-9)[0]
        if len(dup):
            raise InputError(f"{name}: timestamp {float(s[dup[0]])!r} is given more than once")
    tol = default_max_dt(ts_est) if max_dt is None else float(max_dt)
    oe, og = np.argsort(ts_est, kind="stable"), np.argsort(ts_gt, kind="stable")
    se, sg = ts_est[oe], ts_gt[og]
    j = np.clip(np.searchsorted(sg, se), 1, max(len(sg) - 1, 1))
    cand = np.stack([j - 1, np.minimum(j, len(sg) - 1)], 1)
    near = cand[np.arange(len(se)), np.argmin(np.abs(sg[cand] - se[:, None]), axis=1)]
    dt = np.abs(sg[near] - se)
    taken = np.zeros(len(sg), bool)
    keep = np.zeros(len(se), bool)
    for i in np.argsort(dt, kind="stable"):  # the closest pairs first
        if dt[i] > tol:
            break
        if not taken[near[i]]:
            taken[near[i]] = keep[i] = True
    if not keep.any():
        raise InputError(f"none of the {len(se)} timestamps of {names[0]} ({_span(se)}) is "
                         f"within {tol:g} s of one of {names[1]} ({_span(sg)}); is it the "
                         f"ground truth of this sequence? ({hint})")
    return oe[keep], og[near[keep]]


def match_frames(frames_est: np.ndarray, frames_gt: np.ndarray, *,
                 names: tuple[str, str] = ("estimate", "ground truth")
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``(i_est, i_gt)`` pairing poses with equal frame numbers (ints (N,) and
    (M,)), for trajectories without timestamps (KITTI poses: frame i is line i), in the
    estimate's order. InputError if either gives a frame twice or none is shared."""
    fe, fg = np.asarray(frames_est, dtype=np.int64), np.asarray(frames_gt, dtype=np.int64)
    for f, name in ((fe, names[0]), (fg, names[1])):
        if len(f) == 0:
            raise InputError(f"{name}: no poses")
        u, c = np.unique(f, return_counts=True)
        if (c > 1).any():
            raise InputError(f"{name}: frame {int(u[c > 1][0])} is given more than once")
    at = {int(k): j for j, k in enumerate(fg)}
    ie = np.array([i for i, k in enumerate(fe) if int(k) in at], dtype=int)
    if not len(ie):
        raise InputError(f"none of the frames {int(fe.min())}..{int(fe.max())} of {names[0]} "
                         f"is among the frames {int(fg.min())}..{int(fg.max())} of {names[1]}")
    return ie, np.array([at[int(fe[i])] for i in ie], dtype=int)


MIN_COVERAGE = 0.5  # a match is partial below this fraction of the estimate's poses or span


def coverage(keys_est: np.ndarray, i_est: np.ndarray) -> tuple[float, float]:
    """``(poses, span)``: the fractions of the estimate's poses that matched (``i_est`` of
    ``len(keys_est)``) and of its span of timestamps or frames ``keys_est`` (N,) that the
    matched ones cover (1 for a single-instant estimate)."""
    keys = np.asarray(keys_est, dtype=float)
    span = float(keys.max() - keys.min())
    got = keys[np.asarray(i_est)]
    covered = float(got.max() - got.min()) / span if span > 0 and len(got) else 1.0
    return len(i_est) / len(keys), covered


def check_coverage(keys_est: np.ndarray, i_est: np.ndarray, *, by_time: bool, max_dt: float,
                   names: tuple[str, str] = ("estimate", "ground truth")) -> None:
    """InputError (one line, saying how many matched and what to do) unless the matched poses
    are at least :data:`MIN_COVERAGE` of the estimate's poses and cover at least that
    fraction of its span (``keys_est`` (N,): timestamps s if ``by_time``, else frames)."""
    poses, span = coverage(keys_est, i_est)
    if poses >= MIN_COVERAGE and span >= MIN_COVERAGE:
        return
    keys = np.asarray(keys_est, dtype=float)
    got = keys[np.asarray(i_est)]
    unit = "s" if by_time else "frames"
    how = (f"within {max_dt:g} s; max_dt sets the tolerance" if by_time
           else "by frame number")
    raise InputError(f"{names[0]}: only {len(i_est)} of its {len(keys)} poses match "
                     f"{names[1]} ({how}), spanning {float(got.max() - got.min()):.4g} of its "
                     f"{float(keys.max() - keys.min()):.4g} {unit}; if the truth is sparser than "
                     "the estimate or covers less of the drive, allow a partial match to "
                     "evaluate over these poses only, else check that both use one clock")
