"""Shared helpers of the benchmark scripts: machine description, error measures."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

from monovo_cli.geometry import se3_inv, so3_log


def machine() -> str:
    """One line: CPU, cores, Python, numpy, OpenCV, date."""
    import cv2

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
    except OSError:
        commit = "?"
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}, OpenCV {cv2.__version__}, monovo {commit}, "
            f"{datetime.date.today().isoformat()}")


def motion_errors(est: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-axis errors (6,) of one relative motion: translation (m) and rotation vector (deg).

    Both are ``prev_from_cur`` 4x4 poses; rotation errors are differences of rotation vectors,
    as the paper's Tables 10.1/10.2 compare parameters axis by axis.
    """
    dt = est[:3, 3] - gt[:3, 3]
    dr = np.degrees(so3_log(est[:3, :3]) - so3_log(gt[:3, :3]))
    return np.concatenate([dt, dr])


def final_drift(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray) -> tuple[float, float, float]:
    """(final position error m, path length m, final heading error deg) of two trajectories (N,4,4)."""
    err = float(np.linalg.norm(est_world_from_cam[-1][:3, 3] - gt_world_from_cam[-1][:3, 3]))
    steps = np.diff(gt_world_from_cam[:, :3, 3], axis=0)
    dist = float(np.linalg.norm(steps, axis=1).sum())
    dR = se3_inv(gt_world_from_cam[-1]) @ est_world_from_cam[-1]
    return err, dist, float(np.degrees(np.linalg.norm(so3_log(dR[:3, :3]))))
