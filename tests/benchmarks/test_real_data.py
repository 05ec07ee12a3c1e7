"""benchmarks.real_data's conversions on tiny synthetic inputs (never the real data)."""

from __future__ import annotations

import subprocess

import cv2
import numpy as np
import pytest

from benchmarks import real_data as rd
from monovo_cli.geometry.lie import se3_inv, so3_exp
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum


def _pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.asarray(rotvec, dtype=float))
    T[:3, 3] = t
    return T


def test_kitti_rows_are_camera_poses_in_camera_0():
    a = _pose([0.0, 0.1, 0.0], [0.2, -0.1, 1.0])
    text = "\n".join(" ".join(repr(float(v)) for v in T[:3, :].ravel()) for T in (np.eye(4), a))
    poses = rd.kitti_poses(text + "\n")
    assert len(poses) == 2
    np.testing.assert_allclose(poses[1], a, atol=1e-15)
    with pytest.raises(ValueError):
        rd.kitti_poses("1 2 3\n")


def test_rotation_vector_rows_are_world_to_camera():
    w, t = np.array([0.3, -0.2, 0.1]), np.array([0.05, -0.02, 0.4])
    (T,) = rd.rotvec_pose_rows(" ".join(repr(float(v)) for v in (*w, *t)))
    R_cv = cv2.Rodrigues(w)[0]  # the course's convention is OpenCV's Rodrigues
    np.testing.assert_allclose(T[:3, :3], R_cv, atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], t)


def test_rebase_puts_camera_0_at_the_origin():
    world = [_pose([0.1, 0.2, 0.3], [1, 2, 3]), _pose([0.1, 0.25, 0.3], [1.5, 2, 3.2])]
    traj = rd.rebase(world)
    np.testing.assert_array_equal(traj[0], np.eye(4))
    np.testing.assert_allclose(traj[1], se3_inv(world[0]) @ world[1], atol=1e-12)


def test_radial_distortion_in_pixels_becomes_opencv_normalised():
    f, k1_px, k2_px = 400.0, -1.7e-6, 2.6e-12
    k = rd.radial_px_to_opencv(k1_px, k2_px, f, f)
    # A pixel 150 px from the centre is displaced the same way in both models.
    r_px = 150.0
    r_n = r_px / f
    assert 1 + k1_px * r_px**2 + k2_px * r_px**4 == pytest.approx(1 + k[0] * r_n**2 + k[1] * r_n**4)
    assert k[2:] == (0.0, 0.0, 0.0)


def test_plane_from_world_for_a_camera_looking_down():
    # Camera 0.5 m above the world plane z = 0 (z up), looking straight down, x along x.
    T_w_c = np.eye(4)
    T_w_c[:3, :3] = np.diag([1.0, -1.0, -1.0])  # camera z (forward) = world -z
    T_w_c[:3, 3] = [0.3, -0.2, 0.5]
    plane = rd.plane_from_world(se3_inv(T_w_c), (0.0, 0.0, 1.0))
    np.testing.assert_allclose(plane.normal, [0.0, 0.0, 1.0], atol=1e-12)
    assert plane.distance == pytest.approx(0.5)
    # An offset plane: y = 0.8 seen from the same camera is 1.0 m away along camera -y.
    side = rd.plane_from_world(se3_inv(T_w_c), (0.0, 1.0, 0.0), 0.8)
    np.testing.assert_allclose(side.normal, [0.0, -1.0, 0.0], atol=1e-12)
    assert side.distance == pytest.approx(1.0)


def test_plane_from_height_is_orthogonal_to_the_travel_with_no_roll():
    # A car climbing at 2 deg: camera y down, z forward, travelling along (0, -sin, cos).
    climb = np.radians(2.0)
    d = np.array([0.0, -np.sin(climb), np.cos(climb)])
    traj = [_pose([0, 0, 0], d * s + [0.01 * s, 0, 0]) for s in np.arange(0.0, 12.0, 1.0)]
    plane = rd.plane_from_height(traj, 1.65, travel=5.0)
    assert plane.normal[0] == 0.0
    assert plane.normal[1] > 0.99
    assert float(plane.normal @ d) == pytest.approx(0.0, abs=1e-12)
    assert plane.distance == 1.65
    with pytest.raises(ValueError):
        rd.plane_from_height([np.eye(4), _pose([0, 0, 0], [1.0, 0, 0])], 1.65)


