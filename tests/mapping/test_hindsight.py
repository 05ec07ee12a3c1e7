"""The poses re-scaled in hindsight (monovo_cli.mapping.smoothing), against hand-made chains."""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from monovo_cli import track_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.plane.belief import PlaneLink, from_chart
from monovo_cli.core.run import KeyRecord, RunRecorder
from monovo_cli.geometry.lie import make_pose, se3_exp, se3_inv, so3_exp, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.mapping.smoothing import (
    reread_motions,
    segment_log_distance_ratios,
    smooth_drive,
    smoothed_distances,
    smoothed_poses,
)
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.synth.write import synthesize
from tests.helpers.plane_helpers import N0


def drive(n: int) -> np.ndarray:
    """(n, 4, 4) a camera over the plane N0 (1.5 m below), moving 5 cm per frame along the
    ground and turning 1 deg per frame about its normal: the true poses, camera 0 = world."""
    fwd = np.cross(N0, [1.0, 0.0, 0.0])
    out, T = [np.eye(4)], np.eye(4)
    for _ in range(n - 1):
        T = T @ make_pose(so3_exp(-N0 * math.radians(1.0)), 0.05 * fwd)
        out.append(T)
    return np.array(out)


def measured(truth: np.ndarray, keys: list[int], scale: dict[int, float]) -> np.ndarray:
    """The poses a tracker composes when every motion of keyframe ``k``'s segment came out
    with its translation times ``scale[k]`` (a plane ``scale[k]`` times too far)."""
    out = truth.copy()
    seg = np.searchsorted(keys, np.arange(len(truth)), side="right") - 1
    for i in range(1, len(truth)):
        step = se3_inv(truth[i - 1]) @ truth[i]
        step[:3, 3] *= scale[keys[seg[i - 1]]]
        out[i] = out[i - 1] @ step
    return out


def test_a_keyframe_the_chain_corrects_puts_its_segment_and_all_after_it_back():
    """Keyframe 0's plane was 1.54 m where the ground is 1.5 m below (frame 0 at a crest):
    its segment's translations came out 1.54 / 1.5 too long and every later pose carries
    that. Its successor's link says -4 cm (gain 1), so hindsight re-scales the segment and
    the poses after it fall back on the truth; keyframes 5 and 9 were right and stay."""
    truth = drive(14)
    keys = [0, 5, 9]
    est = measured(truth, keys, {0: 1.54 / 1.5, 5: 1.0, 9: 1.0})
    assert np.linalg.norm(est[-1][:3, 3] - truth[-1][:3, 3]) > 0.006  # 25 cm at 2.7 %
    planes = [Plane(N0, 1.54), Plane(N0, 1.5), Plane(N0, 1.5)]
    links = [None, PlaneLink(np.eye(3), np.array([-0.04, 0.0, 0.0])),
             PlaneLink(np.eye(3), np.zeros(3))]
    records = [(k, KeyRecord(k, est[k], p, link)) for k, p, link in zip(keys, planes, links)]
    out = smoothed_poses(range(14), est, records)
    assert out == pytest.approx(truth, abs=1e-12)
    # no link (a chain that begins at each keyframe, or --no-smooth): nothing moves
    plain = [(k, KeyRecord(k, est[k], p, None)) for k, p in zip(keys, planes)]
    assert smoothed_poses(range(14), est, plain) == pytest.approx(est, abs=1e-12)


def test_hindsight_keeps_the_last_keyframe_of_an_index_and_frames_before_the_first():
    """A keyframe rebuilt in place replaces the one of its index; frames before the first
    keyframe (none in a run, where frame 0 is one) keep their poses."""
    truth = drive(10)
    est = measured(truth, [0, 4], {0: 1.0, 4: 1.02})
    rec = RunRecorder()

    def add(k, link):
        rec.add_keyframe(SimpleNamespace(index=k, world_from_key=est[k], plane=Plane(N0, 1.5),
                                         link=link))

    def poses():
        return smoothed_poses(range(10), est, [(k.index, k) for k in rec.keyframes])

    add(4, None)
    add(6, PlaneLink(np.eye(3), np.array([0.9, 0, 0])))
    add(6, None)  # the rebuilt one: no link
    out = poses()
    assert out == pytest.approx(est, abs=1e-12)
    add(9, PlaneLink(np.eye(3), np.array([-0.03, 0, 0])))
    out = poses()
    assert out[:7] == pytest.approx(est[:7], abs=1e-12)  # keyframe 4 has no successor link
    step = se3_inv(est[6]) @ est[7]
    assert np.linalg.norm(out[7][:3, 3] - out[6][:3, 3]) == pytest.approx(
        np.linalg.norm(step[:3, 3]) * 1.47 / 1.5, rel=1e-12)


