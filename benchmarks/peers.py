"""The peers, in the same run, on the same frames: ORB + RANSAC homography and ECC alignment.

    python -m benchmarks.peers                          # 100 pairs + a 300-frame 512x512 drive
    python -m benchmarks.peers --pairs 20 --frames 100  # quicker
    python -m benchmarks.peers --check                  # only the noise-free validation

Two baselines a user with a known ground plane would pick instead of monovo, both built on
OpenCV and given the same plane (init.yaml's normal n and distance d in the previous frame):

* **ORB** -- ``cv2.ORB_create`` (3000 features, 3 pyramid levels), brute-force Hamming
  matching with cross-check, ``cv2.findHomography`` with RANSAC (4 px, 2000 iterations,
  then its least-squares refinement on the inliers);
* **ECC** -- ``cv2.findTransformECC`` with ``MOTION_HOMOGRAPHY`` over a ``cv2.pyrDown``
  pyramid (coarsest side >= 32 px), started from the identity at the coarsest level and
  refined level by level (50 iterations or 1e-6 correlation change per level, 5x5 Gaussian
  pre-filter); and the same stopped at OpenCV's own default, 1e-3 (``ECC_EPS_OPENCV``), what
  a user who picks ECC gets: on the drives nearly the same accuracy in a third to half the
  time.

Both give a homography ``H`` mapping frame k-1 pixels to frame k pixels. For the plane
``{X : n . X = d}`` in camera k-1 and ``X_k = R X_{k-1} + t``,
``H ~ K (R + t n^T / d) K^-1``; ``cv2.decomposeHomographyMat`` returns up to four
``(R, t/d, n)``, the one whose normal is closest to the known ``n`` is kept, ``t`` is scaled by
the known ``d``, and the motion ``T_{k-1}_k`` is the inverse of ``[R | t]``. Along a drive
each method carries the plane forward with its own motion estimates (as monovo carries its
ground model). The settings above were picked on 20 separate pairs (seed 99, noise variance
10) from ORB 3000/5000 features, 3/4/8 levels, 1-6 px RANSAC, cross-check vs ratio test, and
ECC 4-6 levels, 50/100 iterations, 3/5/7 px pre-filter, as the most accurate of each.

Measured: the pairs of ``benchmarks.paper_tables`` (688x544, noise variance 10, same seed,
so the same frames; images in memory, all three methods given both frames) and a
``monovo synth --preset drive`` sequence (512x512, noise variance 10) tracked frame to frame
and chained: monovo end to end, the whole ``pipeline.track.track_sequence`` call timed
(reading init.yaml, frame 0's decode and ground model, every frame, the smoothing in
hindsight and every file ``monovo track`` writes: motion.csv, trajectory.csv and .tum,
trajectory.png, report.html, run.yaml); the peers end to end over the same PNGs, their whole
loop timed (every decode, frame 0's included, estimate and decomposition; they write
nothing). Errors are per axis of the motions ``T_{k-1}_k`` (translation m,
rotation-vector components deg). On the pairs a few estimates diverge (metres off), and one
such pair dominates a mean, so the pairs table gives the mean absolute error over the pairs
on which no method diverged (an error above 1 m or 1 deg on some axis, or no estimate), the
number each method diverged on, and the median over all pairs. On the drive: the mean over
the frames each method estimated, its failures (a peer's: no homography or no solution, the
previous motion is repeated; monovo's: the rows of status ``lost``, which hold the motion it
predicted, and beside them its ``reinit`` rows, tracking restarted after a loss) and the
final drift of the chained trajectory. A pair monovo reports lost counts as no estimate.
Then time per pair / frame on one core (wall and this process's CPU time) and the ratios
monovo / best peer (per axis, the best of the peers on that axis) and monovo frames/s / ECC
frames/s (either stop). Every run first validates the
decomposition on exact homographies (``--check``: only that, and both peers on noise-free
pairs). ~6 min.
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import (
    AXES,
    Stopwatch,
    add_frame0_option,
    add_points_option,
    final_drift,
    load,
    machine,
    motion_errors,
    one_core,
    options_note,
    track_options,
)
from benchmarks.docs_section import writes_section
from benchmarks.paper_tables import track_pairs
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import make_pose, se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.synth.write import synthesize

ORB_FEATURES = 3000
ORB_LEVELS = 3
RANSAC_PX = 4.0
RANSAC_ITERATIONS = 2000
ECC_ITERATIONS = 50
ECC_EPS = 1e-6  # the stop of the accuracy tables: the correlation's gain per iteration
#: OpenCV's own default stop for findTransformECC: what a user who picks ECC gets; on the 512²
#: drives nearly the same accuracy as ECC_EPS's in a third to a half of the time
#: (both stops are columns of this benchmark's tables)
ECC_EPS_OPENCV = 1e-3
ECC_GAUSS = 5
ECC_MIN_SIDE = 32  # px, coarsest pyramid level
CONVERGED = 0.05  # m and deg, as in paper_tables
GROSS = 1.0  # m or deg on some axis: the estimate diverged


# --------------------------------------------------------------------------- homography -> motion


def motion_from_homography(H: np.ndarray, K: np.ndarray, plane: Plane) -> np.ndarray | None:
    """``prev_from_cur`` (4x4) from ``H`` (3x3, any scale) mapping previous-frame pixels to
    current-frame pixels, for the known ``plane`` in the previous camera; None if OpenCV finds
    no decomposition."""
    try:
        _, Rs, ts, ns = cv2.decomposeHomographyMat(np.asarray(H, dtype=np.float64), K)
    except cv2.error:
        return None
    if not len(Rs):
        return None
    best = int(np.argmax([float(np.ravel(n) @ plane.normal) for n in ns]))
    cur_from_prev = make_pose(Rs[best], np.ravel(ts[best]) * plane.distance)
    return se3_inv(cur_from_prev)


def homography_from_motion(prev_from_cur: np.ndarray, K: np.ndarray, plane: Plane) -> np.ndarray:
    """The exact ``H = K (R + t n^T / d) K^-1`` with ``[R | t] = cur_from_prev``."""
    c = se3_inv(prev_from_cur)
    return K @ (c[:3, :3] + np.outer(c[:3, 3], plane.normal) / plane.distance) @ np.linalg.inv(K)


# --------------------------------------------------------------------------- the peers


class OrbPeer:
    """ORB features, cross-checked Hamming matches, RANSAC homography."""

    name = "ORB + RANSAC homography"

    def __init__(self) -> None:
        self.orb = cv2.ORB_create(nfeatures=ORB_FEATURES, nlevels=ORB_LEVELS)
        self.matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)

    def prepare(self, image: np.ndarray):
        """Keypoint positions (N, 2) float32 and descriptors of a uint8 frame."""
        kps, desc = self.orb.detectAndCompute(image, None)
        return np.float32([k.pt for k in kps]).reshape(-1, 2), desc

    def homography(self, prev, cur) -> np.ndarray | None:
        (p0, d0), (p1, d1) = prev, cur
        if d0 is None or d1 is None or len(p0) < 4 or len(p1) < 4:
            return None
        matches = self.matcher.match(d0, d1)
        if len(matches) < 8:
            return None
        a = p0[[m.queryIdx for m in matches]]
        b = p1[[m.trainIdx for m in matches]]
        H, _ = cv2.findHomography(a, b, cv2.RANSAC, RANSAC_PX, maxIters=RANSAC_ITERATIONS,
                                  confidence=0.999)
        return H


def ecc_levels(width: int, height: int) -> int:
    n, w, h = 1, width, height
    while min(w, h) // 2 >= ECC_MIN_SIDE:
        w, h, n = w // 2, h // 2, n + 1
    return n


class EccPeer:
    """Enhanced-correlation-coefficient homography, coarse to fine from the identity."""

    name = "ECC homography (coarse to fine)"

    def __init__(self, eps: float = ECC_EPS) -> None:
        self.eps = eps  # the stop: the correlation coefficient's gain per iteration
        if eps != ECC_EPS:
            self.name = f"ECC homography (coarse to fine, stop at {eps:g})"

    def prepare(self, image: np.ndarray) -> list[np.ndarray]:
        """float32 ``cv2.pyrDown`` pyramid of a frame, finest first."""
        pyr = [image.astype(np.float32)]
        for _ in range(ecc_levels(image.shape[1], image.shape[0]) - 1):
            pyr.append(cv2.pyrDown(pyr[-1]))
        return pyr

    def homography(self, prev: list[np.ndarray], cur: list[np.ndarray]) -> np.ndarray | None:
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, ECC_ITERATIONS, self.eps)
        H = np.eye(3)
        for lv in range(len(prev) - 1, -1, -1):
            # cv2.pyrDown keeps pixel 2j of a level as pixel j of the next: x_l = x_0 / 2^l.
            S = np.diag([0.5 ** lv, 0.5 ** lv, 1.0])
            W = S @ H @ np.linalg.inv(S)
            W = (W / W[2, 2]).astype(np.float32)
            try:
                _, W = cv2.findTransformECC(prev[lv], cur[lv], W, cv2.MOTION_HOMOGRAPHY, criteria,
                                            None, ECC_GAUSS)
            except cv2.error:  # did not converge at this level: keep the coarser estimate
                if lv == 0:
                    return None
                continue
            H = np.linalg.inv(S) @ W.astype(np.float64) @ S
        return H


# --------------------------------------------------------------------------- runs


@dataclass
class MethodResult:
    name: str
    errors: np.ndarray  # (n, 6) per motion; NaN rows where the method failed
    seconds: float  # total wall time over the frames / pairs
    cpu: float  # total CPU time of this process over the same
    count: int  # frames or pairs timed
    drift: tuple[float, float, float] | None = None  # drive: final error m, distance m, heading deg
    reinit: int | None = None  # monovo: rows of status reinit (restarted after a loss); peers None

    @property
    def failed(self) -> int:
        """Motions the method gave no estimate for (monovo: its rows of status lost)."""
        return int(np.isnan(self.errors[:, 0]).sum())

    @property
    def diverged(self) -> np.ndarray:
        """(n,) bool: no estimate, or an error above ``GROSS`` on some axis."""
        e = np.abs(np.nan_to_num(self.errors, nan=np.inf))
        return e.max(axis=1) > GROSS

    @property
    def off(self) -> int:
        """Motions with an error of ``CONVERGED`` or more on some axis (failures included)."""
        e = np.abs(np.nan_to_num(self.errors, nan=np.inf))
        return int(np.count_nonzero(e.max(axis=1) >= CONVERGED))

    def mean_abs(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Per-axis mean |error| (6,) over ``rows`` (bool mask; default all with an estimate)."""
        e = self.errors if rows is None else self.errors[rows]
        return np.nanmean(np.abs(e), axis=0)

    def median_abs(self) -> np.ndarray:
        """Per-axis median |error| (6,) over all motions, a failure counting as infinite."""
        return np.median(np.abs(np.nan_to_num(self.errors, nan=np.inf)), axis=0)


