"""The terrain grid model (issue 14), measured: why the plane fails, and one keyframe pair in detail.

    python -m benchmarks.terrain_grid                          # both sections (~6 min)
    python -m benchmarks.terrain_grid --sections pair
    python -m benchmarks.terrain_grid --sections oracle --frames 300

Uses the drives of ``benchmarks.terrain`` (``monovo synth --preset drive --terrain KIND``,
512x512, noise variance 10, seed 0), rendered into ``--renders`` (reused when present).

* **oracle** -- the rolling drive tracked three times with the plane only (``--plane-only``):
  as it is; with every keyframe's points moved to their *true* depths (ray cast into
  terrain.npz's height field from the keyframe's true pose); with them on the true
  best-fit plane of those depths. If the heading error survives the true plane but not the
  true depths, it is the plane's model error, not its estimate. Then with default options
  (the terrain grid).
* **pair** -- keyframe 100 and frame 112 of each drive (about 0.5 m apart), the keyframe
  plane the best-fit plane of the true depths of its points: the pose error of the planar
  estimate and of ``refine_pose_and_terrain_grid`` (translation mm, rotation deg against the true
  relative pose), the height error of the points (RMS against the true surface, cm), the
  terrain_grid's chi-square over its heights and whether it is used; and the same with the
  keyframe plane pitched by +-1 deg (its distance kept), the case that decided the gauge.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import monovo_cli.core.odometry as odometry
import monovo_cli.core.plane.tracker as plane_tracker
from benchmarks.common import final_drift, machine, one_core
from monovo_cli.core.estimator.estimate import KeyLevel, estimate_motion
from monovo_cli.core.estimator.terrain_grid import plane_axes, refine_pose_and_terrain_grid
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.geometry.lie import se3_inv, so3_exp, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.pyramid import build_pyramid
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.terrain import TERRAINS, load_terrain
from monovo_cli.synth.write import synthesize

SIZE = (512, 512)
NOISE_VAR = 10.0


def drive(renders: Path, kind: str, frames: int) -> Path:
    """The ``kind`` drive of ``frames`` frames (seed 0), rendered once into ``renders``."""
    seq = renders / f"{kind}_{frames}_0"
    if not (seq / "groundtruth.tum").exists():
        synthesize(seq, preset="drive", terrain=kind, frames=frames, size=SIZE,
                   noise_var=NOISE_VAR, seed=0)
    return seq


def true_points(seq: Path, k: int, X: np.ndarray) -> np.ndarray:
    """Points ``X`` (N, 3) of frame ``k``'s camera moved along their rays onto the true
    surface (Newton on the ray parameter against terrain.npz's height field)."""
    terrain = load_terrain(seq / "terrain.npz")
    g = np.load(seq / "terrain.npz")["g_from_cam"][k]
    rays = X / X[:, 2:3]
    D = rays @ g[:3, :3].T
    s = X[:, 2].copy()
    for _ in range(30):
        P = g[:3, 3] + s[:, None] * D
        f = P[:, 2] - terrain.height(P[:, 0], P[:, 1])
        P2 = g[:3, 3] + (s + 1e-4)[:, None] * D
        f2 = P2[:, 2] - terrain.height(P2[:, 0], P2[:, 1])
        s = s - f / ((f2 - f) / 1e-4)
    return rays * s[:, None]


def best_fit_plane(X: np.ndarray) -> Plane:
    m = np.linalg.lstsq(X, np.ones(len(X)), rcond=None)[0]
    return Plane(m / np.linalg.norm(m), 1.0 / np.linalg.norm(m))


def pose_error(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(mm, deg) between two cur_from_key poses."""
    return (1000 * float(np.linalg.norm(T[:3, 3] - truth[:3, 3])),
            float(np.degrees(np.linalg.norm(so3_log(T[:3, :3].T @ truth[:3, :3])))))


# --------------------------------------------------------------------------- oracle


def tracked(seq: Path, frames: int, options: TrackOptions, points: str | None) -> str:
    """One run of ``odometry.estimate_frames``; ``points`` 'depth' / 'plane' swaps every keyframe's
    points for the oracle's (module docstring). One table row."""
    build = odometry.build_keyframe

    def oracle(index, image, camera, plane, region, world_from_key, opts, **kw):
        key = build(index, image, camera, plane, region, world_from_key, opts, **kw)
        levels = []
        for kl in key.levels:
            X = true_points(seq, index, kl.points.X)
            if points == "plane":
                X = best_fit_plane(X).intersect(X / X[:, 2:3])
            levels.append(KeyLevel.from_points(replace(kl.points, X=X)))
        return replace(key, levels=tuple(levels))

    cfg = load_init(seq / "init.yaml")
    fs = open_frames(seq / "frames")
    images = [fs.read(k) for k in range(min(len(fs), frames))]
    if points:
        odometry.build_keyframe = plane_tracker.build_keyframe = oracle
    try:
        t0 = time.perf_counter()
        res = list(odometry.estimate_frames(((f.index, f.timestamp, f.image) for f in images), cfg.camera,
                                  cfg.plane, cfg.region, options))
        seconds = time.perf_counter() - t0
    finally:
        odometry.build_keyframe = plane_tracker.build_keyframe = build
    _, gt = read_tum(seq / "groundtruth.tum")
    err, path, heading = final_drift(np.array([r.world_from_cam for r in res]), gt[:len(res)])
    return (f"{100 * err / path:.3f} | {heading:.3f} | "
            f"{sum(r.status.value == 'lost' for r in res)} | {len(res) / seconds:.1f}")


def oracle_section(renders: Path, frames: int) -> None:
    seq = drive(renders, "rolling", frames)
    print(f"### Why the plane fails: the rolling drive ({frames} frames), keyframe points swapped\n")
    print("| keyframe points | final error (% of distance) | heading error (deg) | lost | "
          "frames/s (one core, in memory) |\n| --- | --- | --- | --- | --- |")
    plane_only = TrackOptions(terrain_grid=False)
    for label, opts, points in (("on the tracker's plane (`--plane-only`)", plane_only, None),
                                ("on the true best-fit plane of their ground", plane_only, "plane"),
                                ("at their true depths", plane_only, "depth"),
                                ("on the terrain grid (default options)", TrackOptions(), None)):
        print(f"| {label} | {tracked(seq, frames, opts, points)} |", flush=True)
    print()


# --------------------------------------------------------------------------- pair


def pair_section(renders: Path, frames: int, k: int = 100, j: int = 112) -> None:
    print(f"### One keyframe pair: frame {k} -> {j}, keyframe plane fitted to the true ground "
          "(pitched: turned about its right axis, distance kept)\n")
    print("| terrain | keyframe plane | planar pose error (mm / deg) | terrain grid pose error (mm / deg) "
          "| point heights RMS, plane / terrain grid (cm) | chi-square / heights | terrain grid used | ms |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    opts = EstimatorOptions()
    for kind in TERRAINS:
        seq = drive(renders, kind, frames)
        cfg = load_init(seq / "init.yaml")
        fs = open_frames(seq / "frames")
        g = np.load(seq / "terrain.npz")["g_from_cam"]
        img_k, img_j = fs.read(k).image, fs.read(j).image
        key0 = build_keyframe(k, img_k, cfg.camera, cfg.plane, cfg.region, np.eye(4), TrackOptions())
        plane = best_fit_plane(true_points(seq, k, key0.levels[0].points.X))
        truth = se3_inv(g[j]) @ g[k]
        for pitch in (0.0, 1.0, -1.0):
            pl = Plane(so3_exp(plane_axes(plane)[0] * np.radians(pitch)) @ plane.normal,
                       plane.distance)
            key = build_keyframe(k, img_k, cfg.camera, pl, cfg.region, np.eye(4), TrackOptions())
            pts = key.levels[0].points
            Xt = true_points(seq, k, pts.X)
            pyr = build_pyramid(img_j, len(key.levels))
            est = estimate_motion(key.levels, pyr, truth, options=opts)
            t0 = time.perf_counter()
            new, terrain_grid, lifted = refine_pose_and_terrain_grid(key.levels[0], pl, pyr[0], est, opts)
            ms = 1000 * (time.perf_counter() - t0)
            X = pts.X if lifted is None else lifted.points.X
            heights = [100 * float(np.sqrt(np.mean(((Y - Xt) @ plane.normal) ** 2)))
                       for Y in (pts.X, X)]
            print(f"| {kind} | {'fitted' if pitch == 0 else f'pitched {pitch:+g} deg'} | "
                  "{:.2f} / {:.4f} | {:.2f} / {:.4f} | ".format(*pose_error(est.cur_from_key, truth),
                                                              *pose_error(new.cur_from_key, truth))
                  + f"{heights[0]:.2f} / {heights[1]:.2f} | {terrain_grid.chi2:.0f} / "
                  f"{terrain_grid.h.size} | "
                  f"{'yes' if lifted is not None else 'no'} | {ms:.0f} |", flush=True)
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sections", nargs="+", default=["pair", "oracle"], choices=["pair", "oracle"])
    ap.add_argument("--frames", type=int, default=300, help="frames of the drives")
    ap.add_argument("--renders", type=Path, default=Path("/tmp/monovo-terrain grid-renders"),
                    help="where the drives are rendered and reused [default: %(default)s]")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}\n")
    if "pair" in args.sections:
        pair_section(args.renders, args.frames)
    if "oracle" in args.sections:
        oracle_section(args.renders, args.frames)


if __name__ == "__main__":
    main()
