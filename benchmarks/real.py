"""Real data (issue 13): the feature hypothesis and `monovo track` on real cameras.

    python -m benchmarks.real                       # the real-data sections (~3 min)
    python -m benchmarks.real --sections features   # one or more of: features cost track
                                                    # choices mer pairs speed
    python -m benchmarks.real --sections mer pairs  # issue 13's synthetic acceptance (~15 min)

Reads the sequences of ``../shared/real`` (relative to the repo; ``--real DIR`` elsewhere),
whose README describes them: ``desk_b`` (hand-held, looking down at a desk, 752x480 with a
strong barrel lens) and ``kitti_ramp`` (KITTI, ~1 m per frame on a highway ramp). When the
folder is absent the script says so and skips those sections; tests never read it.

Sections (each prints one markdown table; a later one can be added to ``SECTIONS``; ``mer``,
``pairs`` and ``speed``, issue 13's synthetic acceptance runs, are described in
:mod:`benchmarks.real_synth` and need no real data):

* ``features`` -- the feature hypothesis (:mod:`monovo_cli.core.recovery.features`) on every
  consecutive frame pair, given the ground-truth plane in the earlier frame (init.yaml's
  plane carried with the ground-truth poses) and init.yaml's region, as the tracker gives
  it a keyframe. Per setting: the share of pairs with a hypothesis, the median and 90th
  percentile of its translation error (mm) and rotation error (deg, angle of
  ``R_est R_gt^T``), of the image error (px: the largest displacement error of the
  region's four corners, lifted onto the plane, between the hypothesis and the truth --
  what the direct estimator would have to close), the share within 2 px and 8 px, the
  mean ms per call (both frames' features detected) and per call with the keyframe's
  features already detected (what a tracker pays per frame). The ORB + RANSAC peer of
  ``benchmarks.peers`` (whole image, ``decomposeHomographyMat``, closest normal) is given on
  the same pairs for comparison.
* ``cost`` -- ms per call at 256², 512², 1024² on a rendered MER-spacing pair (0.75 m
  forward, camera 1.5 m up, pitched 45°, 45° field of view), full and cheap settings.
* ``track`` -- ``monovo track`` end to end (``pipeline.track.track_sequence``, default
  options): final position error as % of the ground-truth path length (both trajectories
  from their first camera), final heading error, frames lost and the longest run of lost
  frames, frames/s; then the tracker's reasons for the lost frames among the first 50.

One core (OpenCV, BLAS), fixed seeds.
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from benchmarks import real_synth
from benchmarks.common import Stopwatch, final_drift, load, machine, one_core
from monovo_cli.core.options import FeatureOptions, TrackOptions
from monovo_cli.core.recovery.features import (
    CUR_DEPRESSION_DEG,
    Features,
    detect_features,
    feature_motion,
    ground_mask,
    motion_from_features,
)
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum

REAL = Path(__file__).resolve().parents[2] / "shared" / "real"
SEQUENCES = ("desk_b", "kitti_ramp")


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class RealSequence:
    """One sequence of ``shared/real``: frames, camera, init.yaml's plane and region, and
    the ground truth ``gt_world_from_cam`` (N, 4, 4) rebased on the first camera."""

    name: str
    directory: Path
    frames: list[Path]
    camera: PinholeCamera
    plane0: Plane
    region: tuple[int, int, int, int]
    gt_world_from_cam: np.ndarray

    def plane_in(self, k: int) -> Plane:
        """The ground plane in camera k (init.yaml's plane carried with the ground truth)."""
        return self.plane0.in_frame(se3_inv(self.gt_world_from_cam[k]))

    def image(self, k: int) -> np.ndarray:
        return cv2.imread(str(self.frames[k]), cv2.IMREAD_GRAYSCALE)

    def pairs(self, step: int = 1) -> Iterator[tuple[np.ndarray, np.ndarray, Plane, np.ndarray]]:
        """The frame pairs (k - step, k): both images, the plane in camera k - step and the
        ground-truth ``T_k_{k-step}`` (4x4)."""
        for k in range(step, len(self.frames), step):
            yield (self.image(k - step), self.image(k), self.plane_in(k - step),
                   se3_inv(self.gt_world_from_cam[k]) @ self.gt_world_from_cam[k - step])


def load_sequence(directory: Path) -> RealSequence:
    cfg = load_init(directory / "init.yaml")
    frames = sorted(p for p in (directory / "frames").iterdir() if p.suffix in (".png", ".jpg"))
    _, gt = read_tum(directory / "groundtruth.tum")
    if len(gt) != len(frames):
        raise SystemExit(f"{directory}: {len(frames)} frames but {len(gt)} ground-truth poses")
    gt = np.array([se3_inv(gt[0]) @ g for g in gt])
    return RealSequence(directory.name, directory, frames, cfg.camera, cfg.plane,
                        tuple(cfg.region), gt)


def real_sequences(root: Path) -> list[RealSequence] | None:
    """The sequences of ``root``, or None (with a line saying so) when it is absent."""
    if not all((root / name / "init.yaml").is_file() for name in SEQUENCES):
        print(f"Real data not found at {root} (expected {', '.join(SEQUENCES)}): real-data "
              "sections skipped.\n")
        return None
    return [load_sequence(root / name) for name in SEQUENCES]


# --------------------------------------------------------------------------- measures


def pose_errors(est: np.ndarray, gt: np.ndarray) -> tuple[float, float]:
    """(translation error m, rotation error deg) of two ``cur_from_prev`` 4x4 poses."""
    E = est @ se3_inv(gt)
    dt = float(np.linalg.norm(est[:3, 3] - gt[:3, 3]))
    return dt, float(np.degrees(np.linalg.norm(so3_log(E[:3, :3]))))


def reprojection_rms_px(cur_from_key: np.ndarray, fm, camera: PinholeCamera, plane: Plane) -> float:
    """RMS (px) of the hypothesis's inliers reprojected with ``cur_from_key`` over ``plane``:
    how well a pose and plane explain the matches (undistorted full-resolution pixels)."""
    X = plane.intersect(fm.key_rays)
    X_cur = X @ cur_from_key[:3, :3].T + cur_from_key[:3, 3]
    f = np.array([camera.fx, camera.fy])
    d = (X_cur[:, :2] / X_cur[:, 2:3] - fm.cur_rays[:, :2]) * f
    return float(np.sqrt(np.nanmean(np.sum(d * d, axis=1))))


def corner_error_px(est: np.ndarray, gt: np.ndarray, camera: PinholeCamera, plane: Plane,
                    region: tuple[int, int, int, int]) -> float:
    """Largest image displacement error (px) of the region's corners lifted onto ``plane``."""
    x0, y0, x1, y1 = region
    uv = np.array([[x0, y0], [x1 - 1, y0], [x1 - 1, y1 - 1], [x0, y1 - 1]], dtype=float)
    X = plane.intersect(camera.rays(uv))
    X = X[np.all(np.isfinite(X), axis=1)]
    if not len(X):
        return float("nan")
    a = X @ est[:3, :3].T + est[:3, 3]
    b = X @ gt[:3, :3].T + gt[:3, 3]
    ok = (a[:, 2] > 0) & (b[:, 2] > 0)
    if not ok.all():
        return float("inf")
    return float(np.max(np.linalg.norm(camera.project(a) - camera.project(b), axis=1)))


@dataclass
class PairStats:
    """Per-pair results of one hypothesis on one sequence (NaN where it gave none)."""

    label: str
    dt: np.ndarray  # m
    dr: np.ndarray  # deg
    px: np.ndarray  # px
    ms: float  # per call, both frames detected
    ms_cached: float  # per call, keyframe features given (NaN: not applicable)
    rms: np.ndarray | None = None  # (n, 2) px: the inliers' RMS under the hypothesis, the truth

    def row(self) -> list[str]:
        ok = np.isfinite(self.dt)
        n = len(ok)

        def q(v: np.ndarray, p: float, scale: float = 1.0, fmt: str = "{:.2f}") -> str:
            v = np.nan_to_num(v, nan=np.inf)  # a missing hypothesis counts as infinitely wrong
            x = float(np.percentile(v, p, method="inverted_cdf")) * scale  # nearest rank
            return fmt.format(x) if np.isfinite(x) else "—"

        px = np.nan_to_num(self.px, nan=np.inf)
        return [self.label, f"{ok.sum()}/{n} ({100 * ok.mean():.0f} %)",
                f"{q(self.dt, 50, 1000, '{:.1f}')} / {q(self.dt, 90, 1000, '{:.1f}')}",
                f"{q(self.dr, 50, 1, '{:.3f}')} / {q(self.dr, 90, 1, '{:.3f}')}",
                f"{q(self.px, 50)} / {q(self.px, 90)}",
                f"{100 * np.mean(px <= 2):.0f} %", f"{100 * np.mean(px <= 8):.0f} %",
                f"{self.ms:.1f}", "—" if not np.isfinite(self.ms_cached) else f"{self.ms_cached:.1f}",
                "—" if self.rms is None else "{:.2f} / {:.2f}".format(*np.nanmedian(self.rms, axis=0))]


PAIR_HEAD = ("| sequence, setting | hypothesis | translation error median / p90 (mm) | rotation "
             "error median / p90 (deg) | corner error median / p90 (px) | ≤ 2 px | ≤ 8 px | "
             "ms/call | ms/call, keyframe cached | inliers' RMS under the hypothesis / the truth, "
             "median (px) |")


def feature_pairs(seq: RealSequence, label: str, options: FeatureOptions, *,
                  region: bool = True, step: int = 1, detect=detect_features) -> PairStats:
    """The feature hypothesis on the pairs (k - step, k) of ``seq``: what ``feature_motion``
    does (masks, both frames' features, matching, pose), timed in full and without the
    keyframe's features (a tracker detects those once per keyframe). ``detect`` replaces
    :func:`detect_features` (same signature) to measure another detector."""
    dt, dr, px, rms = [], [], [], []
    full, cached = Stopwatch(), Stopwatch()
    level = options.level_for(seq.camera)
    roi = seq.region if region else None
    for a, b, plane, gt in seq.pairs(step):
        with full:
            key = detect(a, seq.camera, options=options,
                         mask=ground_mask(seq.camera, plane, level=level, region=roi,
                                          min_depression_deg=options.min_depression_deg))
            with cached:
                cur = detect(b, seq.camera, options=options,
                             mask=ground_mask(seq.camera, plane, level=level,
                                              min_depression_deg=CUR_DEPRESSION_DEG))
                fm = motion_from_features(key, cur, seq.camera, plane, options=options)
        if fm is None:
            dt.append(np.nan), dr.append(np.nan), px.append(np.nan), rms.append((np.nan, np.nan))
            continue
        e = pose_errors(fm.cur_from_key, gt)
        dt.append(e[0]), dr.append(e[1])
        px.append(corner_error_px(fm.cur_from_key, gt, seq.camera, plane, seq.region))
        rms.append((fm.rms_px, reprojection_rms_px(gt, fm, seq.camera, plane)))
    n = len(dt)
    return PairStats(f"{seq.name}, {label}", np.array(dt), np.array(dr), np.array(px),
                     1000 * full.cpu / n, 1000 * cached.cpu / n, np.array(rms))


def sift_features(image: np.ndarray, camera: PinholeCamera, *, mask: np.ndarray | None = None,
                  options: FeatureOptions) -> Features:
    """SIFT in place of ORB (same level, cap and mask): the detector comparison."""
    level = options.level_for(camera)
    img = np.asarray(image, dtype=np.uint8)
    for _ in range(level):
        img = cv2.pyrDown(img)
    kps, desc = cv2.SIFT_create(nfeatures=options.features).detectAndCompute(img, mask)
    if desc is None or not kps:
        return Features(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 128), np.float32))
    uv = np.array([k.pt for k in kps], dtype=float) * 2.0 ** level
    return Features(uv, camera.rays(uv), desc)