def _read_pair(pair: Path):
    cfg = load_init(pair / "init.yaml")
    frames = sorted((pair / "frames").glob("*.png"))
    imgs = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in frames]
    _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
    plane = cfg.plane
    return cfg.camera.K, plane, imgs, gt[0]


def peer_on_pairs(peer, pairs: list[Path]) -> MethodResult:
    errs, watch = [], Stopwatch()
    for pair in pairs:
        K, plane, (i0, i1), gt = _read_pair(pair)
        with watch:
            H = peer.homography(peer.prepare(i0), peer.prepare(i1))
            est = motion_from_homography(H, K, plane) if H is not None else None
        errs.append(motion_errors(est, gt) if est is not None else np.full(6, np.nan))
    return MethodResult(peer.name, np.array(errs), watch.wall, watch.cpu, len(pairs))


def peer_on_drive(peer, seq: Path) -> MethodResult:
    """Frame-to-frame motions of a ``synth --preset drive`` folder, chained; decode timed."""
    cfg = load_init(seq / "init.yaml")
    K = cfg.camera.K
    plane = cfg.plane
    paths = sorted((seq / "frames").glob("*.png"))
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    _, gt_traj = read_tum(seq / "groundtruth.tum")
    poses, motions, failed = [np.eye(4)], [], []
    with Stopwatch() as watch:
        prev = peer.prepare(cv2.imread(str(paths[0]), cv2.IMREAD_GRAYSCALE))
        for path in paths[1:]:
            cur = peer.prepare(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))
            H = peer.homography(prev, cur)
            est = motion_from_homography(H, K, plane) if H is not None else None
            failed.append(est is None)
            motion = est if est is not None else (motions[-1] if motions else np.eye(4))
            motions.append(motion)
            poses.append(poses[-1] @ motion)
            plane = plane.in_frame(se3_inv(motion))  # into the current camera
            prev = cur
    errs = np.array([np.full(6, np.nan) if f else motion_errors(m, g)
                     for m, g, f in zip(motions, gt, failed)])
    return MethodResult(peer.name, errs, watch.wall, watch.cpu, len(paths),
                        final_drift(np.array(poses), gt_traj))


