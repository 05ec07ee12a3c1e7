"""The keyframe's observation points spread over the image (``ground._even_spread``)."""

from __future__ import annotations

import numpy as np
import pytest

from monovo_cli.core.estimator.ground import _even_spread


def _check(score, ys, xs, cap):
    assert len(ys) == min(cap, int(np.count_nonzero(score > 0)))
    assert np.all(score[ys, xs] > 0)
    flat = ys * score.shape[1] + xs
    assert np.all(np.diff(flat) > 0)  # row-major, no pixel twice


@pytest.mark.parametrize("seed", range(3))
def test_a_cap_of_half_the_area_keeps_the_strongest_first_of_equals_in_row_major_order(seed):
    """Blocks of 2x2 would keep every candidate: the cap's strongest are kept, and of the
    pixels equal to the weakest kept, the first in row-major order (scores on a few levels,
    as Sobel magnitudes of 8-bit images are, so that ties are many)."""
    rng = np.random.default_rng(seed)
    score = rng.integers(0, 6, (64, 80)).astype(np.float32)
    cap = int(np.count_nonzero(score > 0)) // 2
    ys, xs = _even_spread(score, cap, 2 * cap)
    _check(score, ys, xs, cap)
    chosen = np.zeros(score.shape, bool)
    chosen[ys, xs] = True
    weakest = score[chosen].min()
    assert np.all(score[~chosen & (score > 0)] <= weakest)
    equal = np.flatnonzero((score == weakest).ravel())
    taken = chosen.ravel()[equal]
    assert np.all(taken[:np.count_nonzero(taken)])  # the first ones of the equal scores


def test_a_small_cap_spreads_the_points_over_the_image():
    """A cap of 1/16 of the area: blocks of 8x8 keep up to 4 each, so a strong corner cannot
    take them all (every 8x8 block of a uniform image gets its share)."""
    score = np.ones((64, 64), np.float32)
    score[:8, :8] = 100.0
    ys, xs = _even_spread(score, 256, score.size)
    _check(score, ys, xs, 256)
    blocks = np.zeros((8, 8), int)
    np.add.at(blocks, (ys // 8, xs // 8), 1)
    assert np.all(blocks == 4)


def test_fewer_candidates_than_the_cap_are_all_kept():
    score = np.zeros((20, 30), np.float32)
    score[3, 4] = score[10, 2] = score[10, 20] = 1.0
    ys, xs = _even_spread(score, 10, score.size)
    assert ys.tolist() == [3, 10, 10] and xs.tolist() == [4, 2, 20]