def peer_pairs(seq: RealSequence, step: int = 1) -> PairStats:
    """``benchmarks.peers``' ORB + RANSAC homography, decomposed (closest normal), whole image."""
    from benchmarks.peers import OrbPeer, motion_from_homography

    peer, watch = OrbPeer(), Stopwatch()
    K = seq.camera.K
    dt, dr, px = [], [], []
    for a, b, plane, gt in seq.pairs(step):
        with watch:
            cv2.setRNGSeed(0)
            H = peer.homography(peer.prepare(a), peer.prepare(b))
            prev_from_cur = motion_from_homography(H, K, plane) if H is not None else None
        if prev_from_cur is None:
            dt.append(np.nan), dr.append(np.nan), px.append(np.nan)
            continue
        est = se3_inv(prev_from_cur)
        e = pose_errors(est, gt)
        dt.append(e[0]), dr.append(e[1])
        px.append(corner_error_px(est, gt, seq.camera, plane, seq.region))
    return PairStats(f"{seq.name}, peers.OrbPeer (whole image, no lens model, decomposition)",
                     np.array(dt), np.array(dr), np.array(px), 1000 * watch.cpu / len(dt), np.nan)


def table(head: str, rows: list[list[str]]) -> str:
    return "\n".join([head, "|" + " --- |" * (head.count("|") - 1)]
                     + ["| " + " | ".join(r) + " |" for r in rows])


