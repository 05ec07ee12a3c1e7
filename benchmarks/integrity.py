"""Data monovo's authors did not make: the real sequences by halves, and synthetic drives whose
assumptions nothing was tuned on. Final error and row integrity.

    python -m benchmarks.integrity                 # ../shared/real by halves + 4 synthetic drives
    python -m benchmarks.integrity --no-real       # the synthetic drives only
    python -m benchmarks.integrity --no-real --only-mer --mer-seeds 14 15 16 17 18

Per drive, tracked with default options (``monovo_cli.track_frames``), one core:

* **final error** -- the end-point error of the trajectory written (smoothed in hindsight)
  against the truth, as % of the true path; for the real sequences also over each half
  (frames ``0..N/2`` and ``N/2..N-1``, each half's trajectory re-based on its first frame);
* **untrusted rows** -- rows of motion.csv (frames k >= 1, every status) more than 5 cm or
  1 deg off the true motion ``T_{k-1}_k`` whose reported std does not cover the error within
  4x on every axis (as ``../shared/tools/integrity.py`` counts them), over all rows / lost
  and re-initialised rows;
* **rows > 4 std** -- rows, whatever their error, more than 4 of their own std off on some
  axis (a std that covers its row's error misses it at most 0.1 % of the time).

The synthetic drives (rendered here, seeds never used to choose a constant):

* ``mer-gravel``: MER spacing (0.6-0.75 m steps, turns in place), the gravel texture, 512²,
  40 frames, frames 12 and 25 blanked (forced losses);
* ``crest-pose``: a flat 512² drive with the mount bobbing (the terrain drives' suspension),
  its init.yaml rewritten as frame 0's *true* plane (frame 0 off the mean mount) -- the
  convention of an independent renderer;
* ``rolling-large``: rolling ground, 512², 60 frames, every second frame dropped (steps
  twice the drive's);
* ``mer-1024``: MER spacing at 1024² (the default texture), 40 frames, frames 12 and 25
  blanked; ``--mer-seeds`` tracks it on other seeds too (``--only-mer``: nothing else);
* ``mer-1024-turn``: the same drive (seed 14) with frames 16 and 17 dropped as well, so that
  one step turns in place by 30 deg (frames 16 and 17 turn 16 and 13 deg, twice the drive's
  largest step) and drives on 0.7 m: the turn the issue asks to be beyond the capture range.

The real sequences are read from ``../shared/real`` when it exists (the script says when it
does not; tests never read it).
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from benchmarks.common import load, machine, one_core
from monovo_cli import track_frames
from monovo_cli.core.run import TrackRun
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.geometry.trajectory import path_length
from monovo_cli.io.formats import read_motion_csv, read_tum, tum_text
from monovo_cli.synth.write import synthesize

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real"
OFF_M, OFF_DEG, COVER = 0.05, 1.0, 4.0
ROAD_OFF_M = 0.3
MER_SEED = 14  # mer-1024's seed; --mer-seeds adds others
TURN_DROPPED = (16, 17)  # mer-1024-turn: seed 14's frames 16 and 17 turn 16 and 13 deg


def beyond_cover(run: TrackRun, gt_prev_from_cur: dict[int, np.ndarray]) -> int:
    """Rows of ``run`` (k >= 1) more than COVER of their own std off the truth on some axis."""
    n = 0
    for k, T, std in zip(run.index[1:], run.prev_from_cur[1:], run.std[1:]):
        G = gt_prev_from_cur.get(int(k))
        if G is None:
            continue
        e = np.r_[T[:3, 3] - G[:3, 3], so3_log(T[:3, :3]) - so3_log(G[:3, :3])]
        n += not (np.all(np.isfinite(std)) and np.all(np.abs(e) <= COVER * std))
    return n


def untrusted(run: TrackRun, gt_prev_from_cur: dict[int, np.ndarray], off_m: float = OFF_M
              ) -> tuple[int, int, int]:
    """(untrusted rows, rows compared, of them lost or re-initialised) of ``run``: rows more
    than ``off_m`` m or OFF_DEG deg off."""
    bad = bad_lost = n = 0
    for k, T, std, status in zip(run.index[1:], run.prev_from_cur[1:], run.std[1:],
                                 run.status[1:]):
        G = gt_prev_from_cur.get(int(k))
        if G is None:
            continue
        n += 1
        e = np.r_[T[:3, 3] - G[:3, 3], np.degrees(so3_log(T[:3, :3]) - so3_log(G[:3, :3]))]
        if np.linalg.norm(e[:3]) <= off_m and np.linalg.norm(e[3:]) <= OFF_DEG:
            continue
        s = np.r_[std[:3], np.degrees(std[3:])]
        if np.all(np.isfinite(s)) and np.all(np.abs(e) <= COVER * s):
            continue
        bad += 1
        bad_lost += status in (FrameStatus.LOST, FrameStatus.REINIT)
    return bad, n, bad_lost


def final_pct(est: np.ndarray, gt: np.ndarray) -> float:
    """End-point error of ``est`` (N, 4, 4) against ``gt``, both re-based on their first pose,
    as % of ``gt``'s path."""
    e, g = se3_inv(est[0]) @ est, se3_inv(gt[0]) @ gt
    return 100.0 * float(np.linalg.norm(e[-1][:3, 3] - g[-1][:3, 3])) / path_length(g)