def bobbing_chain(held: bool = False) -> tuple[np.ndarray, np.ndarray, list]:
    """A camera that bobs 3 cm over the plane N0 with a period of 10 frames, keyframes at
    frames 0, 10 and 20: all at crests, 1.53 m above the ground whose nominal distance
    (init.yaml) is 1.5 m. The tracker anchored frame 0 on 1.5 m, so every translation came
    out 1.5 / 1.53 too short, and the chain carried that exactly (its links' carried
    distances are the keyframes' own). ``held``: keyframe 0's plane confirmed as exact.
    Returns ``(true poses, measured poses, keys)``."""
    along = drive(30)
    truth = along.copy()
    for f in range(30):  # raise the camera: its distance to the ground 1.5 + 0.03 cos
        truth[f][:3, 3] += (1.53 - (1.5 + 0.03 * math.cos(2 * math.pi * f / 10))) * N0
    s = 1.5 / 1.53
    est = truth.copy()
    est[:, :3, 3] *= s  # (positions scale with the translations: same rotations)
    start = 1e-14 if held else 0.05 ** 2
    keys = [(0, KeyRecord(0, est[0], Plane(N0, 1.5), None))]
    for k in (10, 20):
        link = PlaneLink(np.eye(3), np.zeros(3), propagated_distance=1.5, propagated_variance=0.03 ** 2,
                         previous_variance=start if k == 10 else 0.04 ** 2, mounting=(1.5, 0.05))
        key_plane = Plane(se3_inv(est[k])[:3, :3] @ est[0][:3, :3] @ N0, 1.5)
        keys.append((k, KeyRecord(k, est[k], key_plane, link)))
    return truth, est, keys


def test_the_mounting_prior_holds_over_each_segment_s_frames_not_its_keyframe_alone():
    """Every keyframe is at a crest: by the keyframes alone the chain is at its nominal
    distance and nothing moves; over their segments' frames the camera is on average at the
    nominal distance, so the keyframes are 1.53 m up and the trajectory comes back to the
    truth (measured: 1.9 % of the distance at the end -> 0.010 %)."""
    truth, est, keys = bobbing_chain()
    anchored = [k for _, k in keys]
    assert smoothed_distances(anchored) == pytest.approx([1.5, 1.5, 1.5], abs=1e-9)
    log_ratios = segment_log_distance_ratios(range(30), est, keys)
    assert log_ratios[0] == pytest.approx(math.log(1.5 / 1.53), abs=2e-4)
    assert smoothed_distances(anchored, log_ratios) == pytest.approx([1.53] * 3, abs=3e-4)
    path = float(np.sum(np.linalg.norm(np.diff(truth[:, :3, 3], axis=0), axis=1)))
    before = np.linalg.norm(est[-1][:3, 3] - truth[-1][:3, 3]) / path
    out = smoothed_poses(range(30), est, keys)
    after = np.linalg.norm(out[-1][:3, 3] - truth[-1][:3, 3]) / path
    assert before > 0.01 and after < 2e-4
    # rotations are the images' and stay
    assert out[:, :3, :3] == pytest.approx(est[:, :3, :3], abs=1e-12)


def test_a_keyframe_plane_confirmed_as_exact_is_held_in_hindsight():
    """init.yaml confirmed by the images (keyframe 0's distance variance ~0): keyframe 0
    keeps its distance; the later ones move only as far as their priors outweigh the chain."""
    _, est, keys = bobbing_chain(held=True)
    anchored = [k for _, k in keys]
    d = smoothed_distances(anchored, segment_log_distance_ratios(range(30), est, keys))
    assert d[0] == pytest.approx(1.5, abs=1e-9)
    assert 1.5 < d[1] < d[2] < 1.53


def test_the_summary_s_path_is_the_written_trajectory_s(tmp_path, capsys):
    """`monovo track` prints the path length of trajectory.csv (re-scaled in hindsight), not
    of motion.csv's motions composed, with -o DIR and with -o - alike."""
    synthesize(tmp_path / "seq", preset="drive", terrain="flat", frames=30, size=(192, 192),
               noise_var=10.0, seed=4)
    s = track_sequence(tmp_path / "seq", None, tmp_path / "out", TrackOptions())
    _, traj = read_tum(tmp_path / "out" / "trajectory.tum")
    path = float(np.sum(np.linalg.norm(np.diff(traj[:, :3, 3], axis=0), axis=1)))
    assert s.path_length == pytest.approx(path, rel=1e-6)
    streamed = track_sequence(tmp_path / "seq", None, None, TrackOptions())
    assert capsys.readouterr().out.count("\n") == 30  # the header and 29 rows
    assert streamed.path_length == s.path_length


def _rays() -> np.ndarray:
    u, v = np.meshgrid(np.linspace(-0.4, 0.4, 7), np.linspace(-0.1, 0.4, 6))
    return np.c_[u.ravel(), v.ravel(), np.ones(u.size)]