def monovo_errors(est: np.ndarray, gt: np.ndarray, statuses: list[str]) -> np.ndarray:
    """(n, 6) errors of monovo's motions ``est`` against ``gt``, NaN rows where the status is
    lost: such a row holds the motion monovo predicted when it gave up, not an estimate, so it
    counts as a failure (a peer's failure too leaves a NaN row)."""
    return np.array([np.full(6, np.nan) if s == FrameStatus.LOST else motion_errors(e, g)
                     for e, g, s in zip(est, gt, statuses)]).reshape(-1, 6)


def monovo_on_drive(seq: Path, out: Path, options=None, **track_kw) -> MethodResult:
    """monovo end to end on a drive (``track_kw``: more arguments of ``track_sequence``), on
    one thread unless ``track_kw`` says otherwise: the frames decoded in the frame loop, the
    thread budget of the peers it is timed against (``monovo track`` decodes ahead on a
    second thread by default). Timed: the whole ``track_sequence`` call, from reading
    init.yaml and frame 0 to the last file written (report.html unless ``report=False``)."""
    track_kw.setdefault("threads", 1)
    with Stopwatch() as watch:
        track_sequence(seq, None, out, options or TrackOptions(), **track_kw)
    _, est, status = read_motion_csv(out / "motion.csv")
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    _, traj = read_tum(out / "trajectory.tum")
    _, gt_traj = read_tum(seq / "groundtruth.tum")
    return MethodResult("monovo", monovo_errors(est, gt, status), watch.wall, watch.cpu, len(traj),
                        final_drift(traj, gt_traj), reinit=status.count(FrameStatus.REINIT))


