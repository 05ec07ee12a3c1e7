"""The keyframe plane's belief: fusion and propagation against hand-computed cases."""

import math

import numpy as np
import pytest
import yaml

from monovo_cli.core.odometry import Odometry, estimate_frames
from monovo_cli.core.plane.belief import (
    PlaneBelief,
    chart_jacobian,
    default_sigmas,
    from_chart,
    fuse,
    keyframe_plane,
    measured_tilt,
    mounting_prior,
    propagate,
    propagated_plane,
    tilt_std_deg,
    to_chart,
    transported,
    widened,
    with_mount_departure,
)
from monovo_cli.core.plane.tracker import Mounting
from monovo_cli.core.run import RunRecorder
from monovo_cli.errors import ConfigError
from monovo_cli.geometry.lie import make_pose, se3_inv, so3_exp
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.mapping.smoothing import smoothed_keyframes, smoothed_poses
from monovo_cli.mapping.terrain_map import TerrainMap
from monovo_cli.synth.motion import camera_mount
from monovo_cli.synth.render import (
    GroundRenderer,
    default_camera,
    finish_frame,
    ground_in_camera,
    ground_region,
)
from monovo_cli.synth.texture import GroundTexture, procedural_texture
from tests.helpers.plane_helpers import N0, tilted


def test_chart_round_trip_and_jacobian():
    ref = Plane(N0, 1.5)
    p = tilted(ref, 0.03, -0.02, 0.1)
    x = to_chart(ref, p)
    back = from_chart(ref, x)
    assert np.allclose(back.normal, p.normal, atol=1e-12) and back.distance == pytest.approx(1.6)
    # tilting along e1 by a small angle moves chart coordinate 1 by that angle
    assert to_chart(ref, tilted(ref, 1e-4))[1:] == pytest.approx([1e-4, 0.0], abs=1e-10)
    # chart Jacobian against finite differences
    J = chart_jacobian(ref, p)
    h = 1e-7
    num = np.column_stack([(to_chart(ref, from_chart(p, h * e)) - to_chart(ref, p)) / h
                           for e in np.eye(3)])
    assert np.allclose(J, num, atol=1e-5)


def test_fuse_two_distances_by_hand():
    # d = 1.0 (var 0.01) and 1.2 (var 0.03): (100 * 1.0 + 33.33 * 1.2) / 133.33 = 1.05, var 0.0075
    a = PlaneBelief.from_covariance(Plane(N0, 1.0), np.diag([0.01, 1e-4, 1e-4]))
    b = PlaneBelief.from_covariance(Plane(N0, 1.2), np.diag([0.03, 1e-4, 1e-4]))
    f = fuse([a, b])
    assert f.plane.distance == pytest.approx(1.05, abs=1e-12)
    assert np.allclose(f.plane.normal, N0, atol=1e-12)
    assert f.covariance[0, 0] == pytest.approx(0.0075, rel=1e-9)
    assert f.covariance[1, 1] == pytest.approx(5e-5, rel=1e-9)


def test_fuse_two_tilts_by_hand():
    # tilt 0 (std 1 deg) and 0.02 rad (std 2 deg) along e1: (0 * 4 + 0.02 * 1) / 5 = 0.004 rad,
    # variance 1 / (1/s1^2 + 1/s2^2) = 0.8 deg^2
    ref = Plane(N0, 1.5)
    s1, s2 = math.radians(1.0), math.radians(2.0)
    a = PlaneBelief.from_covariance(ref, np.diag([0.01, s1 ** 2, s1 ** 2]))
    b = PlaneBelief.from_covariance(tilted(ref, 0.02), np.diag([0.01, s2 ** 2, s2 ** 2]))
    f = fuse([a, b])
    angle = math.acos(min(1.0, float(f.plane.normal @ N0)))
    assert angle == pytest.approx(0.004, abs=2e-6)  # (the chart's curvature: O(angle^3))
    assert to_chart(ref, f.plane)[1] > 0 and abs(to_chart(ref, f.plane)[2]) < 1e-9
    assert math.degrees(math.sqrt(f.covariance[1, 1])) ** 2 == pytest.approx(0.8, rel=1e-3)


