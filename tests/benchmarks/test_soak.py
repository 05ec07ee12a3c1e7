"""The scenario soak's CI slice (issue 40): small scenarios drawn by benchmarks.soak's
generator with fixed seeds, each tracked and held to the soak's invariants.

``draw(SEED, index, tiny=True)`` (the first PER_CLASS of each class): 96-160 px, 8-15
frames, otherwise the soak's whole box (terrain, turns, jerks, textures, lighting, blank,
corrupt and dropped frames). monovo runs in-process through click's CliRunner with the
soak's arguments: the exit status is the one the command line returns (an internal error is
exit 1 there too). A failing scenario replays with ``python -m benchmarks.soak --seed 40
--tiny --only INDEX --keep /tmp/x``.

Scenarios that fail today on a tracker defect are marked ``xfail(strict=True)`` with the
defect named, so that the fix shows as an XPASS to be unmarked; the invariants themselves
are never loosened here.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from benchmarks.soak import CLASSES, draw, judge, render, track_command
from monovo_cli.cli import main
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.io.formats import read_motion_csv

SEED = 40
PER_CLASS = 7


def _stratified(per_class: int) -> list[int]:
    """The first ``per_class`` tiny scenarios of each class, in index order."""
    picked: dict[str, list[int]] = {c: [] for c in CLASSES}
    index = 0
    while any(len(v) < per_class for v in picked.values()):
        k = draw(SEED, index, tiny=True).klass
        if len(picked[k]) < per_class:
            picked[k].append(index)
        index += 1
    return sorted(i for v in picked.values() for i in v)


INDICES = _stratified(PER_CLASS)
# index -> the defect that makes it fail today (see the module docstring)
KNOWN: dict[int, str] = {
    6: "drift: two turns in place of ~22 deg/frame (45 deg field of view, 144 px) are lost and "
       "the re-initialisation after them leaves 0.21 m of end error on a 1.3 m arc (16 % > 10 %)",
    32: "drift: two frames lost under a moving shadow (no better than chance) and the "
        "re-initialisation after them leave 3.6 cm of end error on a 14 cm path (25 % > 10 %)",
}


def _case(index: int):
    sc = draw(SEED, index, tiny=True)
    marks = [pytest.mark.xfail(strict=True, reason=KNOWN[index])] if index in KNOWN else []
    return pytest.param(index, id=f"{index:02d}-{sc.klass}", marks=marks)


def _tracked(sc, tmp_path):
    """The soak's verdict on scenario ``sc``, rendered and tracked in ``tmp_path``."""
    seq, out = tmp_path / "seq", tmp_path / "out"
    render(sc, seq)
    r = CliRunner().invoke(main, track_command(seq, out, 1))
    return judge(sc, seq, out, r.exit_code, r.output)


def test_the_slice_is_wide():
    """The slice covers every class and the box's damage kinds (not only easy drives)."""
    scenarios = [draw(SEED, i, tiny=True) for i in INDICES]
    assert len(scenarios) >= 30
    assert {s.klass for s in scenarios} == set(CLASSES)
    assert any(s.ground == "rocks" for s in scenarios) and any(s.dropped for s in scenarios)
    assert any(s.corrupt for s in scenarios) and any(s.blank for s in scenarios)
    assert all(96 <= min(s.width, s.height) and max(s.width, s.height) <= 160 and 8 <= s.frames <= 15
               for s in scenarios)


def test_a_scenario_is_replayed_exactly():
    assert draw(SEED, 7, tiny=True) == draw(SEED, 7, tiny=True)
    assert draw(SEED, 7, tiny=True) != draw(SEED, 8, tiny=True)


@pytest.mark.parametrize("index", [_case(i) for i in INDICES])
def test_scenario_holds_the_invariants(index, tmp_path):
    sc = draw(SEED, index, tiny=True)
    verdict = _tracked(sc, tmp_path)
    assert not verdict.failures, (f"{sc.klass}: {', '.join(verdict.failures)}\n  {sc.describe()}\n  "
                                  + "\n  ".join(verdict.details) + f"\n  replay: {sc.replay()}")


# A scenario of the full box that showed a defect the issue names, kept as a regression test
# with every drawn value spelled out (the box may change; this stays).
IGNITION = replace(draw(40, 13), frames=22, blank=(14,), corrupt=((10, "empty"),))