# --------------------------------------------------------------------------- sections


TRACKING = TrackOptions().features  # the tracker's setting ("cheap" in this script's tables)
SETTINGS = (("default", FeatureOptions()),
            (f"cheap (shorter side ≥ {TRACKING.detect_side} px, {TRACKING.features} features)",
             TRACKING))


def section_features(seqs: list[RealSequence] | None, args) -> None:
    if seqs is None:
        return
    print("### The feature hypothesis on consecutive real pairs\n")
    print("Ground-truth plane of the earlier frame, init.yaml's region for its features (the "
          "current frame's below the plane's horizon); ms are CPU time, one core. A missing "
          "hypothesis counts as infinitely wrong in the percentiles (nearest rank).\n")
    rows = []
    for seq in seqs:
        for label, opt in SETTINGS:
            rows.append(feature_pairs(seq, label, opt).row())
        rows.append(feature_pairs(seq, "default, whole ground (no region)", FeatureOptions(),
                                  region=False).row())
        rows.append(peer_pairs(seq).row())
    print(table(PAIR_HEAD, rows) + "\n")


CHOICES = (
    ("default: ORB 2000, FAST 10, ratio 0.8, RANSAC 3 px, LM", FeatureOptions(), detect_features),
    ("cross-check instead of the ratio test", FeatureOptions(ratio=0.0), detect_features),
    ("1000 features", FeatureOptions(features=1000), detect_features),
    ("FAST threshold 20", FeatureOptions(fast_threshold=20), detect_features),
    ("FAST threshold 5", FeatureOptions(fast_threshold=5), detect_features),
    ("RANSAC 2 px", FeatureOptions(ransac_px=2.0), detect_features),
    ("no LM refinement (the homography's pose)", FeatureOptions(refine=False), detect_features),
    ("SIFT 2000 instead of ORB", FeatureOptions(), sift_features),
    ("level 1, 1000 features", FeatureOptions(level=1, features=1000), detect_features),
)