def test_fuse_measurement_without_distance_and_correlated_prior():
    # belief a: d and tilt 1 correlated, cov [[4e-4, 1e-5], [1e-5, 1e-4]]; measurement b: tilt 1
    # = 0.01 rad with variance 1e-4 and no information on d (a zero row). Kalman by hand:
    # gain on the tilt = 1e-4 / (1e-4 + 1e-4) = 0.5 -> tilt 0.005; d += 1e-5 / 2e-4 * 0.01
    # = 5e-4; var d = 4e-4 - (1e-5)^2 / 2e-4 = 3.995e-4.
    ref = Plane(N0, 1.5)
    cov = np.array([[4e-4, 1e-5, 0.0], [1e-5, 1e-4, 0.0], [0.0, 0.0, 1e-4]])
    a = PlaneBelief.from_covariance(ref, cov)
    info = np.zeros((3, 3))
    info[1, 1] = 1e4
    b = PlaneBelief(ref, info, np.array([0.0, 1e4 * 0.01, 0.0]))  # the mean: tilt 0.01 in ref's chart
    f = fuse([a, b])
    x = to_chart(ref, f.plane)  # (linear up to the chart's curvature, O(tilt^2) relative)
    assert x[1] == pytest.approx(0.005, abs=5e-7)
    assert x[0] == pytest.approx(5e-4, abs=5e-8)
    assert f.covariance[0, 0] == pytest.approx(3.995e-4, rel=1e-4)
    with pytest.raises(ValueError):
        fuse([b])  # nothing on the distance


def test_propagate_by_hand():
    n = np.array([0.0, 0.0, 1.0])
    key = Plane(n, 1.5)
    P = np.diag([1e-4, 4e-6, 1e-6])  # tilt 1 and tilt 2 differ
    # the camera moves 0.3 m toward the plane: d_c = 1.2, a distance error scales by 1.2/1.5
    T = make_pose(np.eye(3), np.array([0.0, 0.0, -0.3]))
    Q = np.diag([4e-6, 0, 0, 0, 0, 0])  # motion noise in v_x only: along the plane
    b = propagate(key, P, T, Q)
    assert b.plane.distance == pytest.approx(1.2)
    assert b.covariance[0, 0] == pytest.approx((1.2 / 1.5) ** 2 * 1e-4)
    Q[2, 2] = 9e-6  # noise along the normal adds to the distance
    assert propagate(key, P, T, Q).covariance[0, 0] == pytest.approx(0.64e-4 + 9e-6)
    # a quarter turn about the normal swaps the two tilt variances
    R = so3_exp(np.array([0.0, 0.0, math.pi / 2]))
    b = propagate(key, P, make_pose(R, np.zeros(3)), np.zeros((6, 6)))
    assert np.allclose(np.diag(b.covariance), [1e-4, 1e-6, 4e-6])
    # rotation noise about an axis in the plane tilts the normal by that much
    Q = np.zeros((6, 6))
    Q[3, 3] = 1e-6  # about x
    c = propagate(key, np.diag([1e-4, 0.0, 0.0]) + np.diag([0, 1e-12, 1e-12]), np.eye(4), Q)
    assert np.trace(c.covariance[1:, 1:]) == pytest.approx(1e-6, rel=1e-5)


def test_keyframe_plane_halves_the_prior_when_nothing_moved():
    plane = Plane(N0, 1.5)
    prior = mounting_prior(plane, 0.05, 3.0)
    f = keyframe_plane(propagated_plane(plane, prior.covariance, np.eye(4), np.zeros((6, 6))),
                       prior=prior)
    assert np.allclose(f.covariance, prior.covariance / 2)
    assert f.plane == Plane(f.plane.normal, 1.5) and np.allclose(f.plane.normal, N0)
    assert tilt_std_deg(f.covariance) == pytest.approx(3.0 / math.sqrt(2))


def test_keyframe_plane_adds_the_distance_process_noise():
    # carried variance s^2 + q^2 = 0.0025 + 0.0009 against the prior's 0.0025:
    # 1 / (1/0.0034 + 1/0.0025) = 0.00144; the mean moves 0.0034 / 0.0059 of the way to d0
    plane = Plane(N0, 1.5)
    prior = mounting_prior(Plane(N0, 1.4), 0.05, 3.0)
    f = keyframe_plane(propagated_plane(plane, prior.covariance, np.eye(4), np.zeros((6, 6))),
                       prior=prior,
                       distance_change=0.03)
    assert f.covariance[0, 0] == pytest.approx(1.0 / (1.0 / 0.0034 + 1.0 / 0.0025))
    assert f.plane.distance == pytest.approx(1.5 - 0.1 * 0.0034 / 0.0059)