# --------------------------------------------------------------------------- tables


def _avg_cells(v: np.ndarray, fmt: str) -> list[str]:
    return [fmt.format(x) for x in (*v, v[:3].mean(), v[3:].mean())]


def _time_cells(r: MethodResult) -> list[str]:
    return [f"{1000 * r.seconds / r.count:.1f} ({1000 * r.cpu / r.count:.1f})",
            f"{r.count / r.seconds:.1f} ({r.count / r.cpu:.1f})"]


def common_rows(results: list[MethodResult]) -> np.ndarray:
    """(n,) bool: the motions no method diverged on."""
    return ~np.any([r.diverged for r in results], axis=0)


def pairs_table(results: list[MethodResult]) -> str:
    """Mean |error| over the pairs no method diverged on, divergence counts, time; then the
    per-axis medians over all pairs."""
    rows = common_rows(results)
    head = (f"| method | {' | '.join(AXES)} | transl. avg (m) | rot. avg (deg) | diverged (> {GROSS:g} "
            f"m or deg, or no estimate) | any axis ≥ {CONVERGED:g} | ms/pair wall (CPU) | "
            "pairs/s wall (CPU) |")
    lines = [f"Mean absolute error over the {rows.sum()} of {len(rows)} pairs on which no method "
             "diverged:\n", head, "|" + " --- |" * (head.count("|") - 1)]
    for r in results:
        lines.append(f"| {r.name} | " + " | ".join(
            _avg_cells(r.mean_abs(rows), "{:.5f}") + [str(int(r.diverged.sum())), str(r.off)]
            + _time_cells(r)) + " |")
    lines += ["", f"Median absolute error over all {len(rows)} pairs (a missing estimate counts as "
              "infinite):\n", f"| method | {' | '.join(AXES)} | transl. avg (m) | rot. avg (deg) |",
              "|" + " --- |" * (len(AXES) + 3)]
    for r in results:
        lines.append(f"| {r.name} | " + " | ".join(_avg_cells(r.median_abs(), "{:.5f}")) + " |")
    return "\n".join(lines)


