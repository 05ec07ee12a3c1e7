"""The trajectory readers of monovo eval: one drive written in every format reads back the same."""

import numpy as np
import pytest

from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import pose_from_vectors, quat_from_matrix, se3_inv, so3_log
from monovo_cli.io.formats import MotionRow, motion_csv_text, trajectory_csv_text, tum_text
from monovo_cli.io.trajectories import (
    FORMATS,
    detect_format,
    read_pose_file,
)


def _drive(n=8, seed=1):
    rng = np.random.default_rng(seed)
    poses = [np.eye(4)]
    for _ in range(n - 1):
        poses.append(poses[-1] @ pose_from_vectors(np.r_[0.0, 0.0, 0.05] + rng.normal(0, 0.01, 3),
                                                   np.radians(rng.normal(0, 2.0, 3))))
    return 0.1 * np.arange(n) + 1000.0, np.array(poses)


def _kitti(poses):
    return "".join(" ".join(repr(float(v)) for v in T[:3].ravel()) + "\n" for T in poses)


def _euroc(ts, poses):
    head = ("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
            "q_RS_y [],q_RS_z [],v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m s^-1]\n")
    rows = []
    for t, T in zip(ts, poses):
        q = quat_from_matrix(T[:3, :3])  # x y z w
        rows.append(",".join([str(round(t * 1e9)), *(repr(float(v)) for v in T[:3, 3]),
                              *(repr(float(v)) for v in (q[3], q[0], q[1], q[2])), "0", "0", "0"]))
    return head + "\n".join(rows) + "\n"


def _motion(poses, std=None):
    rows = [MotionRow(k, se3_inv(poses[k - 1]) @ poses[k], 1.0, 3, 100, "ok",
                      std=None if std is None else std[k])
            for k in range(1, len(poses))]
    return motion_csv_text(rows, with_std=std is not None)


@pytest.fixture()
def files(tmp_path):
    ts, poses = _drive()
    out = {"tum": tmp_path / "a.tum", "kitti": tmp_path / "a.kitti.txt",
           "euroc": tmp_path / "data.csv", "trajectory-csv": tmp_path / "run" / "trajectory.csv",
           "motion-csv": tmp_path / "run" / "motion.csv"}
    out["tum"].write_text(tum_text(ts, poses))
    out["kitti"].write_text(_kitti(poses))
    out["euroc"].write_text(_euroc(ts, poses))
    out["motion-csv"].parent.mkdir()
    out["trajectory-csv"].write_text(trajectory_csv_text(range(len(poses)), ts, poses))
    std = np.tile(np.r_[0.001, 0.002, 0.003, 0.01, 0.02, 0.03], (len(poses), 1))
    out["motion-csv"].write_text(_motion(poses, std))
    return ts, poses, out


def test_every_format_is_detected_and_reads_the_same_poses(files):
    ts, poses, paths = files
    assert set(paths) == set(FORMATS)
    for fmt, path in paths.items():
        assert detect_format(path) == fmt
        pf = read_pose_file(path)
        assert pf.format == fmt
        np.testing.assert_allclose(pf.world_from_cam, poses, atol=1e-9, err_msg=fmt)
        if fmt == "kitti":
            assert pf.timestamps is None
        else:  # motion.csv takes them from trajectory.csv beside it
            np.testing.assert_allclose(pf.timestamps, ts, atol=1e-6, err_msg=fmt)
        np.testing.assert_array_equal(pf.frames, np.arange(len(poses)))
    assert detect_format(paths["motion-csv"].parent) == "folder"