def test_keyframe_plane_adds_the_tilt_process_noise():
    # a carried plane known to 0.1 deg, 2 deg of pitch away from the prior (3 deg): without
    # process noise it barely moves; with 1 deg of it the carried tilt variance is
    # 0.1^2 + 1^2 = 1.01 deg^2 against the prior's 9, so the tilt moves 1.01 / 10.01 of the
    # way (gnomonic chart: tan of the angles) and the variance is 1 / (1/1.01 + 1/9) deg^2
    prior = mounting_prior(Plane(N0, 1.5), 1e3, 3.0)
    plane = tilted(Plane(N0, 1.5), math.radians(2.0))
    cov = np.diag([1e-6, math.radians(0.1) ** 2, math.radians(0.1) ** 2])
    carried = propagated_plane(plane, cov, np.eye(4), np.zeros((6, 6)))
    stiff = keyframe_plane(carried, prior=prior)
    loose = keyframe_plane(carried, prior=prior, tilt_change=math.radians(1.0))

    def pitch_deg(p: Plane) -> float:
        return math.degrees(math.atan(to_chart(Plane(N0, 1.5), p)[1]))

    assert pitch_deg(stiff.plane) == pytest.approx(2.0 - 2.0 * 0.01 / 9.01, abs=2e-3)
    assert pitch_deg(loose.plane) == pytest.approx(2.0 - 2.0 * 1.01 / 10.01, abs=2e-2)
    assert tilt_std_deg(loose.covariance) == pytest.approx(
        math.sqrt(1.0 / (1.0 / 1.01 + 1.0 / 9.0)), rel=1e-2)


def test_a_widened_measurement_keeps_its_mean_and_weighs_its_std_times_the_factor():
    # the measurement of the test above (tilt 1 = 0.01 rad, variance 1e-4, nothing on d), its
    # std 3x: variance 9e-4, so against the prior's 1e-4 the gain is 1e-4 / 1e-3 = 0.1 -> 0.001
    ref = Plane(N0, 1.5)
    a = PlaneBelief.from_covariance(ref, np.diag([4e-4, 1e-4, 1e-4]))
    info = np.zeros((3, 3))
    info[1, 1] = 1e4
    b = PlaneBelief(ref, info, np.array([0.0, 1e4 * 0.01, 0.0]))
    w = widened(b, 3.0)
    assert np.allclose(w.information, b.information / 9.0)
    assert np.linalg.solve(w.information[1:2, 1:2], w.eta[1:2]) == pytest.approx([0.01], rel=1e-12)
    assert to_chart(ref, fuse([a, w]).plane)[1] == pytest.approx(0.001, abs=1e-7)
    assert to_chart(ref, fuse([a, b]).plane)[1] == pytest.approx(0.005, abs=5e-7)
    assert widened(b, 1.0) is b


def test_transported_keeps_a_missing_distance_missing():
    plane = Plane(N0, 1.5)
    info = np.zeros((3, 3))
    info[1:, 1:] = np.diag([1e4, 4e4])
    b = PlaneBelief(plane, info, np.array([0.0, 1.0, 2.0]))
    T = make_pose(so3_exp(np.array([0.02, -0.01, 0.3])), np.array([0.1, 0.0, 0.4]))
    m = transported(b, T)
    assert np.allclose(m.information[0], 0.0) and np.allclose(m.information[:, 0], 0.0)
    assert np.allclose(np.linalg.eigvalsh(m.information[1:, 1:]), [1e4, 4e4])
    # its mean moves with the plane: the chart coordinates of the mean, turned
    mean_a = from_chart(plane, np.r_[0.0, np.linalg.solve(info[1:, 1:], b.eta[1:])])
    mean_b = from_chart(m.plane, np.r_[0.0, np.linalg.solve(m.information[1:, 1:], m.eta[1:])])
    assert np.allclose(mean_a.in_frame(T).normal, mean_b.normal, atol=1e-7)


def test_default_sigmas():
    assert default_sigmas(Plane(N0, 1.5), None, None) == pytest.approx((0.05, 3.0))
    assert default_sigmas(Plane(N0, 30.0), None, 1.0) == pytest.approx((1.0, 1.0))
    assert default_sigmas(Plane(N0, 1.5), 0.02, None) == pytest.approx((0.02, 3.0))