def _failed_cell(r: MethodResult) -> str:
    return str(r.failed) if r.reinit is None else f"{r.failed}; {r.reinit} reinit"


def drive_table(results: list[MethodResult]) -> str:
    """Mean |error| of every frame's motion, failures, final drift, time."""
    head = (f"| method | {' | '.join(AXES)} | transl. avg (m) | rot. avg (deg) | failed (monovo: "
            "lost; and its reinit) | final position error (% of distance) | final heading error "
            "(deg) | ms/frame wall (CPU) | frames/s wall (CPU) |")
    lines = [head, "|" + " --- |" * (head.count("|") - 1)]
    for r in results:
        err, dist, heading = r.drift
        lines.append(f"| {r.name} | " + " | ".join(
            _avg_cells(r.mean_abs(), "{:.2e}") + [_failed_cell(r), f"{100 * err / dist:.3f}",
                                                  f"{heading:.3f}"] + _time_cells(r)) + " |")
    return "\n".join(lines)


def _ratio_row(label: str, mono: np.ndarray, peers: list[np.ndarray], speed: str) -> str:
    best = np.min(peers, axis=0)
    best_t = min(p[:3].mean() for p in peers)
    best_r = min(p[3:].mean() for p in peers)
    cells = [f"{v:.3f}" for v in mono / best] + [f"{mono[:3].mean() / best_t:.3f}",
                                                 f"{mono[3:].mean() / best_r:.3f}", speed]
    return f"| {label} | " + " | ".join(cells) + " |"


def all_peers() -> tuple:
    """The peers every table runs: ORB, ECC at the accuracy tables' stop, and ECC at OpenCV's
    own default stop (what a user who picks ECC gets)."""
    return OrbPeer(), EccPeer(), EccPeer(ECC_EPS_OPENCV)


def ratio_table(pairs: list[MethodResult] | None, drive: list[MethodResult] | None) -> str:
    """monovo's error / the best peer's (per axis, and of the averages); monovo speed / ECC's,
    at either stop."""
    lines = ["| monovo / best peer | " + " | ".join(AXES) + " | transl. avg | rot. avg | "
             "monovo frames/s / ECC frames/s, wall (CPU); / ECC at OpenCV's default stop |",
             "|" + " --- |" * (len(AXES) + 4)]

    def speed(res: list[MethodResult]) -> str:
        mono = res[0]
        cells = []
        for name in (EccPeer.name, EccPeer(ECC_EPS_OPENCV).name):
            ecc = next(p for p in res if p.name == name)
            wall = (mono.count / mono.seconds) / (ecc.count / ecc.seconds)
            cpu = (mono.count / mono.cpu) / (ecc.count / ecc.cpu)
            cells.append(f"{wall:.2f} ({cpu:.2f})")
        return "; ".join(cells)

    if pairs is not None:
        rows = common_rows(pairs)
        lines.append(_ratio_row(f"pairs, mean over the {rows.sum()} common", pairs[0].mean_abs(rows),
                                [p.mean_abs(rows) for p in pairs[1:]], speed(pairs)))
        lines.append(_ratio_row("pairs, median over all", pairs[0].median_abs(),
                                [p.median_abs() for p in pairs[1:]], speed(pairs)))
    if drive is not None:
        lines.append(_ratio_row("drive, mean over all frames", drive[0].mean_abs(),
                                [p.mean_abs() for p in drive[1:]], speed(drive)))
    return "\n".join(lines)


# --------------------------------------------------------------------------- validation


