"""Real sequences with ground truth (issue 41), rebuilt from public repositories' snapshots.

    python -m benchmarks.real_data --mirror /work/.mirror --out DIR [--only NAME ...]

Each sequence is rebuilt from a snapshot of a public repository (a bare git directory
``MIRROR/<owner>+<name>/repo``, read with ``git show``) into ``DIR/<name>/`` in the layout of
SPEC.md: ``frames/`` (the source's image files, byte for byte, renumbered from 0),
``init.yaml`` (camera and frame 0's ground plane), ``groundtruth.tum`` and
``groundtruth_motion.csv`` (the package's own writers), and ``DIR/README.md`` says where every
sequence comes from, its licence, how the plane and the ground truth were derived and what
makes it hard. A sequence whose snapshot is absent is skipped with one line saying so.

The data stays outside the repository: ``--out`` must not lie inside it.

Reserved (issue 41) and never read here: KITTI odometry sequences 00 and 06, frames 1-400 of
the desk sequence that desk_b comes from, ``KITTI_sequence_1`` of niconielsen32/ComputerVision
and the test images of luigifreda/pyslam (``KITTI_sample`` of Transportation-Inspection/
visual_odometry and FlagArihant2000/visual-odometry is KITTI 00). Every path read is named
below, so a reserved file cannot be read by accident.

The conversions (pose formats, the lens model, the plane from a camera height or from a
world plane, the region) are plain functions, tested on synthetic inputs by
tests/benchmarks/test_real_data.py.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv, so3_exp
from monovo_cli.geometry.plane import Plane
from monovo_cli.geometry.trajectory import path_length
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.config import dump_init
from monovo_cli.io.formats import FrameStatus, MotionRow, motion_csv_text, tum_text

REPO_ROOT = Path(__file__).resolve().parents[1]
KITTI_CAMERA_HEIGHT_M = 1.65  # KITTI's rig: the left grey camera 1.65 m above the road
TRAVEL_FOR_PLANE_M = 5.0  # the road's direction: the travel over the first ~5 m
DESK_B_REGION = (120, 100, 590, 365)
KITTI_RAMP_NORMAL = (0.0, 0.9993973224531703, 0.03471299286195416)
KITTI_RAMP_REGION = (420, 250, 860, 376)
SHELF_FLOOR_Y_M = 0.266


# --------------------------------------------------------------------------- conversions


def number_rows(text: str, n: int, what: str) -> list[np.ndarray]:
    """The non-blank lines of ``text`` as arrays of ``n`` floats (``what`` names them in the
    error of a line that has another count)."""
    rows = []
    for line in text.splitlines():
        if not line.strip():
            continue
        v = np.array([float(x) for x in line.split()], dtype=float)
        if v.size != n:
            raise ValueError(f"{what} has {n} numbers, not {v.size}")
        rows.append(v)
    return rows


def kitti_poses(text: str) -> list[np.ndarray]:
    """KITTI pose rows (12 floats, a 3x4 ``[R | t]`` row-major, camera k in camera 0's frame)
    as 4x4 ``T_0_k``."""
    poses = []
    for v in number_rows(text, 12, "a KITTI pose row"):
        T = np.eye(4)
        T[:3, :] = v.reshape(3, 4)
        poses.append(T)
    return poses


def kitti_camera(calib_text: str, width: int, height: int) -> PinholeCamera:
    """The left grey camera (``P0``, the first row of calib.txt; rectified, no distortion)."""
    first = calib_text.splitlines()[0].split()
    vals = [float(x) for x in (first[1:] if first[0].endswith(":") else first)]
    P = np.array(vals[:12]).reshape(3, 4)
    return PinholeCamera(width, height, P[0, 0], P[1, 1], P[0, 2], P[1, 2])


def rotvec_pose_rows(text: str) -> list[np.ndarray]:
    """The course's poses.txt rows ``wx wy wz tx ty tz`` (rotation vector rad, translation):
    the world-to-camera transform ``T_C_W``, returned as 4x4 ``T_C_W``."""
    out = []
    for v in number_rows(text, 6, "a pose row"):
        T = np.eye(4)
        T[:3, :3] = so3_exp(v[:3])
        T[:3, 3] = v[3:]
        out.append(T)
    return out


def rebase(world_from_cam: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Poses ``T_W_k`` as ``T_0_k`` (camera 0 is the world, SPEC.md); frame 0 is exact."""
    inv0 = se3_inv(world_from_cam[0])
    return [np.eye(4)] + [inv0 @ T for T in world_from_cam[1:]]


def radial_px_to_opencv(k1_px: float, k2_px: float, fx: float, fy: float) -> tuple[float, ...]:
    """Radial distortion given in pixel units (``x_d = c + (x_u - c)(1 + k1 r^2 + k2 r^4)``, r
    in pixels) as OpenCV's normalised ``(k1, k2, p1, p2, k3)``: ``k1 f^2, k2 f^4``, f the
    mean focal length."""
    f = 0.5 * (fx + fy)
    return (k1_px * f**2, k2_px * f**4, 0.0, 0.0, 0.0)


def plane_from_world(cam_from_world: np.ndarray, normal_w: Sequence[float],
                     offset_w: float = 0.0) -> Plane:
    """The world plane ``{X_W : normal_w . X_W = offset_w}`` in the camera frame of
    ``T_C_W``, its normal pointing from the camera to the plane (distance > 0)."""
    Tw = se3_inv(cam_from_world)  # T_W_C
    R, t = Tw[:3, :3], Tw[:3, 3]
    nw = np.asarray(normal_w, dtype=float)
    nw = nw / np.linalg.norm(nw)
    # X_W = R X_C + t on the plane:  (R^T nw) . X_C = offset - nw . t
    n = R.T @ nw
    d = offset_w - float(nw @ t)
    if d < 0:
        n, d = -n, -d
    if d == 0:
        raise ValueError("the camera lies on the plane")
    return Plane(n + 0.0, d)


def plane_from_height(poses: Sequence[np.ndarray], height: float,
                      travel: float = TRAVEL_FOR_PLANE_M) -> Plane:
    """Frame 0's road plane from the rig's camera ``height`` and the first metres of travel:
    the normal is orthogonal to the direction from camera 0 to the first camera at least
    ``travel`` metres away (its y-z part: roll 0, the camera's x axis parallel to the road),
    pointing down (+y, OpenCV axes). ``poses`` are ``T_0_k``."""
    pos = np.array([T[:3, 3] for T in poses])
    far = np.nonzero(np.linalg.norm(pos, axis=1) >= travel)[0]
    direction = pos[far[0]] if far.size else pos[-1]
    ty, tz = float(direction[1]), float(direction[2])
    norm = np.hypot(ty, tz)
    if norm == 0:
        raise ValueError("no travel along y-z to take the road's direction from")
    n = np.array([0.0, tz, -ty]) / norm
    if n[1] < 0:
        n = -n
    return Plane(n + 0.0, float(height))


def region_of_points(pixels: np.ndarray, width: int, height: int,
                     margin: float = 0.0) -> tuple[int, int, int, int]:
    """The image rectangle ``x0 y0 x1 y1`` around ``pixels`` (N, 2), grown by ``margin`` of
    its size on every side and clipped to the frame."""
    p = np.asarray(pixels, dtype=float).reshape(-1, 2)
    lo, hi = p.min(axis=0), p.max(axis=0)
    grow = margin * (hi - lo)
    lo, hi = lo - grow, hi + grow
    x0 = int(np.clip(np.floor(lo[0]), 0, width))
    y0 = int(np.clip(np.floor(lo[1]), 0, height))
    x1 = int(np.clip(np.ceil(hi[0]), 0, width))
    y1 = int(np.clip(np.ceil(hi[1]), 0, height))
    if x1 - x0 < 2 or y1 - y0 < 2:
        raise ValueError("the region is empty inside the frame")
    return (x0, y0, x1, y1)


def motion_rows(traj: Sequence[np.ndarray]) -> list[MotionRow]:
    """groundtruth_motion.csv rows ``T_{k-1}_k`` of the trajectory ``T_0_k``."""
    return [MotionRow(frame=k, prev_from_cur=se3_inv(traj[k - 1]) @ traj[k], msd=0.0,
                      iterations=0, points=0, status=FrameStatus.OK)
            for k in range(1, len(traj))]


# --------------------------------------------------------------------------- snapshots


class Snapshot:
    """A public repository's snapshot: a git directory read with ``git show``."""

    def __init__(self, mirror: Path, repo: str) -> None:
        self.repo = repo
        base = mirror / repo.replace("/", "+")
        self.git = next((p for p in (base / "repo" / ".git", base / "repo", base)
                         if (p / "HEAD").is_file() and (p / "objects").is_dir()), None)

    @property
    def present(self) -> bool:
        return self.git is not None

    def _git(self, *args: str) -> bytes:
        return subprocess.run(["git", f"--git-dir={self.git}", *args], check=True,
                              capture_output=True).stdout

    def commit(self) -> str:
        return self._git("rev-parse", "HEAD").decode().strip()

    def read(self, path: str) -> bytes:
        return self._git("show", f"HEAD:{path}")

    def text(self, path: str) -> str:
        return self.read(path).decode()

    def listing(self, folder: str) -> list[str]:
        out = self._git("ls-tree", "--name-only", "HEAD", folder.rstrip("/") + "/").decode()
        return sorted(line for line in out.splitlines() if line)


# --------------------------------------------------------------------------- writing


@dataclass
class Built:
    """What README.md says of a rebuilt sequence."""

    name: str
    frames: int
    size: tuple[int, int]
    path_m: float
    commit: str
    notes: str


def write_sequence(out: Path, snap: Snapshot, frame_paths: Sequence[str], cam: PinholeCamera,
                   traj: Sequence[np.ndarray], plane: Plane,
                   region: tuple[int, int, int, int]) -> tuple[int, int]:
    """Frames (bytes as they are, renumbered from 0), init.yaml and the ground truth."""
    frames = out / "frames"
    frames.mkdir(parents=True, exist_ok=True)
    for old in frames.iterdir():
        old.unlink()
    size = None
    for k, src in enumerate(frame_paths):
        data = snap.read(src)
        if size is None:
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
            size = (img.shape[1], img.shape[0])
        (frames / f"{k:06d}{Path(src).suffix.lower()}").write_bytes(data)
    if size != (cam.width, cam.height):
        raise ValueError(f"{out.name}: frames are {size}, the camera {cam.width}x{cam.height}")
    dump_init(out / "init.yaml", cam, plane, region)
    atomic_write_text(out / "groundtruth.tum", tum_text([float(k) for k in range(len(traj))],
                                                        list(traj)))
    atomic_write_text(out / "groundtruth_motion.csv", motion_csv_text(motion_rows(traj)))
    return size


# --------------------------------------------------------------------------- sequences

VAMR = "liuxiao916/Vision-Algorithms-for-Mobile-Robotics-in-ethz"
NICO = "niconielsen32/ComputerVision"


def build_desk_b(snap: Snapshot, out: Path) -> Built:
    """Frames 401-736 of the course's exercise-1 desk sequence (never 1-400, reserved)."""
    base = "Exercise 1 - Augmented Reality Wireframe Cube/data/"
    first, last = 401, 736
    names = [f"{base}images/img_{i:04d}.jpg" for i in range(first, last + 1)]
    K = np.loadtxt(snap.text(base + "K.txt").splitlines())
    D = np.loadtxt(snap.text(base + "D.txt").splitlines()).ravel()
    poses_cw = rotvec_pose_rows(snap.text(base + "poses.txt"))[first - 1:last]
    # The coefficients rounded to 6 decimals and the region as in the build the earlier
    # tuning used (shared/real/README.md), so that its figures stay comparable.
    dist = tuple(round(c, 6) for c in radial_px_to_opencv(D[0], D[1], K[0, 0], K[1, 1]))
    cam = PinholeCamera(752, 480, K[0, 0], K[1, 1], K[0, 2], K[1, 2], dist)
    traj = rebase([se3_inv(T) for T in poses_cw])
    plane = plane_from_world(poses_cw[0], (0.0, 0.0, 1.0))
    region = DESK_B_REGION  # the board in frame 0
    size = write_sequence(out, snap, names, cam, traj, plane, region)
    return Built("desk_b", len(names), size, path_length(np.array(traj)), snap.commit(),
                 f"frames img_{first:04d}-img_{last:04d}.jpg of `{base}images/`")


def build_kitti_ramp(snap: Snapshot, out: Path) -> Built:
    """KITTI_sequence_2 (51 frames) of niconielsen32/ComputerVision; never KITTI_sequence_1."""
    base = "VisualOdometry/KITTI_sequence_2/"
    names = snap.listing(base + "image_l")
    img = cv2.imdecode(np.frombuffer(snap.read(names[0]), np.uint8), cv2.IMREAD_UNCHANGED)
    cam = kitti_camera(snap.text(base + "calib.txt"), img.shape[1], img.shape[0])
    traj = rebase(kitti_poses(snap.text(base + "poses.txt")))
    if len(traj) != len(names):
        raise ValueError(f"kitti_ramp: {len(names)} frames but {len(traj)} poses")
    derived = plane_from_height(traj, KITTI_CAMERA_HEIGHT_M)
    # The plane and region of the build the earlier tuning used (shared/real/README.md), so
    # that its figures stay comparable; the rule above gives a normal within 0.3 deg of it.
    plane = Plane(np.array(KITTI_RAMP_NORMAL), KITTI_CAMERA_HEIGHT_M)
    tilt = np.degrees(np.arccos(min(1.0, float(derived.normal @ plane.normal))))
    if tilt > 0.5:
        raise ValueError(f"kitti_ramp: the derived road normal is {tilt:.2f} deg off the pinned one")
    region = KITTI_RAMP_REGION  # the road in front of the car
    size = write_sequence(out, snap, names, cam, traj, plane, region)
    return Built("kitti_ramp", len(names), size, path_length(np.array(traj)), snap.commit(),
                 f"`{base}image_l/`, `poses.txt`, `calib.txt`")


def build_shelf_tags(snap: Snapshot, out: Path) -> Built:
    """The course's exercise-2 (PnP) sequence: 210 undistorted frames of a shelf's floor and
    back wall with AprilTag sheets; the pose of every frame from the 12 given tag corners."""
    base = "Exercise 2 - PnP/data/"
    names = snap.listing(base + "images_undistorted")
    K = np.loadtxt(snap.text(base + "K.txt").splitlines())
    pw = np.loadtxt(snap.text(base + "p_W_corners.txt").splitlines(), delimiter=",") / 100.0
    uv = np.loadtxt(snap.text(base + "detected_corners.txt").splitlines()).reshape(-1, 12, 2)
    if len(uv) != len(names):
        raise ValueError(f"shelf_tags: {len(names)} frames but {len(uv)} corner rows")
    poses_cw = pnp_poses(pw, uv, K)
    cam = PinholeCamera(752, 480, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    traj = rebase([se3_inv(T) for T in poses_cw])
    # Three planes carry the tags: a side wall (z = 0), the back wall (x = 19.4 cm) and the
    # shelf's floor (y = 26.6 cm), whose normal points down in the image.
    floor = np.isclose(pw[:, 1], SHELF_FLOOR_Y_M)
    plane = plane_from_world(poses_cw[0], (0.0, 1.0, 0.0), SHELF_FLOOR_Y_M)
    region = region_of_points(uv[0][floor], cam.width, cam.height, margin=0.3)
    size = write_sequence(out, snap, names, cam, traj, plane, region)
    rms = pnp_rms(pw, uv, K, poses_cw)
    return Built("shelf_tags", len(names), size, path_length(np.array(traj)), snap.commit(),
                 f"`{base}images_undistorted/`; PnP reprojection RMS {rms:.2f} px")


def pnp_poses(points_w: np.ndarray, pixels: np.ndarray, K: np.ndarray) -> list[np.ndarray]:
    """``T_C_W`` of every frame from its pixels (F, N, 2) of ``points_w`` (N, 3) (no lens
    distortion): EPnP, refined by Levenberg-Marquardt."""
    out = []
    for uv in pixels:
        ok, rvec, tvec = cv2.solvePnP(points_w, uv, K, None, flags=cv2.SOLVEPNP_EPNP)
        if not ok:
            raise ValueError("PnP failed")
        rvec, tvec = cv2.solvePnPRefineLM(points_w, uv, K, None, rvec, tvec)
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(rvec)[0]
        T[:3, 3] = tvec.ravel()
        out.append(T)
    return out


def pnp_rms(points_w: np.ndarray, pixels: np.ndarray, K: np.ndarray,
            poses_cw: Sequence[np.ndarray]) -> float:
    err = []
    for uv, T in zip(pixels, poses_cw):
        pc = points_w @ T[:3, :3].T + T[:3, 3]
        proj = pc @ K.T
        err.append(proj[:, :2] / proj[:, 2:] - uv)
    return float(np.sqrt(np.mean(np.square(err))))


@dataclass(frozen=True)
class Source:
    name: str
    repo: str
    build: Callable[[Snapshot, Path], Built]
    licence: str
    readme: str  # camera, plane, ground truth, what makes it hard (markdown)


SOURCES: tuple[Source, ...] = (
    Source("desk_b", VAMR, build_desk_b,
           "none stated: course material (UZH/ETH, Vision Algorithms for Mobile Robotics), "
           "research and education use",
           "Hand-held camera looking down at a desk with a checkerboard (752x480 JPEG). Camera: "
           "K from `K.txt`; its radial distortion `D.txt` is in pixel units and converted to "
           "OpenCV's normalised k1 = k1_px f^2, k2 = k2_px f^4 (f the mean focal length); the "
           "frames are not undistorted. Ground truth: the course's `poses.txt` (the board's "
           "pose in the camera, PnP on the checkerboard, rotation vector + translation) for "
           "every frame; the board and the desk are the world plane z = 0, whose pose in frame "
           "0 is init.yaml's plane (exact). Region: the board in frame 0 (as in the build the "
           "earlier tuning used). Hard: real lens and sensor, strong "
           "barrel distortion, hand-held tilts of tens of degrees, mugs, a keyboard, papers and "
           "a hand on the desk, the floor below the desk's edge, reflections."),
    Source("kitti_ramp", NICO, build_kitti_ramp,
           "KITTI Vision Benchmark: CC BY-NC-SA 3.0",
           "KITTI odometry, left grey camera (1241x376 PNG, rectified): a highway on-ramp, ~1 m "
           "a frame at 10 Hz, ~98 deg of yaw. Camera: P0 of `calib.txt`, no distortion. Ground "
           "truth: KITTI's poses (GPS/INS), rebased on frame 0. Plane: the rig's specification, "
           "camera 1.65 m above the road; normal orthogonal (in the camera's y-z plane, roll 0) "
           "to the first ~8-10 m of travel (pinned to the value of the build the earlier tuning "
           "used; the script checks that its own rule, the direction to the first camera 5 m "
           "away, agrees within 0.5 deg: it gives 0.24 deg), so the scale is known to about "
           "1-2 %. Region: the road in front of the car (lower third, middle "
           "of the width). Hard: fast forward motion (tens of pixels a frame on the road), "
           "low-texture asphalt at a grazing angle, guard rails and passing cars."),
    Source("shelf_tags", VAMR, build_shelf_tags,
           "none stated: course material (UZH/ETH, Vision Algorithms for Mobile Robotics), "
           "research and education use",
           "Hand-held camera (the desk sequence's camera, 752x480 JPEG, already undistorted by "
           "the course) looking into a white shelf whose floor and back wall carry printed "
           "AprilTag sheets; 210 frames of the course's PnP exercise. Camera: K from `K.txt`, no "
           "distortion. Ground truth: PnP (EPnP, then Levenberg-Marquardt) on the 12 given tag "
           "corners of `detected_corners.txt` against `p_W_corners.txt` (cm, converted to m) "
           "for every frame. Plane: the shelf's floor, world y = 26.6 cm (the four corners "
           "on it; the other eight lie on a side wall, z = 0, and the back wall), in frame 0. "
           "Region: the floor corners' bounding box in frame 0, grown by 30 % "
           "of its size each side. Hard: a small floor (the back wall and shelf sides fill much "
           "of the image), white, textureless board around the tags, a dark background beside "
           "the shelf, motion blur; the ground truth is only as good as 12 corners' PnP."),
)


# --------------------------------------------------------------------------- main


def readme_text(built: Sequence[tuple[Source, Built]], skipped: Sequence[str]) -> str:
    lines = ["# Real sequences rebuilt by benchmarks/real_data.py", "",
             "Each sequence is rebuilt from a public repository's snapshot. Do not copy them into "
             "the product repository (licences below). Layout of SPEC.md: `frames/` (the "
             "source's files, renumbered from 0), `init.yaml`, `groundtruth.tum`, "
             "`groundtruth_motion.csv` (timestamps are frame numbers).", ""]
    for src, b in built:
        lines += [f"## {b.name} — {b.frames} frames, {b.size[0]}x{b.size[1]}, "
                  f"{b.path_m:.2f} m of path", "",
                  f"- Source: https://github.com/{src.repo} (commit {b.commit[:12]}), {b.notes}.",
                  f"- Licence: {src.licence}.",
                  f"- {src.readme}", ""]
    if skipped:
        lines += ["## Skipped", ""] + [f"- {s}" for s in skipped] + [""]
    return "\n".join(lines)


#: the split, chosen before any tuning on the new sequences (docs/benchmarks.md "real-split")
SPLIT = {"desk_b": "tuning", "kitti_ramp": "tuning", "shelf_tags": "test"}
ROADS = ("kitti_ramp",)  # a road's plane is known to a few %: integrity.py's 0.3 m for it


def track_rows(out: Path, names: Sequence[str]) -> list[str]:
    """One table row per rebuilt sequence under ``out``, tracked with default options on
    one core: its set, frames, path, final drift (% of the path), lost frames, rows more than
    5 cm (0.3 m on a road) or 1 deg off whose std does not cover them within 4x, and
    std(error / std) per axis over the ``ok`` and ``reanchored`` rows."""
    from benchmarks.integrity import ROAD_OFF_M, final_pct, untrusted
    from monovo_cli import track_frames
    from monovo_cli.core.status import FrameStatus
    from monovo_cli.geometry.lie import so3_log
    from monovo_cli.io.formats import read_motion_csv, read_tum

    rows = []
    for name in names:
        seq = out / name
        run = track_frames(seq)
        _, gt = read_tum(seq / "groundtruth.tum")
        idx, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
        truth = {int(k): m for k, m in zip(idx, motions)}
        bad, n, _ = untrusted(run, truth, ROAD_OFF_M) if name in ROADS else untrusted(run, truth)
        z = []
        for k, T, std, status in zip(run.index[1:], run.prev_from_cur[1:], run.std[1:],
                                     run.status[1:]):
            G = truth.get(int(k))
            if G is None or status not in (FrameStatus.OK, FrameStatus.REANCHORED):
                continue
            z.append(np.r_[T[:3, 3] - G[:3, 3], so3_log(T[:3, :3]) - so3_log(G[:3, :3])] / std)
        honesty = " ".join(f"{v:.2f}" for v in np.std(np.array(z), axis=0))
        rows.append(f"| {name} | {SPLIT.get(name, '?')} | {run.frames} | {path_length(gt):.2f} | "
                    f"{final_pct(run.trajectory, gt):.2f} | {run.lost} | {bad} of {n} | {honesty} |")
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mirror", type=Path, required=True,
                    help="folder of snapshots, one bare git directory per <owner>+<name>")
    ap.add_argument("--out", type=Path, required=True, help="where to write DIR/<name>/")
    ap.add_argument("--only", nargs="*", help="rebuild only these sequences")
    ap.add_argument("--track", action="store_true",
                    help="also track every sequence under --out and write the table of "
                         "docs/benchmarks.md's real-sequences section")
    args = ap.parse_args(argv)
    out = args.out.resolve()
    if out == REPO_ROOT or REPO_ROOT in out.parents:
        print(f"{out}: inside the repository; the data must stay out of it", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    built, skipped = [], []
    for src in SOURCES:
        if args.only and src.name not in args.only:
            continue
        snap = Snapshot(args.mirror, src.repo)
        if not snap.present:
            msg = f"{src.name}: no snapshot of {src.repo} under {args.mirror}; skipped"
            print(msg, file=sys.stderr)
            skipped.append(msg)
            continue
        b = src.build(snap, out / src.name)
        print(f"{b.name}: {b.frames} frames, {b.size[0]}x{b.size[1]}, {b.path_m:.2f} m",
              file=sys.stderr)
        built.append((src, b))
    atomic_write_text(out / "README.md", readme_text(built, skipped))
    if args.track:
        from benchmarks.common import machine
        from benchmarks.docs_section import write_section

        names = [n for n in SPLIT if (out / n / "groundtruth.tum").exists()]
        table = "\n".join(["| sequence | set | frames | path (m) | final drift (%) | lost | "
                           "untrusted rows | std(error / std) tx ty tz rx ry rz |",
                           "| --- | --- | --- | --- | --- | --- | --- | --- |",
                           *track_rows(out, names)])
        print(table)
        write_section("real-sequences", "The real sequences, tuning and test set",
                      f"`python -m benchmarks.real_data --mirror MIRROR --out DIR --track`: "
                      f"`monovo track` with default options, one core; untrusted rows as "
                      f"`../shared/tools/integrity.py` counts them (0.3 m on a road).\n\n"
                      f"{machine()}\n\n{table}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