def section_choices(seqs: list[RealSequence] | None, args) -> None:
    """The settings behind the defaults: desk_b 5 frames apart (larger motions), kitti_ramp
    consecutive and 2 frames apart."""
    if seqs is None:
        return
    print("### Why these settings: variants of the feature hypothesis\n")
    print("desk_b every 5th frame against the one 5 before (67 pairs), kitti_ramp consecutive "
          "(50) and 2 apart (25 pairs, ~2 m).\n")
    by_name = {s.name: s for s in seqs}
    rows = []
    for name, step in (("desk_b", 5), ("kitti_ramp", 1), ("kitti_ramp", 2)):
        for label, opt, detect in CHOICES:
            rows.append(feature_pairs(by_name[name], f"step {step}, {label}", opt, step=step,
                                      detect=detect).row())
    print(table(PAIR_HEAD, rows) + "\n")


def section_cost(seqs, args) -> None:
    from benchmarks.common import mer_pose, mer_renderer
    from monovo_cli.synth.motion import MER_STEP
    from monovo_cli.synth.render import ground_in_camera

    step = MER_STEP[1]  # synth's longest MER step, 0.75 m

    print("### Cost per call on a rendered MER-spacing pair (0.75 m forward)\n")
    print("ms per call, CPU time of one core, mean of 10 calls; 'cached': the keyframe's "
          "features already detected.\n")
    head = ("| size | setting | detection level | inliers / matches | ms/call | ms/call, keyframe "
            "cached |")
    rows = []
    for size in (256, 512, 1024):
        cam, renderer = mer_renderer(size)
        g0, g1 = mer_pose(1.0, 1.0, 30.0), mer_pose(1.0 + step * np.cos(np.radians(30.0)),
                                                    1.0 + step * np.sin(np.radians(30.0)), 30.0)
        rng = np.random.default_rng(0)
        a, b = (np.clip(np.rint(renderer.render(g) + rng.normal(0.0, np.sqrt(10.0), (size, size))),
                        0, 255).astype(np.uint8) for g in (g0, g1))
        plane = Plane(*ground_in_camera(g0))
        for label, opt in SETTINGS:
            full, cached = Stopwatch(), Stopwatch()
            level = opt.level_for(cam)
            key = detect_features(a, cam, options=opt, mask=ground_mask(cam, plane, level=level))
            for _ in range(10):
                with full:
                    fm = feature_motion(a, b, cam, plane, options=opt)
                with cached:
                    cur = detect_features(b, cam, options=opt,
                                          mask=ground_mask(cam, plane, level=level,
                                                           min_depression_deg=CUR_DEPRESSION_DEG))
                    motion_from_features(key, cur, cam, plane, options=opt)
            got = "none" if fm is None else f"{fm.inliers} / {fm.matches}"
            rows.append([f"{size}²", label, str(level), got, f"{100 * full.cpu:.1f}",
                         f"{100 * cached.cpu:.1f}"])
    print(table(head, rows) + "\n")


