"""Why the gravel pairs sit at 2-3x the Cramér–Rao bound: aliasing in the rendered frames.

    python -m benchmarks.aliasing                 # 50 pairs per texture, ~40 min at load 4
    python -m benchmarks.aliasing --pairs 10 --split-pairs 5       # ~8 min

The pairs of ``benchmarks.real --sections pairs`` (seed ``PAIR_SEED``, noise variance 10 on
frame 1, frame 0 noise-free; rendered into ``--renders`` like that section and reused), the
first ``--pairs`` of each texture. Three measurements, every ratio against the bound of the
noisy pairs (``benchmarks.crb``, second image only, RMS over the pairs):

* **noise-free floor** -- the same pairs rendered again without noise (same geometry, same
  frame 0), tracked with default options: what is left is model error, not noise;
* **the model error at the true pose** (noise-free, ``--split-pairs`` pairs) -- frame 1 sampled
  at the keyframe's finest-level points moved by the true motion, minus the points' frame-0
  intensities, split into *interpolation* (frame 1's bicubic sample minus the exact value of
  a frame-1 pixel centred there: the 4x4 box of a 4x render, the renderer's own pixel) and
  *footprint* (that exact value minus the frame-0 pixel: the view-dependent filtering), with
  the ideal band-limited (sinc) reconstruction of frame 1 beside bicubic; RMS over the points
  and the motion error each part alone causes (one least-squares step from the true pose with
  the estimator's rows);
* **the test** -- the pairs rendered by a camera whose optics blur before the pixel (a
  Gaussian PSF of ``--psf`` px, then the same 4x4-supersampled box), which band-limits the
  frames; noise of the pairs' variance on frame 1 (drawn here, seed ``PAIR_SEED``), the
  bound computed with that renderer, tracked with default options.

Why it matters: ``benchmarks.crb`` differentiates the renderer, i.e. takes the continuous
texture as known, while monovo knows frame 0's samples; where the frames are aliased the
bound counts information that no estimator working from samples can use (this script measures
how much: run it).
"""

from __future__ import annotations

import argparse
import hashlib
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import AXES, load, machine, motion_errors, one_core, pair_scenes
from benchmarks.crb import QUANTISATION_VAR, bound_levels, bound_std, information
from benchmarks.real_synth import NOISE_VAR, PAIR_SEED, RENDERS, crb_stds, rendered, rock_png
from monovo_cli.core.estimator.estimate import residuals
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.geometry.lie import se3_exp, se3_inv
from monovo_cli.image.sampling import sample_at
from monovo_cli.io.config import load_init
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.render import SUPERSAMPLE, GroundRenderer, finish_frame
from monovo_cli.synth.write import synthesize

VAR = NOISE_VAR + QUANTISATION_VAR
FULL = 100  # pairs per texture of benchmarks.real's pairs section (its default)


class BlurredRenderer:
    """``GroundRenderer``'s image with a Gaussian PSF of ``sigma`` px before the pixel's box:
    the supersampled grid is rendered as one image of a camera ``SUPERSAMPLE`` times finer,
    blurred, and averaged over each pixel's ``SUPERSAMPLE`` x ``SUPERSAMPLE`` block (with
    ``sigma = 0`` it is ``GroundRenderer``'s image)."""

    def __init__(self, cam, texture, sigma: float) -> None:
        s = SUPERSAMPLE
        fine = replace(cam, width=cam.width * s, height=cam.height * s, fx=cam.fx * s,
                       fy=cam.fy * s, cx=cam.cx * s + (s - 1) / 2.0, cy=cam.cy * s + (s - 1) / 2.0)
        self.cam, self.sigma = cam, float(sigma)
        self.fine = GroundRenderer(fine, texture, supersample=1)

    def render_fine(self, g_from_cam: np.ndarray) -> np.ndarray:
        img = self.fine.render(g_from_cam)
        if self.sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), self.sigma * SUPERSAMPLE,
                                   borderType=cv2.BORDER_REFLECT)
        return img

    def render(self, g_from_cam: np.ndarray) -> np.ndarray:
        return cv2.resize(self.render_fine(g_from_cam), (self.cam.width, self.cam.height),
                          interpolation=cv2.INTER_AREA)