def evaluate(seq: Path, *, halves: bool = False) -> list[str]:
    run = track_frames(seq)
    _, gt = read_tum(seq / "groundtruth.tum")
    idx, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    assert len(gt) == run.frames, (len(gt), run.frames)
    truth = {int(k): m for k, m in zip(idx, motions)}
    bad, n, bad_lost = untrusted(run, truth)
    cells = [f"{final_pct(run.trajectory, gt):.2f}"]
    if halves:
        h = run.frames // 2
        cells += [f"{final_pct(run.trajectory[:h + 1], gt[:h + 1]):.2f}",
                  f"{final_pct(run.trajectory[h:], gt[h:]):.2f}"]
    cells += [f"{run.lost} / {run.reinit}", f"{bad} of {n} ({bad_lost} lost/reinit)",
              f"{beyond_cover(run, truth)} of {n}"]
    if halves:  # a road's plane is known to a few %: integrity.py's threshold for it
        cells.append(f"{untrusted(run, truth, ROAD_OFF_M)[0]} of {n}")
    return [seq.name, str(run.frames), f"{path_length(gt):.2f}", *cells]


def crest_pose(seq: Path) -> None:
    """Rewrite ``seq``'s init.yaml as frame 0's true ground (terrain.npz's ``g_from_cam``)."""
    g_from_cam0 = np.load(seq / "terrain.npz")["g_from_cam"][0]
    R, c = g_from_cam0[:3, :3], g_from_cam0[:3, 3]
    normal = -R.T @ np.array([0.0, 0.0, 1.0])  # the ground's downward normal, camera 0
    cfg = yaml.safe_load((seq / "init.yaml").read_text())
    cfg["ground"].pop("height", None), cfg["ground"].pop("pitch_deg", None)
    cfg["ground"].pop("roll_deg", None)
    cfg["ground"]["normal"] = [float(v) for v in normal]
    cfg["ground"]["distance"] = float(c[2])
    (seq / "init.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))


def drop_every_second(seq: Path) -> None:
    """Keep the even frames of ``seq`` (and their ground truth): steps twice as long."""
    keep_frames(seq, np.arange(0, len(sorted((seq / "frames").glob("*.png"))), 2))


def keep_frames(seq: Path, keep: np.ndarray) -> None:
    """Keep only the frames ``keep`` (indices, ascending) of ``seq`` and their ground truth."""
    frames, kept = sorted((seq / "frames").glob("*.png")), set(keep.tolist())
    for k, p in enumerate(frames):
        if k not in kept:
            p.unlink()
    ts, gt = read_tum(seq / "groundtruth.tum")
    (seq / "groundtruth.tum").write_text(tum_text(ts[keep], gt[keep]))
    rel = [se3_inv(a) @ b for a, b in zip(gt[keep][:-1], gt[keep][1:])]
    lines = ["frame,tx,ty,tz,rx,ry,rz"]
    for k, T in enumerate(rel, start=1):
        r = np.degrees(so3_log(T[:3, :3]))
        lines.append(",".join([str(k), *(f"{v:.9f}" for v in (*T[:3, 3], *r))]))
    (seq / "groundtruth_motion.csv").write_text("\n".join(lines) + "\n")
    if (seq / "times.txt").exists():
        (seq / "times.txt").unlink()


def blank(seq: Path, frames: tuple[int, ...]) -> None:
    """Overwrite those frames of ``seq`` with black images of their size and depth."""
    paths = sorted((seq / "frames").glob("*.png"))
    for k in frames:
        cv2.imwrite(str(paths[k]), np.zeros_like(cv2.imread(str(paths[k]), cv2.IMREAD_UNCHANGED)))


def synthetic(root: Path, mer_seeds: tuple[int, ...] = (14,), only_mer: bool = False
              ) -> list[list[str]]:
    rows = []
    if only_mer:
        return _mer(root, mer_seeds, rows)
    mer = root / "mer-gravel"
    synthesize(mer, preset="mer", frames=40, size=(512, 512), noise_var=10.0, seed=11,
               texture="gravel")
    blank(mer, (12, 25))
    rows.append(evaluate(mer))
    crest = root / "crest-pose"
    synthesize(crest, preset="drive", terrain="flat", frames=150, size=(512, 512), noise_var=10.0,
               seed=12)
    crest_pose(crest)
    rows.append(evaluate(crest))
    large = root / "rolling-large"
    synthesize(large, preset="drive", terrain="rolling", frames=120, size=(512, 512),
               noise_var=10.0, seed=13)
    drop_every_second(large)
    rows.append(evaluate(large))
    return _mer(root, mer_seeds, rows)


def _mer(root: Path, mer_seeds: tuple[int, ...], rows: list[list[str]]) -> list[list[str]]:
    for seed in mer_seeds:
        big = root / f"mer-1024-{seed}"
        synthesize(big, preset="mer", frames=40, size=(1024, 1024), noise_var=10.0, seed=seed)
        blank(big, (12, 25))
        rows.append(evaluate(big))
        rows[-1][0] = "mer-1024" + ("" if seed == MER_SEED else f" (seed {seed})")
        shutil.rmtree(big, ignore_errors=True)
    turn = root / "mer-1024-turn"
    synthesize(turn, preset="mer", frames=40, size=(1024, 1024), noise_var=10.0, seed=MER_SEED)
    blank(turn, (12, 25))
    keep_frames(turn, np.array([k for k in range(40) if k not in TURN_DROPPED]))
    rows.append(evaluate(turn))
    shutil.rmtree(turn, ignore_errors=True)
    return rows


def table(head: str, rows: list[list[str]]) -> str:
    sep = "| " + " | ".join(["---"] * (head.count("|") - 1)) + " |"
    return "\n".join([head, sep, *("| " + " | ".join(r) + " |" for r in rows)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", type=Path, default=REAL, help="folder of the real sequences")
    ap.add_argument("--no-real", action="store_true", help="the synthetic drives only")
    ap.add_argument("--mer-seeds", type=int, nargs="+", default=[MER_SEED],
                    help=f"seeds of the mer-1024 drive (default {MER_SEED})")
    ap.add_argument("--only-mer", action="store_true", help="of the synthetic drives, mer-1024 only")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    if not args.no_real:
        names = ("desk_b", "kitti_ramp")
        if all((args.real / n / "init.yaml").is_file() for n in names):
            rows = [evaluate(args.real / n, halves=True) for n in names]
            print(table("| sequence | frames | path (m) | final error (% of path) | first half | "
                        "second half | lost / reinit | untrusted rows | rows > 4 std | untrusted at 0.3 m |",
                        rows) + "\n")
        else:
            print(f"Real data not found at {args.real}: the real sequences are skipped.\n")
    with tempfile.TemporaryDirectory() as tmp:
        rows = synthetic(Path(tmp), tuple(args.mer_seeds), args.only_mer)
        shutil.rmtree(tmp, ignore_errors=True)
    print(table("| drive | frames | path (m) | final error (% of path) | lost / reinit | "
                "untrusted rows | rows > 4 std |", rows) + "\n")
    print(f"({load()} at the end.)")


if __name__ == "__main__":
    main()