def track_run(seq: RealSequence, out: Path) -> list[str]:
    from monovo_cli.core.odometry import TrackOptions
    from monovo_cli.pipeline.track import track_sequence

    with Stopwatch() as watch:
        track_sequence(seq.directory, None, out, TrackOptions(), overwrite=True)
    _, _, statuses = read_motion_csv(out / "motion.csv")
    _, traj = read_tum(out / "trajectory.tum")
    traj = np.array([se3_inv(traj[0]) @ t for t in traj])
    err, dist, heading = final_drift(traj, seq.gt_world_from_cam)
    lost = np.array([s == "lost" for s in statuses])
    longest = run = 0
    for x in lost:
        run = run + 1 if x else 0
        longest = max(longest, run)
    n = len(statuses) + 1
    return [seq.name, str(n), f"{dist:.3f}", f"{err:.3f}", f"{100 * err / dist:.1f}", f"{heading:.1f}",
            f"{lost.sum()} ({100 * lost.mean():.0f} %)", str(longest),
            f"{n / watch.wall:.1f} ({n / watch.cpu:.1f})"]


def section_track(seqs: list[RealSequence] | None, args) -> None:
    if seqs is None:
        return
    print("### `monovo track` end to end (default options)\n")
    head = ("| sequence | frames | path (m) | final position error (m) | % of path | final heading "
            "error (deg) | lost frames | longest lost run | frames/s wall (CPU) |")
    rows, reasons = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seq in seqs:
            rows.append(track_run(seq, Path(tmp) / seq.name))
            reasons.append(loss_reasons(seq.name, Path(tmp) / seq.name / "motion.csv"))
    print(table(head, rows) + "\n")
    print("Why frames are lost or re-initialised: the `reason` column of the same runs' motion.csv.\n")
    print(table("| sequence | lost / re-init | reasons (frames) |", reasons) + "\n")


def loss_reasons(name: str, motion_csv: Path) -> list[str]:
    """One table row: the lost and re-initialised frames of a motion.csv and their reasons."""
    import csv
    from collections import Counter

    with open(motion_csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["status"] in ("lost", "reinit")]
    reasons = Counter(r["reason"] for r in rows)
    text = "; ".join(f"{why} ({count})" for why, count in reasons.most_common()) or "—"
    lost = sum(r["status"] == "lost" for r in rows)
    return [name, f"{lost} / {len(rows) - lost}", text]


SECTIONS = {"features": section_features, "cost": section_cost, "track": section_track,
            "choices": section_choices, **real_synth.SECTIONS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", type=Path, default=REAL, help="folder of the real sequences")
    ap.add_argument("--sections", nargs="+", choices=list(SECTIONS),
                    default=["features", "cost", "track"], help="[default: features cost track]")
    real_synth.add_arguments(ap)
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    seqs = None
    if set(args.sections) - set(real_synth.SECTIONS):
        seqs = real_sequences(args.real)
    for name in args.sections:
        SECTIONS[name](seqs, args)
    print(f"({load()} at the end.)")


if __name__ == "__main__":
    main()
