"""The files of one synthetic sequence besides its frames (:mod:`monovo_cli.synth.write`
renders those): init.yaml, the ground truth, synth.yaml and photometric.csv; and the PNG and
folder writers, which turn an OS failure into a one-line OutputError."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

from monovo_cli.errors import OutputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.config import dump_init
from monovo_cli.io.formats import FrameStatus, MotionRow, fmt, motion_csv_text, tum_text
from monovo_cli.synth.render import ground_in_camera

INIT_POSES = {  # init_pose -> the note that heads init.yaml
    "frame0": "# The ground below is frame 0's: the wheels' plane seen from the camera, its bob\n"
              "# included (the terrain differs from it; see terrain.npz).\n",
    "nominal": "# The ground below is the nominal mount: the wheels' plane seen from the camera's\n"
               "# mounting, not frame 0's (bobbing and terrain differ; see terrain.npz).\n"}


def write_sequence(seq_dir: Path, cam: PinholeCamera, poses: list[np.ndarray],
                    region: list[int], params: dict,
                    photometric: list[tuple[float, float]] | None,
                    plane_pose: np.ndarray | None = None, nominal: bool = False) -> None:
    """init.yaml, ground truth, synth.yaml (+ photometric.csv) of one sequence; frames are
    written by the caller as they are rendered. init.yaml's plane is ``z_G = 0`` seen from
    ``plane_pose`` (default: ``poses[0]``), declared the nominal mount if ``nominal``."""
    inv0 = se3_inv(poses[0])
    traj = [np.eye(4)] + [inv0 @ g for g in poses[1:]]
    rows = [MotionRow(frame=k, prev_from_cur=se3_inv(poses[k - 1]) @ poses[k], msd=0.0,
                      iterations=0, points=0, status=FrameStatus.OK) for k in range(1, len(poses))]
    n, d = ground_in_camera(poses[0] if plane_pose is None else plane_pose)
    dump_init(seq_dir / "init.yaml", cam, Plane(n + 0.0, d), tuple(region),  # (+ 0.0: no -0.0)
              nominal=nominal)
    atomic_write_text(seq_dir / "groundtruth.tum", tum_text([float(k) for k in range(len(poses))],
                                                            traj))
    atomic_write_text(seq_dir / "groundtruth_motion.csv", motion_csv_text(rows))
    atomic_write_text(seq_dir / "synth.yaml",
                      yaml.safe_dump(params, default_flow_style=None, sort_keys=False))
    if photometric is not None:
        lines = ["frame,gain,bias"] + [f"{k},{fmt(g)},{fmt(b)}"
                                       for k, (g, b) in enumerate(photometric)]
        atomic_write_text(seq_dir / "photometric.csv", "\n".join(lines) + "\n")


def write_png(path: Path, img: np.ndarray) -> None:
    try:
        ok = cv2.imwrite(str(path), img)
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"{path}: cannot write PNG")


def make_dir(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create directory ({exc.strerror or exc})") from None