def test_the_soak_crash_drive_runs_to_the_end_and_its_rows_say_what_they_know(tmp_path):
    """The drive the soak stopped on with ``internal error: IndexError`` (exit 1) at frame 9,
    after three lost frames: ``step -> _resolve_gap -> estimate_motion(ref.levels, pyr,
    ...)``, the gap re-solved against a keyframe with more pyramid levels than the frame's
    pyramid (192 px, wheels climbing rocks, zigzagging 0.68 m steps). Now every frame has
    its row and the run exits 0 or 3.

    Its rows 17-19, after the gap was re-solved 7 deg off, were then written ok 9-12 deg off
    at 19-37 std; the rival minima sought turned as well as moved
    (:func:`monovo_cli.core.aliases.rivals`) now cover them. The drift stays (10 of 21
    frames lost, 43 % of the path)."""
    seq, out = tmp_path / "seq", tmp_path / "out"
    render(IGNITION, seq)
    r = CliRunner().invoke(main, track_command(seq, out, 1))
    assert r.exit_code in (0, 3), r.output
    rows = (out / "motion.csv").read_text().splitlines()
    assert len(rows) == 1 + 21
    verdict = judge(IGNITION, seq, out, r.exit_code, r.output)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_the_crash_scenario_is_the_one_that_failed():
    """The crash scenario as the soak drew it at 29e2d18 (seed 40, index 13, 22 frames)."""
    assert (IGNITION.width, IGNITION.frames, IGNITION.mode, IGNITION.ground, IGNITION.climb,
            IGNITION.texture) == (192, 22, "zigzag", "rocks", True, "gravel")
    assert round(IGNITION.step * IGNITION.cam_height, 2) == 0.68 and IGNITION.blank == (14,)


def test_a_fit_that_flips_the_view_of_the_ground_is_not_written_ok(tmp_path):
    """Seed 41's tiny scenario 88 (160 px, low texture, 0.39 m steps, frame 3 dropped): frame
    2's fit converged to a wrong minimum 51 deg off in pitch, 0.86 m off, at the drive's msd
    level, and was written ``reanchored`` with a std 5 times too small. A fit that turns the
    ground's tilt by more than MAX_TILT_STEP_DEG in one frame is no longer accepted."""
    sc = draw(41, 88, tiny=True)
    assert (sc.width, sc.frames, sc.texture, sc.dropped) == (160, 8, "low", (3,))
    verdict = _tracked(sc, tmp_path)
    assert not verdict.failures, "\n".join(verdict.details)


def test_a_step_the_checkerboard_cannot_tell_from_another_says_so(tmp_path):
    """Seed 40's scenario 12 (192 px, a checkerboard, spinning in place at 5.7 deg a frame
    with 2.4 cm of bobbing): from frame 17 on the fit sat one period of the board away from
    the truth, 8.8 cm, at the drive's msd level, written ``ok`` at 32-44 std. The images
    cannot tell such steps apart; the row's std now holds the period where the prediction
    cannot pick the minimum (:mod:`monovo_cli.core.aliases`). The drift stays: no tracker
    can recover a period it was never shown."""
    sc = draw(40, 12)
    assert (sc.width, sc.frames, sc.mode, sc.texture) == (192, 25, "spin", "checker")
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_a_standing_start_on_low_texture_states_the_minima_it_cannot_exclude(tmp_path):
    """Seed 40's scenario 209 (192x144, low texture over rocks, 1.25 m steps from a standing
    start at frame 0): frame 1's fit stayed near the start, 1.3 m off, and rows 1-5 were
    written ok at 85-336 std; the images there leave minima all around as good as the
    fit's. Where no prediction picks the minimum, fits from starts around it now find them
    and the row's std holds their spread (:func:`monovo_cli.core.aliases.rivals`). The
    drift stays."""
    sc = draw(40, 209)
    assert (sc.width, sc.height, sc.frames, sc.texture, sc.ground) == (192, 144, 12, "low", "rocks")
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_a_turn_after_a_dropped_frame_states_the_turned_minima_it_cannot_exclude(tmp_path):
    """Seed 40's scenario 28 (160 px gravel, MER turns of 17.5 deg, noise variance 23, a
    moving shadow, frame 22 dropped): frame 24, the first after a re-initialisation, was
    written ok 25 deg off in pitch at 22.5 std. The starts around a fit no prediction pins
    were moved along the plane only; turned ones now find the minima that trade a turn for
    a step (:func:`monovo_cli.core.aliases.rivals`), and the row's std reaches the farthest.
    The drift stays: 7 of 24 frames are lost."""
    sc = draw(40, 28)
    assert (sc.width, sc.frames, sc.mode, sc.texture, sc.dropped) == (160, 26, "mer", "gravel", (22,))
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_steps_past_the_capture_range_after_a_loss_state_the_minima_they_cannot_exclude(tmp_path):
    """Seed 40's scenario 193 (384x288, the wheels climbing rocks, 1.29 m steps, 0.74 of the
    camera's height): after frames 4-10 were lost, frames 13-16 were written 1.3-1.4 m and
    7-11 deg off at 5-8.5 std, a short step the images fit as well as the true one. The
    rival minima, now sought turned as well as moved, and the farthest of them in the
    std (not their mean, which the near ones diluted), cover them. The drift stays."""
    sc = draw(40, 193)
    assert (sc.width, sc.height, sc.frames, sc.ground, sc.climb) == (384, 288, 17, "rocks", True)
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_a_gap_re_solved_to_a_turn_no_ground_allows_is_not_taken(tmp_path):
    """Seed 40's scenario 297, cut to 9 frames (384 px checkerboard at noise variance 24, a
    moving shadow, 0.74 m steps): frames 4-5 were lost, and frame 6, re-solved from frame 3
    across the gap, landed turned by 153 deg (125 deg in pitch at 7.1 std) and was written
    ``reinit``. The re-solved step is now held to the one-frame tilt bound once per frame of
    the gap; refused, the frame re-initialises at the prediction, whose std covers it. In
    the full soak, 286, 297, 322 and 463 (re-solved 95-135 deg off) hold every invariant
    after the same change."""
    sc = replace(draw(40, 297), frames=9)
    assert (sc.width, sc.texture, sc.shadow is not None) == (384, "checker", True)
    verdict = _tracked(sc, tmp_path)
    assert not verdict.failures, "\n".join(verdict.details)


