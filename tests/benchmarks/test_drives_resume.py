"""benchmarks.drives' resume criterion: tracking has resumed after a fault at the first frame
that is not lost and whose position relative to frame 0 is within 1 cm of the truth again."""

from __future__ import annotations

import numpy as np

from benchmarks.drives import frames_to_resume

N = 100  # frames, 5 cm apart: a 4.95 m drive, so 1 % of its distance is 5 cm


def _drive(offset: dict[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """Truth and estimate (N, 4, 4) T_0_j of a straight drive, the estimate ``offset[j]`` m off
    sideways at frame j."""
    gt = np.repeat(np.eye(4)[None], N, axis=0)
    gt[:, 0, 3] = 0.05 * np.arange(N)
    est = gt.copy()
    for j, d in offset.items():
        est[j, 1, 3] += d
    return est, gt


def test_resumes_where_the_error_is_back_within_1_cm():
    status = ["ok"] * N
    status[11] = "lost"
    est, gt = _drive({11: 0.3, 12: 0.05, 13: 0.009})
    assert frames_to_resume(10, status, est, gt) == 3


def test_an_error_the_fault_left_behind_is_never_resumed():
    """5 cm off from the fault on: within 1 % of the distance, but not within 1 cm."""
    est, gt = _drive({j: 0.05 for j in range(11, N)})
    assert frames_to_resume(10, ["ok"] * N, est, gt) is None
