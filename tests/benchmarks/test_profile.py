"""benchmarks.profile: its parts add up to the run they time, and its timers come off again."""

from __future__ import annotations

import time

import benchmarks.profile as profile
from monovo_cli.core.estimator import estimate
from monovo_cli.core.odometry import Odometry
from monovo_cli.io.sources.base import FrameSource


def test_the_parts_add_up_to_the_run(small_drive, tmp_path):
    originals = (FrameSource.read, Odometry._accept, estimate._solve_level, estimate.residuals)
    profile.profile_drive(small_drive, tmp_path / "warm")  # the imports and caches, once
    t0 = time.perf_counter()
    p = profile.profile_drive(small_drive, tmp_path / "out")
    whole = time.perf_counter() - t0
    assert p.frames == 10
    # every part is measured, none counted twice ("other", the rest of the loop, is not < 0)
    assert all(p.parts[part] > 0 for part in profile.PARTS), p.parts
    assert p.parts["other"] >= 0 and p.parts_cpu["other"] >= -1e-3, (p.parts, p.parts_cpu)
    # the named parts hold most of the frame loop; with "other" they are all of it
    assert sum(p.parts[part] for part in profile.PARTS) >= 0.5 * p.loop
    per_frame = sum(p.ms_per_frame(part) for part in (*profile.PARTS, "other"))
    assert abs(per_frame - 1000 * p.loop / p.frames) <= 1e-6 * per_frame
    # and the loop, what came before it and what came after are the call, timed from outside
    # (with the timers' installation)
    assert abs(p.before + p.loop + p.finish - whole) <= 0.1 * whole
    # the nested measures sit inside their parts; the limit is a fraction of a frame
    wall = {k: v[0] for k, v in p.inside.items()}
    assert wall["remap"] <= wall["residual evaluations"] <= p.parts["estimator"] + 1e-9
    assert p.inside["residual evaluations"][2] >= p.inside["level solves"][2] > 0
    assert 0 < p.limit_ms < 1000 * p.loop / p.frames
    assert (FrameSource.read, Odometry._accept, estimate._solve_level,
            estimate.residuals) == originals
    assert "| decode (PNG read) |" in profile.table([(128, p, (0.5, 0.03, 0.3))])


def test_start_up_is_timed_to_the_first_decode(small_drive, tmp_path):
    total, interpreter, imports = profile.startup(small_drive, tmp_path / "out", repeats=1)
    assert 0 < interpreter < total and 0 < imports < total