def test_low_texture_under_heavy_noise_states_the_std_its_gradients_allow(tmp_path):
    """Seed 40's scenario 399, cut to 12 frames (384 px, a texture of 8.5 grey levels' std
    at noise variance 29.6, turns of 12.9 deg in place): frame 10 was written ok 1.6 deg off
    in pitch at 6.2 std, and rows of the full drive up to 9.8. The keyframe's gradients at
    its points were mostly noise, and the normal matrix took them for texture; the noise std
    is now widened by how little of them the next frame shares
    (:mod:`monovo_cli.core.estimator.gradient_noise`). The drift stays."""
    sc = replace(draw(40, 399), frames=12)
    assert (sc.width, sc.texture, sc.noise_var) == (384, "low", pytest.approx(29.6, abs=0.05))
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_a_wrong_minimum_after_a_loss_on_noisy_gravel_says_so(tmp_path):
    """Seed 40's scenario 312 (128 px gravel at noise variance 28.2, a moving shadow, rolling
    ground, a jerking camera): after seven lost frames, frame 13 converged on the 80 of the
    keyframe's points still in view to a pose whose view of the ground was turned 91 deg, and
    frame 15, anchored there, was written ``reanchored`` 19.7 deg off in rx at 4.3 std. No
    keyframe could be anchored at frames 13 and 14: the region's rays missed the plane.
    A pose at which the ground would not fill the region is now no fit
    (:func:`monovo_cli.core.checks.off_the_ground`): frame 13 is lost, and so are the
    frames after it."""
    sc = draw(40, 312)
    assert (sc.width, sc.texture, sc.frames) == (128, "gravel", 20)
    verdict = _tracked(sc, tmp_path)
    assert "untrusted" not in verdict.failures, "\n".join(verdict.details)


def test_a_row_after_one_a_period_off_on_a_checkerboard_states_that_period(tmp_path):
    """Seed 40's scenario 83, cut to 9 frames (192x144 checkerboard on rocks at noise
    variance 28, turns of 19.6 deg a frame): frames 6 and 7 converged a period off (0.15-0.2
    m, their std covering it with their aliases' variance), and frame 8, fitted against the
    same keyframe, came back: its motion was 0.19 m off in tz with a std of 0.0045 m (41
    std), the previous pose's doubt nowhere in it. That doubt is now the next motion's too
    (``frame_std.from_predicted``, as a lost frame's is); the drift stays."""
    sc = replace(draw(40, 83), frames=9)
    assert (sc.texture, sc.ground, sc.width, sc.height) == ("checker", "rocks", 192, 144)
    verdict = _tracked(sc, tmp_path)
    assert set(verdict.failures) <= {"drift"}, "\n".join(verdict.details)