def check(n_pairs: int = 10) -> None:
    """Decomposition of exact homographies (must be exact), then both peers on noise-free pairs."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "pairs"
        synthesize(root, preset="pairs", frames=n_pairs, noise_var=0.0, seed=99)
        pairs = sorted(p for p in root.iterdir() if p.name.startswith("pair_"))
        worst = 0.0
        for pair in pairs:
            K, plane, _, gt = _read_pair(pair)
            H = 3.7 * homography_from_motion(gt, K, plane)  # any scale
            worst = max(worst, float(np.abs(motion_errors(motion_from_homography(H, K, plane), gt)).max()))
        print(f"Exact homographies of {n_pairs} noise-free pairs, decomposed: largest error "
              f"{worst:.1e} (m / deg)\n")
        if worst > 1e-9:
            raise SystemExit("decomposition check failed: conventions are wrong")
        res = [peer_on_pairs(p, pairs) for p in (OrbPeer(), EccPeer())]
        print(f"Both peers on the same {n_pairs} pairs without noise (seed 99):\n")
        print(pairs_table(res) + "\n")


@writes_section("peers", "Accuracy against the peers, ORB and ECC", "benchmarks.peers")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_points_option(ap)
    add_frame0_option(ap)
    ap.add_argument("--pairs", type=int, default=100, help="pairs (0: skip)")
    ap.add_argument("--pair-noise-var", type=float, default=10.0)
    ap.add_argument("--pair-seed", type=int, default=1, help="same default as paper_tables")
    ap.add_argument("--frames", type=int, default=300, help="drive frames (0: skip)")
    ap.add_argument("--size", default="512x512", help="drive frame size WxH")
    ap.add_argument("--drive-noise-var", type=float, default=10.0)
    ap.add_argument("--drive-seed", type=int, default=0, help="same default as benchmarks.drive")
    ap.add_argument("--check", action="store_true", help="only validate the peers on noise-free pairs")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    one_core()
    cv2.setRNGSeed(0)  # RANSAC draws
    print(f"Machine: {machine()}; {load()} at the start\n")
    print(f"monovo: {options_note(args)}.\n")
    check()
    if args.check:
        return
    pair_res = drive_res = None
    with tempfile.TemporaryDirectory() as tmp:
        if args.pairs:
            root = Path(tmp) / "pairs"
            synthesize(root, preset="pairs", frames=args.pairs, noise_var=args.pair_noise_var,
                       seed=args.pair_seed, clean_frame0=not args.noisy_frame0)
            errs, frame1, secs, cpu = track_pairs(root, track_options(args))
            pairs = sorted(p for p in root.iterdir() if p.name.startswith("pair_"))
            errs[np.array([r.status == FrameStatus.LOST for r in frame1], bool)] = np.nan  # predicted
            pair_res = [MethodResult("monovo", errs, float(secs.sum()), float(cpu.sum()), len(pairs))]
            pair_res += [peer_on_pairs(p, pairs) for p in all_peers()]
            print(f"### {args.pairs} pairs of the paper protocol (688x544, noise variance "
                  f"{args.pair_noise_var:g} on "
                  f"{'both frames' if args.noisy_frame0 else 'frame 1 (frame 0 noise-free)'}, "
                  f"seed {args.pair_seed}), mean absolute error\n")
            print("Time per pair: both frames in memory, each method processes both (monovo: "
                  "frame-0 model + estimate; ORB: features of both + match + RANSAC; ECC: "
                  "pyramids + alignment), plus the decomposition. One core.\n")
            print(pairs_table(pair_res) + "\n")
        if args.frames:
            w, h = (int(v) for v in args.size.split("x"))
            seq = Path(tmp) / "drive"
            synthesize(seq, preset="drive", frames=args.frames, size=(w, h),
                       noise_var=args.drive_noise_var, seed=args.drive_seed)
            drive_res = [monovo_on_drive(seq, Path(tmp) / "out", track_options(args))]
            drive_res += [peer_on_drive(p, seq) for p in all_peers()]
            print(f"### {args.frames}-frame drive ({args.size}, noise variance "
                  f"{args.drive_noise_var:g}, seed {args.drive_seed}), frame to frame, mean "
                  "absolute error of T_{k-1}_k\n")
            print("Time per frame end to end, one core: monovo the whole `track_sequence` call "
                  "(init.yaml, frame 0's decode and ground model, every frame, the smoothing in "
                  "hindsight, and its files: motion.csv, trajectory.csv and .tum, "
                  "trajectory.png, report.html, run.yaml); the peers their whole loop over the "
                  "PNGs (decode, estimate, decomposition; no file written).\n")
            print(drive_table(drive_res) + "\n")
    print("### Ratios\n")
    print(ratio_table(pair_res, drive_res))
    print(f"\n({load()} at the end. Wall times count other processes' load on a shared "
          "machine; CPU times are this process's own, one thread.)")


if __name__ == "__main__":
    main()