def test_euroc_nanoseconds_become_seconds_exactly_enough(tmp_path):
    p = tmp_path / "data.csv"
    p.write_text("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
                 "q_RS_y [],q_RS_z []\n1403636579758555392,1,2,3,1,0,0,0\n"
                 "1403636579763555584,1,2,3,0,0,0,1\n")
    pf = read_pose_file(p)
    assert pf.timestamps[0] == pytest.approx(1403636579.758555392, abs=1e-6)
    assert pf.timestamps[1] - pf.timestamps[0] == pytest.approx(0.005000192, abs=1e-6)
    np.testing.assert_allclose(pf.world_from_cam[0][:3, 3], [1, 2, 3])
    np.testing.assert_allclose(pf.world_from_cam[1][:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-12)


def test_kitti_times_file_and_the_output_folder(files, tmp_path):
    ts, poses, paths = files
    times = tmp_path / "times.txt"
    times.write_text("".join(f"{float(t)!r}\n" for t in ts))
    pf = read_pose_file(paths["kitti"], times=times)
    np.testing.assert_allclose(pf.timestamps, ts)
    run = read_pose_file(paths["motion-csv"].parent)
    assert run.format == "folder" and run.motions is not None
    np.testing.assert_array_equal(run.motions.frames, np.arange(1, len(poses)))
    np.testing.assert_allclose(run.motions.std[0],  # motion.csv's std columns: m, deg
                               np.r_[0.001, 0.002, 0.003, np.degrees([0.01, 0.02, 0.03])])
    rel = run.motions.prev_from_cur[2]
    np.testing.assert_allclose(rel, se3_inv(poses[2]) @ poses[3], atol=1e-12)
    # trajectory.tum beside trajectory.csv and motion.csv gets the reported motions too
    (paths["motion-csv"].parent / "trajectory.tum").write_text(tum_text(ts, poses))
    assert read_pose_file(paths["motion-csv"].parent / "trajectory.tum").motions is not None
    assert read_pose_file(paths["tum"]).motions is None


def test_a_format_can_be_forced(files):
    _, poses, paths = files
    with pytest.raises(InputError, match="is a trajectory CSV, not a TUM trajectory"):
        read_pose_file(paths["trajectory-csv"], "tum")
    with pytest.raises(InputError, match=r"a\.tum: line 1: expected 12 numbers"):
        read_pose_file(paths["tum"], "kitti")
    assert so3_log(read_pose_file(paths["kitti"], "kitti").world_from_cam[1][:3, :3]) \
        == pytest.approx(so3_log(poses[1][:3, :3]))


@pytest.mark.parametrize(("name", "text", "fmt", "words"), [
    ("a.txt", "1 2 3\n", None, r"a\.txt: cannot tell its format \(first data line has 3 fields"),
    ("a.txt", "", None, r"a\.txt: no poses"),
    ("k.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n", None,
     r"k\.txt: line 2: the 3x3 part is not a rotation"),
    ("k.txt", "1 0 0 0 0 1 0 0 0 0 1 x\n", "kitti", r"k\.txt: line 1: expected numbers"),
    ("e.csv", "#timestamp [ns],x\n1.5e9,0,0,0,1,0,0,0\n", None,
     r"e\.csv: line 2: expected a timestamp in whole ns, got '1\.5e9'"),
    ("e.csv", "#timestamp [ns],x\n15,0,0,0,1,0,0\n", None, r"e\.csv: line 2: expected at least 8"),
    ("m.csv", "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status\n1,0,0,0,0,0,0,1,1,1,ok\n"
     "3,0,0,0,0,0,0,1,1,1,ok\n", None, r"m\.csv: line 3: frame 3 follows frame 1"),
    ("m.csv", "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status\n", None,
     r"m\.csv: no rows"),
])
def test_bad_files_are_one_line_naming_file_and_line(tmp_path, name, text, fmt, words):
    (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=words) as err:
        read_pose_file(tmp_path / name, fmt)
    assert "\n" not in str(err.value)


def test_missing_things(tmp_path):
    with pytest.raises(InputError, match=r"none\.tum: cannot read trajectory \(No such file"):
        read_pose_file(tmp_path / "none.tum")
    with pytest.raises(InputError, match="a folder without trajectory.csv"):
        read_pose_file(tmp_path)
    (tmp_path / "k.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 3)
    (tmp_path / "t.txt").write_text("0\n1\n")
    with pytest.raises(InputError, match=r"t\.txt: holds 2 timestamps for 3 poses"):
        read_pose_file(tmp_path / "k.txt", times=tmp_path / "t.txt")