def test_a_jerking_camera_on_noisy_low_texture_is_re_tried_from_the_capture(tmp_path):
    """Seed 40's scenario 51 (160 px rocks of low texture at noise variance 27.3, the camera
    jerking by 3.2 deg): from frame 7 on the prediction led the fit into wrong minima 2-15
    deg off whose robust msd was 1.3-2.5x the recent frames', and they were accepted (frame
    7 at 11.7 std). Such a fit is now re-tried from the capture's starts
    (``checks.FitChecks.doubtful``), which find the right minimum: every accepted row of
    frames 1-20 is within 1 deg of the truth (before: up to 21.7 deg off).

    Frame 21's fit, 12 deg off, fits better than the truth (robust msd 62 against 76), so no
    re-try can find the truth; it was written reanchored at 30 std. The prediction there was
    10-15 deg uncertain (the jerks), so it does not pick the minimum, and the rival search now
    runs (``aliases.unpinned``): the row states the minima it cannot exclude."""
    sc = draw(40, 51)
    assert (sc.width, sc.texture, sc.ground) == (160, "low", "rocks")
    seq, out = tmp_path / "seq", tmp_path / "out"
    render(sc, seq)
    r = CliRunner().invoke(main, track_command(seq, out, 1))
    assert r.exit_code in (0, 3)
    verdict = judge(sc, seq, out, r.exit_code, r.output)
    assert "untrusted" not in verdict.failures, "\n".join(verdict.details)
    frames, motions, statuses = read_motion_csv(out / "motion.csv")
    truth = dict(zip(*read_motion_csv(seq / "groundtruth_motion.csv")[:2]))
    off = {int(f): np.degrees(np.linalg.norm(so3_log((se3_inv(truth[f]) @ m)[:3, :3])))
           for f, m, s in zip(frames, motions, statuses) if f <= 20 and s in ("ok", "reanchored")}
    assert len(off) >= 18
    assert max(off.values()) < 1.0, off


def test_lost_rows_after_re_initialisations_that_measured_nothing_keep_the_prediction_doubt(tmp_path):
    """Seed 40's scenario 295 (128 px, steps of the camera's height, 0.97 m: past the capture
    range from the start, and frame 16 a double step over a dropped frame): no frame is ever
    tracked, the tracker re-initialises every third frame, and each re-initialisation reset
    the prediction's random walk to a standing start's 0.48 m. Frame 16, 1.97 m off, was
    written lost at 4.1 std. A re-initialisation that re-solves no gap measures no motion, so
    the walk now goes on from the last motion measured (here none): frame 16's std is 1.9 m.
    Scenario 3 (320 px, 2.7 m steps, frame 8 6.5 m off at 4.6 std) was the same."""
    sc = draw(40, 295)
    assert (sc.width, sc.frames, sc.dropped) == (128, 23, (16,))
    verdict = _tracked(sc, tmp_path)
    assert not verdict.failures, "\n".join(verdict.details)


@pytest.mark.xfail(strict=True, reason=(
    "frame 14, after a turn in place of 15 deg: the prediction repeats the turn and the fit "
    "from it stays there, 20 deg from the straight step taken (msd 92.2, the level 98.6); "
    "the rival search's turned starts do not reach the truth and the row says 4.4 deg, 4.5 "
    "std. With the keyframe planes' beliefs widened by the gradient-noise factor the drive "
    "takes another branch (frames 8-9 lost) than the one this test was written on"))
def test_rows_against_a_keyframe_plane_far_from_the_mount_state_its_departure(tmp_path):
    """Seed 40's scenario 307 (384 px low texture on rocks at noise variance 19.1, turns in
    place of 18 deg): the keyframes' normals turned away from the truth, 21 deg at frame 11
    and 29 deg at frame 15, their tilts reported with a std of 2.4-3.3 deg each, and frames
    16 and 17 were written ok at 4.8 and 18.9 std. The rover stands on its ground, so a
    keyframe plane that the mounting prior cannot reconcile with its own tilt states that
    departure in every row measured against it (``PlaneTracker.reported``). Cut to 18
    frames, the drive did not show the defect: the test runs all 30."""
    sc = draw(40, 307)
    assert (sc.width, sc.texture, sc.ground, sc.frames) == (384, "low", "rocks", 30)
    verdict = _tracked(sc, tmp_path)
    assert "untrusted" not in verdict.failures, "\n".join(verdict.details)


