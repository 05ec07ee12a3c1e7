"""Shared helpers of the benchmark scripts: machine description, error tables, scenes.

The error measures and the cameras are the package's (monovo_cli.evaluation.metrics,
monovo_cli.geometry.trajectory, monovo_cli.synth): the benchmarks measure with what
``monovo eval`` and ``monovo synth`` use, not with copies of them.
"""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from monovo_cli.evaluation import metrics
from monovo_cli.evaluation.metrics import relative_motion_errors
from monovo_cli.geometry.lie import make_pose, se3_inv, so3_exp, so3_log
from monovo_cli.geometry.trajectory import path_length
from monovo_cli.io.formats import STD_COLUMNS
from monovo_cli.synth.motion import DRIVE_MAST_HEIGHT, MER_PITCH_DEG, camera_mount
from monovo_cli.synth.rover import mer_camera


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
        dirty = subprocess.run(["git", "status", "--porcelain", "--", ":/monovo_cli"],
                               capture_output=True, text=True, cwd=Path(__file__).parent).stdout
        if dirty.strip():
            commit += " (+ uncommitted changes in monovo_cli/)"
    except OSError:
        commit = "?"
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}, OpenCV {cv2.__version__}, monovo {commit}, "
            f"{datetime.date.today().isoformat()}")