def _seen(motion: np.ndarray, plane: Plane, rays: np.ndarray) -> np.ndarray:
    """Where a frame camera at ``motion`` (key_from_cam) sees the keyframe rays' points on
    ``plane``: (m, 2) normalised image coordinates."""
    X = rays * (plane.distance / (rays @ plane.normal))[:, None]
    P = (X - motion[:3, 3]) @ motion[:3, :3]
    return P[:, :2] / P[:, 2:]


def _fit(motion: np.ndarray, src: Plane, dst: Plane, rays: np.ndarray) -> np.ndarray:
    """The motion against ``dst`` whose image of the rays comes closest to ``motion``'s
    against ``src``: numeric Gauss-Newton over se3_exp, written apart from the module's."""
    target = _seen(motion, src, rays)
    W = motion.copy()
    W[:3, 3] *= dst.distance / src.distance
    for _ in range(20):
        r = (_seen(W, dst, rays) - target).ravel()
        J = np.column_stack([((_seen(W @ se3_exp(h), dst, rays) - target).ravel() - r) / 1e-7
                             for h in 1e-7 * np.eye(6)])
        W = W @ se3_exp(-np.linalg.lstsq(J, r, rcond=None)[0])
    return W


def test_a_motion_re_read_against_a_new_tilt_is_the_one_its_images_fit_best():
    """A 30 cm motion measured against the true ground, re-read against a plane 0.6 / -0.4
    deg off and 2 cm further: the module's two Gauss-Newton steps land on the independent fit
    (to 1e-3 mdeg and 1e-5 mm; measured 3e-5 mdeg), 87 mdeg from the motion kept with its
    translation scaled; re-read back
    against the true plane it returns to the motion within 0.5 mdeg and 0.02 mm (second order
    in the tilt's change times the motion, what no rotation can take)."""
    true = Plane(N0, 1.5)
    off = from_chart(true, np.array([0.02, math.radians(0.6), math.radians(-0.4)]))
    T = make_pose(so3_exp(np.radians([0.3, -0.5, 0.8])),
                  0.3 * np.cross(N0, [1.0, 0.0, 0.0]) + np.array([0.02, 0.01, 0.0]))
    rays = _rays()
    against_off = reread_motions(T[None], true, off, rays)[0]
    expected = _fit(T, true, off, rays)
    assert np.degrees(np.linalg.norm(so3_log(expected[:3, :3].T @ against_off[:3, :3]))) < 1e-6
    assert against_off[:3, 3] == pytest.approx(expected[:3, 3], abs=1e-8)
    scaled = reread_motions(T[None], true, off, None)[0]
    assert scaled[:3, :3] == pytest.approx(T[:3, :3], abs=1e-15)
    assert np.degrees(np.linalg.norm(so3_log(scaled[:3, :3].T @ against_off[:3, :3]))) > 0.08
    back = reread_motions(against_off[None], off, true, rays)[0]
    assert np.degrees(np.linalg.norm(so3_log(T[:3, :3].T @ back[:3, :3]))) < 5e-4
    assert back[:3, 3] == pytest.approx(T[:3, 3], abs=2e-5)


def _long_drive_jobs(n: int) -> list:
    """Re-reading jobs of a drive of ``n`` frames: 40 keyframes' segments, each re-read
    against a plane 0.5 deg off with 40 samples (a drive's records keep about 32)."""
    rng = np.random.default_rng(5)
    true = Plane(N0, 1.5)
    jobs = []
    for seg in np.array_split(np.arange(n), 40):
        off = from_chart(true, np.r_[0.01, np.radians(rng.uniform(-0.5, 0.5, 2))])
        motions = np.array([make_pose(so3_exp(np.radians(rng.normal(0.0, 0.5, 3))),
                                      0.3 * rng.normal(size=3) * [1.0, 0.2, 1.0]) for _ in seg])
        rays = np.c_[rng.uniform(-0.4, 0.4, 40), rng.uniform(-0.1, 0.4, 40), np.ones(40)]
        jobs.append((motions, true, off, rays))
    return jobs


def test_a_long_drive_is_re_read_a_chunk_at_a_time_with_the_same_motions(monkeypatch):
    """The re-reading's arrays are (motions, samples, 2, 6): over a whole drive at once they
    grew monovo track's peak memory with the drive's length (+33 % from 500 to 5000 frames
    at 512², `benchmarks.speed --memory`). A chunk at a time gives the same motions to the
    bit, and its peak stays that of one chunk (measured: 4.5 MB at 6000 motions against
    94 MB at once)."""
    import tracemalloc

    import monovo_cli.mapping.smoothing as smoothing

    jobs = _long_drive_jobs(6000)
    chunked = smoothing._reread_all(jobs)
    tracemalloc.start()
    try:
        smoothing._reread_all(jobs)
        peak_chunked = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        monkeypatch.setattr(smoothing, "REREAD_CHUNK", 10 ** 9)
        whole = smoothing._reread_all(jobs)
        peak_whole = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert all(np.array_equal(a, b) for a, b in zip(chunked, whole))
    assert any(not np.array_equal(a, job[0]) for a, job in zip(chunked, jobs))  # (re-read)
    assert peak_chunked < 8e6 < 40e6 < peak_whole