def test_region_of_points_grows_and_clips():
    px = np.array([[100.0, 200.0], [200.0, 300.0]])
    assert rd.region_of_points(px, 640, 480) == (100, 200, 200, 300)
    assert rd.region_of_points(px, 640, 480, margin=0.5) == (50, 150, 250, 350)
    assert rd.region_of_points(px, 220, 320, margin=0.5) == (50, 150, 220, 320)
    with pytest.raises(ValueError):
        rd.region_of_points(np.array([[700.0, 10.0], [800.0, 20.0]]), 640, 480)


def test_pnp_recovers_a_synthetic_pose():
    K = np.array([[420.0, 0, 376], [0, 420.0, 240], [0, 0, 1]])
    pw = np.array([[x, y, z] for x in (0, 0.1) for y in (0.08, 0.2) for z in (0, -0.1, -0.2)])
    T = _pose([0.4, -0.3, 0.1], [-0.05, -0.1, 0.5])
    pc = pw @ T[:3, :3].T + T[:3, 3]
    uv = (pc @ K.T)[:, :2] / (pc @ K.T)[:, 2:]
    (est,) = rd.pnp_poses(pw, uv[None], K)
    np.testing.assert_allclose(est, T, atol=1e-8)
    assert rd.pnp_rms(pw, uv[None], K, [est]) < 1e-6


def _tiny_repo(tmp_path):
    """A git repository holding a 3-frame KITTI-like clip in the layout of the source."""
    work = tmp_path / "work"
    base = work / "VisualOdometry" / "KITTI_sequence_2"
    (base / "image_l").mkdir(parents=True)
    rng = np.random.default_rng(0)
    for k in range(3):
        cv2.imwrite(str(base / "image_l" / f"{k:06d}.png"),
                    rng.integers(0, 255, (376, 1241), dtype=np.uint8))
    P = "718.856 0 607.1928 0 0 718.856 185.2157 0 0 0 1 0"
    (base / "calib.txt").write_text(P + "\n" + P + "\n")
    rows = []
    for k in range(3):
        T = _pose([0, 0.01 * k, 0], [0.0, -0.035 * k, 1.0 * k])
        rows.append(" ".join(repr(float(v)) for v in T[:3, :].ravel()))
    (base / "poses.txt").write_text("\n".join(rows) + "\n")
    git = ["git", "-C", str(work), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git[:3], "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "clip"], check=True)
    mirror = tmp_path / "mirror"
    (mirror / rd.NICO.replace("/", "+")).mkdir(parents=True)
    (work / ".git").rename(mirror / rd.NICO.replace("/", "+") / "repo")
    return mirror


def test_main_rebuilds_a_sequence_and_skips_absent_snapshots(tmp_path, capsys):
    mirror = _tiny_repo(tmp_path)
    out = tmp_path / "out"
    assert rd.main(["--mirror", str(mirror), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "desk_b: no snapshot" in err and "shelf_tags: no snapshot" in err
    seq = out / "kitti_ramp"
    assert sorted(p.name for p in (seq / "frames").iterdir()) == [f"{k:06d}.png" for k in range(3)]
    cam, plane, region = (lambda c: (c.camera, c.plane, c.region))(load_init(seq / "init.yaml"))
    assert (cam.width, cam.height, cam.fx) == (1241, 376, 718.856)
    assert plane.distance == 1.65
    ts, poses = read_tum(seq / "groundtruth.tum")
    assert list(ts) == [0.0, 1.0, 2.0]
    np.testing.assert_allclose(poses[2][:3, 3], [0.0, -0.07, 2.0], atol=1e-9)
    frames, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    assert list(frames) == [1, 2]
    readme = (out / "README.md").read_text()
    assert "kitti_ramp" in readme and "CC BY-NC-SA 3.0" in readme and "Skipped" in readme


def test_main_refuses_an_output_inside_the_repository(tmp_path):
    assert rd.main(["--mirror", str(tmp_path), "--out", str(rd.REPO_ROOT / "real_out")]) == 2
    assert not (rd.REPO_ROOT / "real_out").exists()
