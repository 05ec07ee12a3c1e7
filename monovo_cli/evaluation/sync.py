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
