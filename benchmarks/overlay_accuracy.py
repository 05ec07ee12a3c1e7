"""Does the glued triangle stay glued? Vertex error of the overlay against the ground truth.

    python -m benchmarks.overlay_accuracy --frames 300 --size 512x512

Renders ``monovo synth --preset drive``, tracks it with default options (``monovo track``'s
library call), renders ``monovo overlay`` to MP4 and measures, in every frame, the image
distance between the triangle's vertices projected with the estimated pose and with the
true pose (``groundtruth.tum``), for every vertex the truth shows inside the image. Two
triangles: the default one (equilateral, centred in the ground region) and a wide one
spanning the region (its bottom corners and the middle of its top edge). Then reads the
video back with imageio and checks its frame count and size. Where evo is installed
(``pip install '.[evo]'``) it also compares ``monovo eval``'s ATE with evo's on the tracked
trajectory.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import drive_arguments, machine
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_trajectory_csv, read_tum
from monovo_cli.pipeline.overlay import overlay_sequence
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.synth.write import synthesize
from monovo_cli.viz.overlay import default_triangle_pixels, triangle_on_ground, vertex_errors


def wide_triangle_pixels(region: tuple[int, int, int, int]) -> np.ndarray:
    """Bottom-left and bottom-right corners of the region and the middle of its top edge."""
    x0, y0, x1, y1 = region
    return np.array([[x0 + 2.0, y1 - 3.0], [x1 - 3.0, y1 - 3.0], [0.5 * (x0 + x1 - 1), y0 + 2.0]])


def measure(root: Path, frames: int, size: tuple[int, int], seed: int, noise_var: float) -> dict:
    seq, out = root / "seq", root / "out"
    synthesize(seq, preset="drive", frames=frames, size=size, noise_var=noise_var, seed=seed)
    t0 = time.perf_counter()
    track_sequence(seq, None, out, TrackOptions())
    t_track = time.perf_counter() - t0
    t0 = time.perf_counter()
    ov = overlay_sequence(seq, None, out / "trajectory.csv", out / "overlay.mp4")
    t_overlay = time.perf_counter() - t0

    cfg = load_init(seq / "init.yaml")
    plane = cfg.plane
    region = cfg.region
    _, _, est = read_trajectory_csv(out / "trajectory.csv")
    _, gt = read_tum(seq / "groundtruth.tum")
    _, _, status = read_motion_csv(out / "motion.csv")
    rows = []
    for name, uv in (("default", default_triangle_pixels(region)),
                     ("wide", wide_triangle_pixels(region))):
        tri = triangle_on_ground(cfg.camera, plane, uv, region)
        err = vertex_errors(cfg.camera, tri, est, gt)
        seen = np.isfinite(err)
        flat = np.where(seen, err, -1.0)
        k, v = np.unravel_index(int(np.argmax(flat)), flat.shape)
        frames_seen = int(np.any(seen, axis=1).sum())
        last_seen = int(np.nonzero(np.any(seen, axis=1))[0].max())
        rows.append({"triangle": name, "frames_in_view": frames_seen, "last_frame_in_view": last_seen,
                     "max_px": float(err[seen].max()), "mean_px": float(err[seen].mean()),
                     "p95_px": float(np.percentile(err[seen], 95)), "worst_frame": int(k),
                     "worst_vertex": int(v)})

    import imageio.v2 as iio

    evo = evo_check(out / "trajectory.tum", seq / "groundtruth.tum")
    reader = iio.get_reader(out / "overlay.mp4")
    meta = reader.get_meta_data()
    n_read, shape = 0, None
    for img in reader:
        n_read += 1
        shape = img.shape
    reader.close()
    return {"rows": rows, "frames": frames, "size": size, "video_frames_written": ov.frames,
            "video_frames_read": n_read, "video_shape": shape, "codec": meta.get("codec"),
            "pix_fmt": meta.get("pix_fmt"), "video_bytes": (out / "overlay.mp4").stat().st_size,
            "lost": status.count("lost"), "reanchored": status.count("reanchored"),
            "t_track": t_track, "t_overlay": t_overlay, "evo": evo}


def evo_check(est_path: Path, gt_path: Path) -> list[tuple[str, float, float]] | None:
    """``[(alignment, monovo ATE, evo ATE)]`` in m, or None without evo."""
    try:
        from evo.core import metrics, sync
        from evo.tools import file_interface
    except ImportError:
        return None
    from monovo_cli.evaluation.metrics import evaluate

    ts_e, e = read_tum(est_path)
    ts_g, g = read_tum(gt_path)
    ours = evaluate(ts_e, e, ts_g, g, align=True)
    rows = []
    for align, mine in ((False, ours.ate_rmse), (True, ours.ate_rmse_aligned)):
        ref = file_interface.read_tum_trajectory_file(str(gt_path))
        est = file_interface.read_tum_trajectory_file(str(est_path))
        ref, est = sync.associate_trajectories(ref, est)
        if align:
            est.align(ref, correct_scale=False)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((ref, est))
        rows.append(("SE(3) aligned" if align else "none", mine,
                     float(ape.get_statistic(metrics.StatisticsType.rmse))))
    return rows


def main() -> None:
    args, (w, h) = drive_arguments(__doc__)
    print(f"machine: {machine()}\n")
    with tempfile.TemporaryDirectory() as tmp:
        r = measure(Path(tmp), args.frames, (w, h), args.seed, args.noise_var)
    print(f"drive: {r['frames']} frames, {w}x{h}, seed {args.seed}, noise variance "
          f"{args.noise_var:g}; {r['reanchored']} re-anchored, {r['lost']} lost; track "
          f"{r['t_track']:.1f} s, overlay (render + H.264) {r['t_overlay']:.1f} s\n")
    print("| triangle | frames with a vertex in view | last such frame | max error (px) "
          "| mean (px) | 95th percentile (px) | worst frame / vertex |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for row in r["rows"]:
        print(f"| {row['triangle']} | {row['frames_in_view']} | {row['last_frame_in_view']} | "
              f"{row['max_px']:.3f} | {row['mean_px']:.3f} | {row['p95_px']:.3f} | "
              f"{row['worst_frame']} / {row['worst_vertex']} |")
    ok = r["video_frames_read"] == r["frames"] and r["video_shape"] == (h + h % 2, w + w % 2, 3)
    print(f"\nvideo read back with imageio: {r['video_frames_read']} frames of "
          f"{r['video_shape'][1]}x{r['video_shape'][0]} ({r['codec']}, {r['pix_fmt']}, "
          f"{r['video_bytes'] / 1e6:.1f} MB); expected {r['frames']} frames of {w}x{h}: "
          f"{'ok' if ok else 'MISMATCH'}")
    if r["evo"] is None:
        print("\nevo not installed: ATE cross-check skipped (pip install '.[evo]')")
    else:
        print("\n| ATE alignment | monovo eval (m) | evo_ape (m) | difference (m) |")
        print("| --- | --- | --- | --- |")
        for name, mine, theirs in r["evo"]:
            print(f"| {name} | {mine:.9f} | {theirs:.9f} | {abs(mine - theirs):.1e} |")


if __name__ == "__main__":
    main()