def sinc_upsampled(image: np.ndarray, s: int) -> np.ndarray:
    """``image`` (H, W) reconstructed band-limited (zero-padded spectrum of its symmetric
    extension) on a grid ``s`` times finer: pixel (y, x) of the result is (y / s, x / s)."""
    h, w = image.shape
    ext = np.concatenate([image, image[::-1]], 0)
    ext = np.concatenate([ext, ext[:, ::-1]], 1).astype(np.float64)
    H, W = ext.shape
    F = np.zeros((H * s, W * s), complex)
    r0, c0 = H * s // 2 - H // 2, W * s // 2 - W // 2
    F[r0:r0 + H, c0:c0 + W] = np.fft.fftshift(np.fft.fft2(ext))
    up = np.real(np.fft.ifft2(np.fft.ifftshift(F))) * s * s
    return up[:h * s, :w * s].astype(np.float32)


def ratios(errs: np.ndarray, stds: np.ndarray) -> np.ndarray:
    """RMS error / RMS bound per axis (6,)."""
    return np.sqrt(np.mean(errs ** 2, axis=0)) / bound_levels(stds)[0]


def cells(v: np.ndarray) -> str:
    return " / ".join(f"{x:.2f}" for x in v)


def track_frames(scene, frames: list[np.ndarray]) -> np.ndarray:
    """Errors (6,) of monovo (default options) on a pair held in memory."""
    cfg = load_init(scene.directory / "init.yaml")
    res = list(estimate_frames([(k, float(k), f) for k, f in enumerate(frames)], cfg.camera, cfg.plane,
                     cfg.region, TrackOptions()))
    return motion_errors(res[1].prev_from_cur, scene.prev_from_cur)