def test_bobbing_drive_from_a_crest_ends_without_the_crests_scale():
    """Flat ground, the body bobbing (height +-3 cm, pitch +-1.5 deg, roll +-1 deg), frame 0 at
    a crest of all three: init.yaml's plane (the mounting's) is 2.6 % off the true ground at
    frame 0. The keyframes' mounting priors average the bobbing out: the scale of the last
    third is within 0.6 % of the truth (the mean of ~7 keyframes' departures, ~0.3 %, plus
    noise), where frame 0's plane alone, or a plane pulled toward frame 0's, keeps most of
    the 2.6 % (measured: 1.3 % with the former 10 % pull, 0.1 % with the prior). The terrain
    map puts keyframe 0, anchored on init.yaml's plane, on the plane the chain found, and the
    trajectory re-scaled in hindsight ends closer than the motions as streamed."""
    mount = camera_mount(40.0)
    n_frames = 90

    def pose(k):
        h = 0.03 * math.cos(2 * math.pi * k / 23.0)
        pitch = -math.radians(1.5) * math.cos(2 * math.pi * k / 37.0)  # (raises the camera)
        roll = math.radians(1.0) * math.cos(2 * math.pi * k / 29.0)
        return make_pose(so3_exp(np.array([roll, pitch, 0.0])), np.array([0.05 * k, 0.0, h])) @ mount

    poses = [pose(k) for k in range(n_frames)]
    cam = default_camera(128, 128)
    rng = np.random.default_rng(0)
    renderer = GroundRenderer(cam, GroundTexture(procedural_texture(512, 0), 1.125 / cam.fx),
                              supersample=2)
    frames = ((k, float(k), finish_frame(renderer.render(g), rng, 10.0).astype(np.float32))
              for k, g in enumerate(poses))
    n0, d0 = ground_in_camera(mount)
    assert d0 / ground_in_camera(poses[0])[1] == pytest.approx(0.974, abs=1e-3)  # the crest
    tmap = TerrainMap(Plane(n0, d0))
    first = {}  # keyframe 0's points (all kept: fewer than POINTS_PER_KEYFRAME at 128x128)
    recorder = RunRecorder()

    def on_keyframe(key):
        recorder.add_keyframe(key)
        tmap.add(key)
        if key.index == 0:
            first["n"] = len(key.levels[0].points)

    res = list(estimate_frames(frames, cam, Plane(n0, d0), tuple(ground_region(cam, mount)),
                               mounting=Mounting.nominal(Plane(n0, d0)), on_keyframe=on_keyframe))
    assert all(r.status.value != "lost" for r in res)
    # the terrain products: every keyframe's points on the ground (height 0 in the true world
    # frame); frame 0's keyframe, anchored on init.yaml's plane, is put on the plane the
    # chain of keyframes found in hindsight (terrain_map's smoothing)
    drives = {True: smoothed_keyframes(tmap.keyframes), False: None}
    heights = {s: (tmap.points(d)[0] @ poses[0][:3, :3].T + poses[0][:3, 3])[:, 2]
               for s, d in drives.items()}
    rms = {s: float(np.sqrt(np.mean(h ** 2))) for s, h in heights.items()}
    rms0 = {s: float(np.sqrt(np.mean(h[:first["n"]] ** 2))) for s, h in heights.items()}
    # (measured: keyframe 0 2.4 cm -> 1.65 cm, all points 1.05 -> 0.71 cm; with 0.5 deg of
    # tilt process noise, the default before issue 24.5, 2.4 -> 0.97 cm and 1.08 -> 0.56 cm)
    assert rms0[False] > 0.02 and rms0[True] < 0.75 * rms0[False]
    assert rms[True] < 0.008 and rms[True] < 0.75 * rms[False]
    est = np.array([np.linalg.norm(r.prev_from_cur[:3, 3]) for r in res[1:]])
    true = np.array([np.linalg.norm((se3_inv(a) @ b)[:3, 3]) for a, b in zip(poses, poses[1:])])
    last = slice(2 * n_frames // 3, None)
    assert abs(est[last].sum() / true[last].sum() - 1.0) < 0.006
    truth = se3_inv(poses[0]) @ poses[-1]
    final = np.linalg.norm(res[-1].world_from_cam[:3, 3] - truth[:3, 3])
    assert final / true.sum() < 0.012
    # the trajectory written at the end: keyframe 0's segment re-scaled in hindsight
    smoothed = smoothed_poses([r.index for r in res], np.array([r.world_from_cam for r in res]),
                              [(k.index, k) for k in recorder.keyframes])
    final_h = np.linalg.norm(smoothed[-1][:3, 3] - truth[:3, 3])
    assert final_h / true.sum() < 0.002 and final_h < 0.5 * final  # (measured 0.35 -> 0.12 %)


INIT = {"camera": {"width": 64, "height": 48, "fx": 60.0, "fy": 60.0, "cx": 31.5, "cy": 23.5},
        "ground": {"height": 1.5, "pitch_deg": 45.0}}


def test_init_yaml_sigmas_reach_the_tracker(tmp_path):
    """By default frame 0's plane is exact and the sigmas are the bobbing's width around a
    latent mean mount; with ``ground.nominal: true`` frame 0's plane is known to that width
    and the prior is centred on it."""
    p = tmp_path / "init.yaml"
    p.write_text(yaml.safe_dump(INIT))
    cfg = load_init(p)
    assert cfg.sigma_distance is None and cfg.sigma_deg is None and not cfg.nominal
    odo = Odometry(cfg.camera, cfg.plane, cfg.region, mounting=cfg.mounting)
    assert np.all(np.sqrt(np.diag(odo._plane.covariance)) < 1e-5)  # frame 0's plane: exact
    assert odo._plane.sigmas == pytest.approx((0.05, 3.0))  # the defaults: d / 30 and 3 deg
    assert odo._plane.latent_mount
    # the prior: frame 0's plane with the latent mean's uncertainty and the bobbing's
    assert np.allclose(np.sqrt(np.diag(odo._plane.mounting.covariance)),
                       np.sqrt(2) * np.array([0.05, math.radians(3), math.radians(3)]))
    p.write_text(yaml.safe_dump({**INIT, "ground": {**INIT["ground"], "sigma_distance": 0.02,
                                                    "sigma_deg": 1.5, "nominal": True}}))
    cfg = load_init(p)
    assert (cfg.sigma_distance, cfg.sigma_deg, cfg.nominal) == (0.02, 1.5, True)
    odo = Odometry(cfg.camera, cfg.plane, cfg.region, mounting=cfg.mounting)
    assert np.allclose(np.sqrt(np.diag(odo._plane.covariance)), [0.02, math.radians(1.5), math.radians(1.5)])
    assert not odo._plane.latent_mount
    assert np.allclose(np.sqrt(np.diag(odo._plane.mounting.covariance)),
                       [0.02, math.radians(1.5), math.radians(1.5)])


@pytest.mark.parametrize("key, value, words", [
    ("sigma_distance", 0.0, "ground.sigma_distance must be > 0"),
    ("sigma_distance", -1, "ground.sigma_distance must be > 0"),
    ("sigma_distance", "far", "ground.sigma_distance"),
    ("sigma_deg", 0, "ground.sigma_deg must be > 0"),
    ("sigma_deg", 90.0, "ground.sigma_deg must be at most 45"),
])
def test_init_yaml_bad_sigmas_are_one_line_errors(tmp_path, key, value, words):
    p = tmp_path / "init.yaml"
    p.write_text(yaml.safe_dump({**INIT, "ground": {**INIT["ground"], key: value}}))
    with pytest.raises(ConfigError) as e:
        load_init(p)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_a_keyframe_tilt_the_mount_cannot_reconcile_reports_the_departure():
    """The mount (3 deg of bobbing) against keyframe planes tilted from it, each known to 1 deg:
    5 deg is within both covariances (chi-square 2.5, nothing added); 25 deg is not
    (chi-square 50), and the difference (the chart's tan 25 deg) joins the tilt block whole,
    along its direction."""
    mount = mounting_prior(Plane.from_height_pitch(1.5, 50.0), 0.05, 3.0)
    P = np.diag([0.02 ** 2, math.radians(1.0) ** 2, math.radians(1.0) ** 2])
    near = Plane.from_height_pitch(1.5, 55.0)
    assert with_mount_departure(P, measured_tilt(mount, near)) is P
    far = Plane.from_height_pitch(1.5, 75.0)
    delta, _ = measured_tilt(mount, far)
    assert np.linalg.norm(delta) == pytest.approx(math.tan(math.radians(25.0)), rel=1e-6)
    widened = with_mount_departure(P, measured_tilt(mount, far))
    np.testing.assert_allclose(widened[1:, 1:] - P[1:, 1:], np.outer(delta, delta), atol=1e-12)
    assert widened[0, 0] == P[0, 0]
    assert with_mount_departure(P, None) is P