def test_a_distance_change_alone_scales_the_translations_exactly():
    """Same normal: the homography is kept exactly by scaling the translations, bit for bit
    what hindsight did before it re-read tilts."""
    T = drive(6)
    out = reread_motions(T, Plane(N0, 1.5), Plane(N0, 1.53), _rays())
    expected = T.copy()
    expected[:, :3, 3] *= 1.53 / 1.5
    assert np.array_equal(out, expected)


def test_hindsight_re_reads_a_nominal_drive_s_motions_against_the_tilts_it_solved(tmp_path):
    """A flat 256² drive whose init.yaml is the nominal mount (frame 0 at a crest, tilted
    about 2 deg from it): the first keyframes' tilts move in hindsight, and with their
    motions re-read against them the trajectory's rotation stays within 40 mdeg of the truth
    on every frame (measured 24.5), where scaling the translations alone left the rotation
    up to 136 mdeg off and the end 6.4 mm off (3.3 re-read)."""
    seq = tmp_path / "seq"
    synthesize(seq, preset="drive", terrain="flat", frames=80, size=(256, 256), noise_var=10.0,
               seed=3, init_pose="nominal")
    run = track_frames(seq / "frames", load_init(seq / "init.yaml"))
    _, truth = read_tum(seq / "groundtruth.tum")
    assert all(k.samples is not None and len(k.samples) > 30 for k in run.keyframes)
    scaled = smoothed_poses(run.index, run.world_from_cam,
                            [(k.index, replace(k, samples=None)) for k in run.keyframes])

    def worst_mdeg(poses):
        return max(1e3 * np.degrees(np.linalg.norm(so3_log(g[:3, :3].T @ e[:3, :3])))
                   for g, e in zip(truth, poses))

    assert worst_mdeg(run.trajectory) < 40.0 < 100.0 < worst_mdeg(scaled)
    end = np.linalg.norm(run.trajectory[-1][:3, 3] - truth[-1][:3, 3])
    assert end < 0.005 < np.linalg.norm(scaled[-1][:3, 3] - truth[-1][:3, 3])


def test_planes_given_replace_the_smoothed_ones():
    """``smooth_drive(planes=...)`` re-reads every segment against the planes given (how
    benchmarks.hindsight tells the re-reading's error from the smoother's). A drive whose
    keyframes took their ground 0.3 deg off in tilt and 1 cm too far, each motion the one its
    images fit best against that plane, comes back onto the true poses when the true planes
    are given (to the second order of the tilt's error times the motion: 0.005 mm and
    0.12 mdeg measured, from 4.1 mm off), and stays as it was when its own planes are given."""
    truth = drive(12)
    keys, rays = [0, 4, 8], _rays()
    true_planes = [Plane(N0, 1.5).in_frame(se3_inv(truth[k])) for k in keys]
    tilt = so3_exp(np.radians([0.3, 0.0, 0.0]))
    wrong = [Plane(tilt @ p.normal, p.distance + 0.01) for p in true_planes]
    seg = np.searchsorted(keys, np.arange(12), side="right") - 1
    est = np.empty_like(truth)
    for i in range(12):
        a = seg[i] if i not in keys or i == 0 else seg[i] - 1  # a keyframe: its predecessor's
        k = keys[a]
        rel = _fit(se3_inv(truth[k]) @ truth[i], true_planes[a], wrong[a], rays)
        est[i] = (np.eye(4) if k == 0 else est[k]) @ rel
    assert np.abs(est[:, :3, 3] - truth[:, :3, 3]).max() > 0.003  # 3 mm and more off
    records = [(k, KeyRecord(k, est[k], p, None, 3.0 * rays)) for k, p in zip(keys, wrong)]
    back = smooth_drive(range(12), est, records, tilts=True, planes=true_planes).world_from_cam
    assert np.abs(back[:, :3, 3] - truth[:, :3, 3]).max() < 5e-5
    for b, t in zip(back, truth):
        assert np.degrees(np.linalg.norm(so3_log(b[:3, :3] @ t[:3, :3].T))) < 1e-3
    same = smooth_drive(range(12), est, records, tilts=True, planes=wrong).world_from_cam
    assert same == pytest.approx(est, abs=1e-12)