def motion_errors(est: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-axis errors (6,) of one relative motion: translation (m) and rotation vector (deg).

    Both are ``prev_from_cur`` 4x4 poses; the errors are ``monovo eval``'s
    (:func:`~monovo_cli.evaluation.metrics.relative_motion_errors` of the two-pose paths
    ``[I, est]`` and ``[I, gt]``): differences of rotation vectors, as the paper's
    Tables 10.1/10.2 compare parameters axis by axis.
    """
    start = np.eye(4)
    return relative_motion_errors(np.stack([start, est]), np.stack([start, gt]))[0]


def final_drift(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray) -> tuple[float, float, float]:
    """(final position error m, path length m, final heading error deg) of two trajectories (N,4,4)."""
    err = float(np.linalg.norm(est_world_from_cam[-1][:3, 3] - gt_world_from_cam[-1][:3, 3]))
    dist = path_length(gt_world_from_cam)
    dR = se3_inv(gt_world_from_cam[-1]) @ est_world_from_cam[-1]
    return err, dist, float(np.degrees(np.linalg.norm(so3_log(dR[:3, :3]))))


def keyframe_tilt_errors(run, seq: Path) -> dict[int, float]:
    """Each keyframe's tilt error (deg) of ``run`` (a :class:`~monovo_cli.core.run.TrackRun`)
    against the true ground of the synthetic sequence ``seq`` (``terrain.npz``'s
    ``g_from_cam``): the angle between the keyframe plane's normal and the ground's in that
    camera, by keyframe index."""
    g_from_cam = np.load(seq / "terrain.npz")["g_from_cam"]
    errors = {}
    for key in run.keyframes:
        true_normal = -g_from_cam[key.index][:3, :3].T @ np.array([0.0, 0.0, 1.0])
        cos = min(1.0, abs(float(key.plane.normal @ true_normal)))
        errors[key.index] = float(np.degrees(np.arccos(cos)))
    return errors


def std_columns(path: Path) -> np.ndarray:
    """The std_tx..std_rz columns of a motion.csv (N, 6) (m, deg); NaN where empty (lost)."""
    import csv

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r[c]) if r[c] else np.nan for c in STD_COLUMNS] for r in rows])


#: ``monovo eval``'s axes with their units: tx (m) .. rz (deg).
AXES = tuple(f"{a} ({'m' if i < 3 else 'deg'})" for i, a in enumerate(metrics.AXES))


def axis_table(rows: list[tuple[str, np.ndarray]], *, digits: int = 5) -> str:
    """Markdown table: one row of per-axis values (6,) per label, plus the translation and
    rotation averages (units of ``AXES``)."""
    lines = ["| | " + " | ".join(AXES) + " | transl. avg (m) | rot. avg (deg) |",
             "|" + " --- |" * (len(AXES) + 3)]
    for label, v in rows:
        v = np.asarray(v, dtype=float)
        cells = [f"{x:.{digits}f}" for x in v] + [f"{v[:3].mean():.{digits}f}",
                                                   f"{v[3:].mean():.{digits}f}"]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


class Stopwatch:
    """Accumulates wall-clock and CPU seconds of this process over ``with`` blocks.

    On a shared machine the wall time grows with other processes' load while the CPU time
    (one thread: numpy, OpenCV and BLAS are limited to one) stays close to the unloaded
    wall time, so the scripts print both.
    """

    def __init__(self) -> None:
        self.wall = 0.0
        self.cpu = 0.0

    def __enter__(self) -> Stopwatch:
        self._w, self._c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc) -> None:
        self.wall += time.perf_counter() - self._w
        self.cpu += time.process_time() - self._c


def load() -> str:
    """The 1-minute load average and the core count, e.g. 'load 1.2 on 2 cores'."""
    return f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"


def child_env(pythonpath: Path) -> dict[str, str]:
    """The environment of a timed child process: ``pythonpath`` on its path, BLAS, OpenMP and
    OpenCV on one thread (OpenCV's pool as ``--threads 1`` sets it since d1e8526, so a commit
    from before runs on one core too: its idle pool worker otherwise spins on a second), and
    the modules' bytecode written as ``pip install`` leaves a package
    (PYTHONDONTWRITEBYTECODE dropped: with it every run compiles every module again, which
    doubles monovo's own import time)."""
    env = {**os.environ, "PYTHONPATH": str(pythonpath), "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENCV_FOR_THREADS_NUM": "1"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def one_core() -> None:
    """OpenCV on one thread (BLAS/OpenMP are limited in ``benchmarks/__init__.py``)."""
    import cv2

    cv2.setNumThreads(1)


# --------------------------------------------------------------------------- synthetic pairs


@dataclass(frozen=True)
class PairScene:
    """One pair written by ``synthesize(preset="pairs")`` with the poses it was rendered from.

    ``g_from_cam0`` / ``g_from_cam1`` (4x4) map camera points to the ground frame G, whose
    plane ``z_G = 0`` is the ground; ``region`` is init.yaml's ``[x0, y0, x1, y1]``.
    """

    directory: Path
    g_from_cam0: np.ndarray
    g_from_cam1: np.ndarray
    region: tuple[int, int, int, int]

    @property
    def prev_from_cur(self) -> np.ndarray:
        """Ground-truth ``T_0_1``."""
        return se3_inv(self.g_from_cam0) @ self.g_from_cam1


def pair_scenes(pairs_dir: Path):
    """``(camera, texture, [PairScene, ...])`` of a folder written by ``synthesize(preset="pairs")``.

    ``synthesize`` records each pair's motion and plane but not its ground-frame pose (the
    azimuth and texture origin), which the Cramér–Rao bound needs to re-render the pair. The
    texture is rebuilt from synth.yaml (the procedural one, ``gravel``, or the image file it
    names, which must still exist); the poses are regenerated by replaying synthesize's seeded
    draws (the motion stream, first of the seed's spawned streams; one texture origin then
    ``pair_poses`` per pair), and every replayed pair is checked against the folder's
    ``groundtruth_motion.csv`` and ``init.yaml``: if ``monovo_cli.synth`` changes how it
    draws, this raises instead of returning wrong poses.
    """
    import yaml

    from monovo_cli.io.config import load_init
    from monovo_cli.io.formats import read_motion_csv
    from monovo_cli.synth.gravel import gravel_texture
    from monovo_cli.synth.motion import pair_poses
    from monovo_cli.synth.render import default_camera, ground_in_camera
    from monovo_cli.synth.texture import (
        GroundTexture,
        load_texture,
        procedural_texture,
        procedural_texture_size,
    )

    pairs_dir = Path(pairs_dir)
    params = yaml.safe_load((pairs_dir / "synth.yaml").read_text())
    if (params.get("preset") != "pairs" or params.get("exposure") or params.get("low_texture")
            or params.get("shadow")):
        raise ValueError(f"{pairs_dir}: expected pairs without exposure change, shadow or low texture")
    width, height = params["size"]
    cam = default_camera(width, height)
    texture, n_tex = params.get("texture"), procedural_texture_size(width, height)
    if texture in (None, "procedural"):
        image = procedural_texture(n_tex, params["seed"])
    elif texture == "gravel":
        image = gravel_texture(n_tex, params["seed"], metres_per_texel=params["metres_per_texel"])
    else:
        image = load_texture(Path(texture))
    tex = GroundTexture(image, params["metres_per_texel"])
    if list(tex.shape[::-1]) != list(params["texture_texels"]):
        raise RuntimeError(f"{pairs_dir}: replayed texture is {tex.shape[::-1]}, synth wrote "
                           f"{params['texture_texels']}; benchmarks.common.pair_scenes needs updating")
    motion_rng = np.random.default_rng(np.random.SeedSequence(params["seed"]).spawn(3)[0])
    period = np.array(tex.shape[::-1], dtype=float) * params["metres_per_texel"]
    scenes = []
    for i in range(params["frames"]):
        origin = tuple(motion_rng.uniform(0.0, 1.0, 2) * period)
        g0, g1 = pair_poses(cam, motion_rng, max_translation=float(params["max_translation"]),
                            max_rotation_deg=float(params["max_rotation_deg"]), origin=origin)
        d = pairs_dir / f"pair_{i:04d}"
        _, gt, _ = read_motion_csv(d / "groundtruth_motion.csv")
        cfg = load_init(d / "init.yaml")
        n, dist = ground_in_camera(g0)
        if (not np.allclose(se3_inv(g0) @ g1, gt[0], atol=1e-9)
                or not np.allclose(n, cfg.plane.normal, atol=1e-9)
                or abs(dist - cfg.plane.distance) > 1e-9):
            raise RuntimeError(f"{d}: replayed pose differs from the ground truth synth wrote; "
                               "benchmarks.common.pair_scenes needs updating")
        scenes.append(PairScene(d, g0, g1, tuple(int(v) for v in cfg.region)))
    return cam, tex, scenes


def pair_renderer(pairs_dir: Path, cam, tex):
    """synth's renderer of a folder written by ``synthesize(preset="pairs")``: the camera's
    optical blur (synth.yaml's ``psf``, absent when there is none) in front of the texture."""
    import yaml

    from monovo_cli.synth.render import ground_renderer

    params = yaml.safe_load((Path(pairs_dir) / "synth.yaml").read_text())
    return ground_renderer(cam, tex, psf=float(params.get("psf", 0.0)))


def drive_arguments(doc: str | None):
    """Parse the options of a one-drive benchmark: ``--frames --size --noise-var --seed``.

    Returns ``(args, (width, height))`` with OpenCV set to one thread.
    """
    import argparse

    import cv2

    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--noise-var", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    w, h = (int(v) for v in args.size.split("x"))
    return args, (w, h)


def _points(value: str) -> int:
    if value.strip().lower() == "all":
        from monovo_cli.core.options import ALL_POINTS

        return ALL_POINTS
    return int(value)


def add_points_option(ap) -> None:
    """``--max-points N|all``: monovo's observation-point cap (default: the tool's own default)."""
    from monovo_cli.core.options import TrackOptions

    per = TrackOptions().pixels_per_point
    ap.add_argument("--max-points", type=_points, default=None, metavar="N|all",
                    help="monovo's cap on observation points at full resolution [default: "
                         f"monovo's default, one per {per} pixels]; 'all': every pixel above the "
                         "gradient threshold (monovo's dense setting, `--max-points all`)")


def add_frame0_option(ap) -> None:
    """``--noisy-frame0``: noise on both frames of a pair instead of the paper's clean frame 0."""
    ap.add_argument("--noisy-frame0", action="store_true",
                    help="add the noise to frame 0 too [default: frame 0 noise-free, as in the "
                         "paper, whose ground texture is exactly known; then only frame 1 is "
                         "noisy, which is also what the Cramér–Rao bound of benchmarks.crb "
                         "assumes]")


def options_note(args) -> str:
    """How monovo was run, for the tables' headers."""
    mp = getattr(args, "max_points", None)
    if mp is None:
        return "default options"
    from monovo_cli.core.options import ALL_POINTS

    return f"default options but `--max-points {'all' if mp >= ALL_POINTS else mp}`"


def track_options(args):
    """monovo's TrackOptions for a benchmark run: the dataclass defaults, but ``--max-points``
    when it was given (the only option the benchmarks vary)."""
    from monovo_cli.core.options import TrackOptions

    max_points = getattr(args, "max_points", None)
    return TrackOptions() if max_points is None else TrackOptions(max_points=max_points)


# --------------------------------------------------------------------------- MER spacing
# The camera, pitch, mast height and steps are monovo_cli.synth's (``synth --preset mer``):
# synth.rover.mer_camera, synth.motion.MER_PITCH_DEG, DRIVE_MAST_HEIGHT, MER_STEP (a range).


def mer_pose(x: float, y: float, heading_deg: float, *, height: float = DRIVE_MAST_HEIGHT,
             pitch_deg: float = MER_PITCH_DEG) -> np.ndarray:
    """``g_from_cam`` (4x4) of the mast camera at ground position ``(x, y)`` m, looking along
    ``heading_deg`` (about the ground normal z_G, from x_G) and ``pitch_deg`` below the horizon:
    synth's camera mount (:func:`~monovo_cli.synth.motion.camera_mount`), the mast over
    ``(x, y)`` (not ahead of it) on flat ground."""
    ground = make_pose(so3_exp(np.array([0.0, 0.0, np.radians(heading_deg)])), np.array([x, y, 0.0]))
    return ground @ camera_mount(pitch_deg, height, forward=0.0)


def mer_renderer(width: int, height: int | None = None, *, texture_seed: int = 3,
                 supersample: int = 2, metres_per_texel: float = 0.004):
    """``(camera, GroundRenderer)`` of synth's MER camera (45 deg field of view; square images
    unless ``height``) over the procedural Mars texture (1024 texels, period 4.1 m at the
    default scale)."""
    from monovo_cli.synth.render import GroundRenderer
    from monovo_cli.synth.texture import GroundTexture, procedural_texture

    cam = mer_camera(width, width if height is None else height)
    tex = GroundTexture(procedural_texture(1024, texture_seed), metres_per_texel)
    return cam, GroundRenderer(cam, tex, supersample=supersample)