def test_a_doubtful_fit_kept_after_its_re_try_states_its_excess(tmp_path):
    """Seed 40's scenario 479 (320 px, a nadir camera, zigzag steps of 1 m): frame 8's fit
    from the prediction left a robust msd 4.2x the recent frames'. Re-tried, the capture
    came back to the same fit, and the rival search found no minimum within reach; it was
    written reanchored, 0.15 m off in ty at 4.5 std. A doubtful fit that is kept now widens
    its row's reported variance by that excess (``FitChecks.excess``)."""
    sc = draw(40, 479)
    assert (sc.width, sc.frames, sc.ground) == (320, 15, "flat")
    verdict = _tracked(sc, tmp_path)
    assert "untrusted" not in verdict.failures, "\n".join(verdict.details)


def test_a_first_frame_past_the_capture_range_states_its_excess_over_the_noise(tmp_path):
    """Seed 40's scenario 207 (320 px low texture on rocks, 0.85 m steps, frames 1 and 2
    dropped): frame 1 is three steps (3.6 m) from frame 0, past the capture range, and its fit
    from the standing start is a wrong minimum written ok 1.4 m off in tz at 5.2 std. With no
    recent frames to compare it with it is not re-tried (a closer fit there is as often the
    wrong one), but its robust msd is 2.3x what the two images' noise leaves, and that excess
    now widens its row as a kept doubtful fit's does (``FitChecks.excess``)."""
    sc = draw(40, 207)
    assert (sc.width, sc.texture, sc.ground, sc.dropped) == (320, "low", "rocks", (1, 2, 14))
    verdict = _tracked(sc, tmp_path)
    assert "untrusted" not in verdict.failures, "\n".join(verdict.details)


def test_a_capture_after_re_initialisations_that_measured_nothing_covers_the_truth(tmp_path):
    """Seed 40's scenario 138 (224x168 low texture on rocks, 0.54 m steps): frames 1-9 are
    lost or re-initialised. Before the prediction's random walk went on through them, frame
    10 stayed lost and the drive failed its drift bound (54 %); then frame 10 was captured
    ok, a wrong minimum 8.6, -11.6 and -9.9 deg off in rx, ry, rz whose std (the fit's and
    the rival minima's spread) was 2.3 deg in rz: 4.3 std. It is the first fit against the
    keyframe the last re-initialisation anchored, with no recent frames to compare it with,
    and its excess over the two images' noise now widens its row (``FitChecks.excess``):
    1.4 std. The drift holds."""
    sc = draw(40, 138)
    assert (sc.width, sc.height, sc.texture, sc.ground) == (224, 168, "low", "rocks")
    verdict = _tracked(sc, tmp_path)
    assert not verdict.failures, "\n".join(verdict.details)


def test_the_first_fits_after_a_re_initialisation_are_held_to_the_drive_s_level(tmp_path):
    """Seed 41's scenario 414 (384x288 on flat ground, 1.74 m steps from 2.76 m: each frame
    keeps 13-39 % of its keyframe's points in view): frames 22 and 23 were lost and frame 24
    re-initialised. The re-initialisation cleared the recent frames' msd, so the fits of
    frames 25-27, wrong minima 12-16 deg off with a robust msd 20-60x the drive's level (the
    two images' noise leaves 6), were held to nothing and written reanchored at 8-10 std.
    The scene and the camera are the same after a loss, so the level carries over: those
    fits now fail as any fit that far above it does, and are written lost."""
    sc = draw(41, 414)
    assert (sc.width, sc.height, sc.ground, sc.frames) == (384, 288, "flat", 29)
    verdict = _tracked(sc, tmp_path)
    assert "msd" not in verdict.failures, "\n".join(verdict.details)


def test_keyframe_planes_on_noisy_low_texture_weigh_the_images_as_their_gradients_allow(tmp_path):
    """Seed 40's scenario 77 (160 px low texture on rolling ground at noise variance 6.9,
    blank frames 4 and 10): the keyframe anchored after the blank frame stood on a plane
    about 11 deg off, its tilt reported at 3.8-4 deg, and frame 7 was written ok 4.4 std
    off; the drive ended 0.72 m off (17 %). The normal the images measure and the motion a plane
    is carried by took the keyframe's noisy gradients as texture; widened by its noise
    factor (as the rows' std is) the mounting prior keeps its weight."""
    sc = draw(40, 77)
    assert (sc.width, sc.texture, sc.ground, sc.blank) == (160, "low", "rolling", (4, 10))
    verdict = _tracked(sc, tmp_path)
    assert verdict.failures == [], "\n".join(verdict.details)