def split(scene, cam, renderer: BlurredRenderer) -> dict[str, tuple[float, np.ndarray]]:
    """The noise-free model error at the true pose of one pair, by part: RMS over the points
    (grey levels) and the motion error (6,) one least-squares step makes of it."""
    s = SUPERSAMPLE
    f0, f1 = (finish_frame(renderer.render(g), np.random.default_rng(0), 0.0).astype(np.float32)
              for g in (scene.g_from_cam0, scene.g_from_cam1))
    cfg = load_init(scene.directory / "init.yaml")
    level = build_keyframe(0, f0, cam, cfg.plane, cfg.region, np.eye(4), TrackOptions()).levels[0]
    n = len(level.points)
    cur_from_key = se3_inv(scene.prev_from_cur)
    grid = level.warp_grid(cur_from_key)
    # the frame-1 pixel centred at u: the s x s box of the fine render around s u + (s-1)/2
    box = cv2.blur(renderer.render_fine(scene.g_from_cam1), (s, s), borderType=cv2.BORDER_REPLICATE)
    exact, ok = sample_at(box, (grid * s + s / 2.0).astype(np.float32), n, cv2.INTER_CUBIC)
    sinc, ok_s = sample_at(sinc_upsampled(f1, s), (grid * s).astype(np.float32), n, cv2.INTER_CUBIC)
    cubic, valid = residuals(level, f1, cur_from_key, flag=cv2.INTER_CUBIC)
    u, v = grid.reshape(-1, 2)[:n].T
    valid &= ok & ok_s & (u > 8) & (u < cam.width - 9) & (v > 8) & (v < cam.height - 9)
    ref = level.points.intensity
    A = level.J.astype(np.float64) * valid[:, None]  # the rows o_i and the brightness columns
    parts = {"bicubic, all (the estimator's)": cubic,
             "bicubic interpolation": cubic + ref - exact,
             "footprint (view-dependent filtering)": exact - ref,
             "sinc reconstruction, all": sinc - ref}
    out = {}
    for name, r in parts.items():
        r = (r * valid).astype(np.float64)
        p = np.linalg.solve(A.T @ A, A.T @ r)
        out[name] = (float(np.sqrt(np.mean(r[valid] ** 2))),
                     motion_errors(se3_inv(cur_from_key @ se3_exp(-p[:6])), scene.prev_from_cur))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=50, help=f"pairs per texture (<= {FULL}) [50]")
    ap.add_argument("--split-pairs", type=int, default=20, help="pairs of the split [20]")
    ap.add_argument("--psf", type=float, default=0.5, help="PSF sigma of the test, px [0.5]")
    ap.add_argument("--renders", type=Path, default=RENDERS,
                    help=f"rendered pairs, shared with benchmarks.real [{RENDERS}]")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}, {load()}\n")
    n, t0 = min(args.pairs, FULL), time.perf_counter()
    args.renders.mkdir(parents=True, exist_ok=True)
    rock = rock_png(args.renders)
    floor, split_rows, test_rows = [], [], []
    for label, texture in (("procedural", None), ("gravel", "gravel"), ("rock", rock)):
        tag = label if texture != rock else f"rock-{hashlib.sha1(rock.read_bytes()).hexdigest()[:8]}"
        # the benchmark's 100 pairs (benchmarks.real --sections pairs), of which the first n
        pairs_dir = rendered(args.renders, f"pairs_{tag}_{FULL}_{PAIR_SEED}_{NOISE_VAR:g}_clean0",
                             lambda d, t=texture: synthesize(
                                 d, preset="pairs", frames=FULL, noise_var=NOISE_VAR,
                                 seed=PAIR_SEED, texture=t, clean_frame0=True)) / "data"
        cam, tex, scenes = pair_scenes(pairs_dir)
        scenes = scenes[:n]
        stds = crb_stds(pairs_dir, VAR)[0][:n]
        box = BlurredRenderer(cam, tex, 0.0)
        errs = np.array([track_frames(sc, [f.image for f in open_frames(sc.directory / "frames")])
                         for sc in scenes])
        clean = np.array([track_frames(sc, [finish_frame(box.render(g), np.random.default_rng(0),
                                                         0.0).astype(np.float32)
                                            for g in (sc.g_from_cam0, sc.g_from_cam1)])
                          for sc in scenes])
        floor.append((label, ratios(errs, stds), ratios(clean, stds)))
        acc: dict[str, list] = {}
        for sc in scenes[:args.split_pairs]:
            for name, (rms, e) in split(sc, cam, box).items():
                acc.setdefault(name, []).append((rms, e))
        for name, v in acc.items():
            split_rows.append((label, name, np.mean([r for r, _ in v]),
                               ratios(np.array([e for _, e in v]), stds[:args.split_pairs])))
        blurred = BlurredRenderer(cam, tex, args.psf)
        rng = np.random.default_rng(PAIR_SEED)
        test, b_stds = [], []
        for sc in scenes:
            frames = [finish_frame(blurred.render(g), rng, v).astype(np.float32)
                      for g, v in ((sc.g_from_cam0, 0.0), (sc.g_from_cam1, NOISE_VAR))]
            test.append(track_frames(sc, frames))
            b_stds.append(bound_std(information(cam, tex, sc, blurred)[0], VAR))
        test, b_stds = np.array(test), np.array(b_stds)
        test_rows.append((label, ratios(test, b_stds), bound_levels(b_stds)[0],
                          bound_levels(stds)[0], np.sqrt(np.mean(test ** 2, axis=0)),
                          np.sqrt(np.mean(errs ** 2, axis=0))))
        print(f"({label} done, {time.perf_counter() - t0:.0f} s so far, {load()})", flush=True)
    axes = " / ".join(a.split()[0] for a in AXES)
    print(f"\n#### Noise-free floor: the first {n} pairs of each texture, RMS error / RMS "
          f"σ_CRB of the noisy pairs (noise variance {NOISE_VAR:g}), {axes}\n")
    print("| texture | noisy pairs (the benchmark) | the same pairs noise-free |\n| --- | --- | --- |")
    for label, noisy, clean in floor:
        print(f"| {label} | {cells(noisy)} | {cells(clean)} |")
    print(f"\n#### The model error at the true pose, noise-free, first {args.split_pairs} pairs: "
          "RMS over the points (grey levels; the noise's σ is "
          f"{np.sqrt(NOISE_VAR):.2f}) and the motion error it alone causes, RMS / σ_CRB, {axes}\n")
    print("| texture | part | RMS (grey levels) | motion error / σ_CRB |\n| --- | --- | --- | --- |")
    for label, name, rms, r in split_rows:
        print(f"| {label} | {name} | {rms:.2f} | {cells(r)} |")
    print(f"\n#### The test: a camera with a Gaussian PSF of σ = {args.psf:g} px before the pixel "
          f"(band-limited frames), the first {n} pairs, noise variance {NOISE_VAR:g} on frame 1, "
          "the bound of that camera\n")
    print(f"| texture | RMS error / σ_CRB {axes} | σ_CRB tx (m), rx (deg) | RMS error tx (m), rx "
          "(deg) | the benchmark's camera: σ_CRB, RMS error |\n| --- | --- | --- | --- | --- |")
    for label, r, b, b0, e, e0 in test_rows:
        print(f"| {label} | {cells(r)} | {b[0]:.2e}, {b[3]:.2e} | {e[0]:.2e}, {e[3]:.2e} | "
              f"{b0[0]:.2e}, {b0[3]:.2e}; {e0[0]:.2e}, {e0[3]:.2e} |")


if __name__ == "__main__":
    main()
