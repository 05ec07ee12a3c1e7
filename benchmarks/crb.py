"""The physical limit: Cramér–Rao lower bound of each motion parameter on the paper's pairs.

    python -m benchmarks.crb                        # 50 pairs, noise variances 0 10 50 100
    python -m benchmarks.crb --pairs 100 --noise-var 10
    python -m benchmarks.crb --noise-var 10 --texture gravel --psf 0.5

For each pair of ``benchmarks.paper_tables`` (the same seed, ``--texture`` and ``--psf`` give
the very same frames) the parameters θ are those of the reported errors: the translation (m)
and the rotation vector (rad, printed in deg) of ``T_0_1``. Frame 1 carries white Gaussian
noise of variance s2; if its noise-free value is modelled as a function ``m(θ)`` of the
motion, its Fisher information is ``J^T J / s2`` with ``J = dm/dθ`` (N_pixels x 6), and

    CRB = s2 (J^T J)^-1.

Two models of frame 1, two bounds (issue 24: "A benchmark's Cramér–Rao bound is computed
from the images as that benchmark renders them: the Fisher information of the noise-free
rendered frames, sampling included"):

**The bound from the rendered frames** (the acceptance bound). What an estimator knows of
the ground is frame 0 as rendered -- its pixels, not the texture behind them. Frame 1 is
then, exactly,

    F1(x) = R[F0](w_θ(x)) + a_θ(x) + n(x),

``w_θ(x)`` the frame-0 point that frame-1 pixel ``x`` sees (the plane homography of θ),
``R[F0]`` frame 0's image reconstructed between its samples, ``n`` the noise, and ``a_θ``
the rest: what frame 0's samples do not determine -- the texture's grain past frame 0's
Nyquist frequency, which the renderer's box pixel lets through and which the samples hold
only folded (aliased), and the small difference of the two frames' pixel footprints. The
model is ``m(θ) = R[F0](w_θ(x))`` and, by the chain rule,

    J_i = ∇R[F0](w_θ(x_i)) · dw_θ(x_i)/dθ,

the 2x6 ``dw/dθ`` by central differences of the homography (float64, steps 1e-4 m and
1e-6 rad: exact to ~1e-8). ``R`` is the band-limited (Whittaker–Shannon) reconstruction,
the one interpolant with no frequency beyond frame 0's Nyquist limit, so the bound depends on
no estimator's interpolator; it is taken of frame 0's half-sample-symmetric extension (the
DCT interpolant: no jump at the image's borders, though the gradient is damped within
~1 px of them), differentiated exactly in its spectrum, evaluated on a 4x finer grid by zero
padding and read at ``w_θ(x_i)`` by Lanczos-4 (tests/benchmarks/test_crb.py: within 1 % RMS
of the analytic gradient of band-limited images, its energy within 0.5 %). ``F0`` is the
noise-free float render (the written frame 0 is it rounded to whole grey levels).

Why this bound, and why it is a lower one. Model the texture's detail that frame 0's samples
leave open as random (a stationary texture of known statistics): then ``a_θ`` is clutter of
some covariance ``C_a`` on top of the noise, and the Fisher information of frame 1 given
frame 0 is, for Gaussian clutter, ``J^T (C_a + s2 I)^-1 J`` plus a term in ``dC_a/dθ`` (how
the clutter's variance changes with the sub-pixel phase of ``w_θ(x)``: information in the
size of the mismatch, not in its value, which no estimator that matches intensities uses;
left out). Since ``(C_a + s2 I)^-1 <= I / s2``, the ``J^T J / s2`` used here is the larger
information: the bound does not count the aliasing as noise, and is lower (stricter) for it.
It counts what frame 0's samples let an estimator predict of frame 1, no more. When the
frames do not alias (a camera with a PSF: band-limited renders) ``R[F0] ∘ w_θ`` *is* frame
1's noise-free image up to the footprints, ``a_θ ~ 0``, and the bound is the former one
below (``--texture gravel --psf 0.5`` measures it). The
mismatch ``a_θ`` at the true motion is printed (grey levels RMS), and for scale only the
ratios to the bound that would count it as white noise of its variance.

**The former bound, the texture known** (for reference). ``m(θ)`` = synth's rendering of
frame 1: ``J`` by central finite differences of the same supersampled, mip-mapped renderer
that drew the frames, optics included (its float32 warps are exact, not 1/32 px quantised):
the pair's ``g_from_cam1 = g_from_cam0 @ [exp(r) | t]`` is rendered with ``t_j +- h_t``
(``h_t = 3e-3`` m, ~0.02 px of image motion) and ``r_j +- h_r`` (``h_r = 3e-5`` rad,
~0.02 px), noise free, in float, and differenced. (Steps 10x smaller let the renderer's
float32 rounding inflate J^T J and shrink the bound by up to 20 %; 3x larger or smaller
steps change it by < 1 %.) It takes the continuous texture as known: where the frames
alias (gravel without a PSF) it also counts the motion of grain that frame 0's samples do
not hold. Measured, that share is small (the bound from the rendered frames is 3-7 % above
it on gravel, 0-1 % on procedural and behind a 0.5 px PSF): the samples keep nearly all
the gradient information; what aliasing takes is the *prediction* of frame 1 from them (the
mismatch, printed by ``--texture gravel`` without a PSF).

Pixels, for both: every pixel of frame 1 whose ground point lies inside frame 0's ground
region (the ground model only knows what frame 0 saw); the former bound over all of frame 1
is printed for reference.

Noise: frames carry Gaussian noise of variance ``V`` and are rounded to 8 bit, so the
effective variance is ``s2 = V + 1/12``. By default frame 0 is noise-free (the paper's
experiment) and the bound is the **second image only** one, ``s2 (J^T J)^-1``; with
``--noisy-frame0`` monovo compares frame 1 with a noisy frame 0, every intensity difference
carries the noise of two images, and the ratios are against ``2 s2 (J^T J)^-1`` (**both
images noisy**: the bound of the linearised difference model, neglecting the noise of the
reference gradients).

monovo's errors are aggregated over the converged pairs (as in the paper tables). Per
parameter: RMS error beside ``sigma_CRB = sqrt(mean_i CRB_i)`` (the bound on the RMS), and
mean |error| beside ``sqrt(2/pi) mean_i sqrt(CRB_i)`` (the mean |error| an efficient,
unbiased Gaussian estimator would reach). A ratio of 1 means the bound is attained.
The two Jacobians take ~2 s per pair (12 perturbed renders; frame 0's 4x upsampled
spectrum); 50 pairs at one noise level, tracking included, ~2-3 min.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import (
    AXES,
    PairScene,
    add_frame0_option,
    add_points_option,
    machine,
    one_core,
    options_note,
    pair_renderer,
    pair_scenes,
    track_options,
)
from benchmarks.docs_section import writes_section
from benchmarks.paper_tables import run_pairs, scene_header
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import pose_from_vectors, so3_log
from monovo_cli.synth.render import GroundRenderer, plane_homography

H_T = 3e-3  # m
H_R = 3e-5  # rad
GEOMETRY_H_T = 1e-4  # m: steps of dw/dθ (exact geometry in float64)
GEOMETRY_H_R = 1e-6  # rad
UPSAMPLE = 4  # the band-limited gradient's grid, read by Lanczos-4 between its nodes
MAX_RATIO = 2.0  # issue 13's acceptance: error <= 2x the bound on every axis
QUANTISATION_VAR = 1.0 / 12.0  # rounding to whole grey levels


def central_differences(cam0_from_cam1: np.ndarray, f, h_t: float, h_r: float) -> list[np.ndarray]:
    """The six central differences ``(f(+h) - f(-h)) / 2h`` of ``f(cam0_from_cam1')`` over the
    parameters θ = (t, r) of ``cam0_from_cam1 = [exp(r) | t]``, steps ``h_t`` (m) on t and
    ``h_r`` (rad) on r."""
    t = cam0_from_cam1[:3, 3].copy()
    r = so3_log(cam0_from_cam1[:3, :3])
    cols = []
    for j in range(6):
        h = h_t if j < 3 else h_r
        values = []
        for sign in (1.0, -1.0):
            tp, rp = t.copy(), r.copy()
            if j < 3:
                tp[j] += sign * h
            else:
                rp[j - 3] += sign * h
            values.append(f(pose_from_vectors(tp, rp)))
        cols.append((values[0] - values[1]) / (2.0 * h))
    return cols


def image_jacobian(renderer: GroundRenderer, g_from_cam0: np.ndarray, cam0_from_cam1: np.ndarray,
                   *, h_t: float = H_T, h_r: float = H_R) -> np.ndarray:
    """(H*W, 6) float64: d(noise-free frame 1)/d(t, r) of ``cam0_from_cam1 = [exp(r) | t]``,
    grey levels per metre (columns 0-2) and per radian (3-5), central differences."""
    cols = central_differences(
        cam0_from_cam1, lambda T: renderer.render(g_from_cam0 @ T).astype(np.float64).ravel(),
        h_t, h_r)
    return np.stack(cols, axis=1)


def seen_in_frame0(cam: PinholeCamera, g_from_cam0: np.ndarray, g_from_cam1: np.ndarray,
                   region: tuple[int, int, int, int]) -> np.ndarray:
    """(H*W,) bool: frame-1 pixels whose ground point projects inside frame 0's ``region``
    (x0, y0, x1, y1; pixel centres, x1 and y1 exclusive)."""
    x, y = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    cam0_from_cam1_px = plane_homography(cam, g_from_cam0) @ np.linalg.inv(
        plane_homography(cam, g_from_cam1))
    p = cam0_from_cam1_px @ np.stack([x.ravel(), y.ravel(), np.ones(x.size)])
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = p[0] / p[2], p[1] / p[2]
    x0, y0, x1, y1 = region
    return (p[2] > 0) & (u >= x0) & (u <= x1 - 1) & (v >= y0) & (v <= y1 - 1)


def information(cam: PinholeCamera, tex, scene: PairScene, renderer
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """The former bound's ``J^T J`` (6, 6) (the texture known: finite differences of
    ``renderer``, a GroundRenderer or PsfRenderer) over the pixels frame 0 saw, over all
    pixels, and the share seen."""
    J = image_jacobian(renderer, scene.g_from_cam0, scene.prev_from_cur)
    seen = seen_in_frame0(cam, scene.g_from_cam0, scene.g_from_cam1, scene.region)
    Js = J[seen]
    return Js.T @ Js, J.T @ J, float(seen.mean())


# --------------------------------------------------------------------------- the rendered frames


class BandLimited:
    """``image``'s band-limited reconstruction (module docstring) and its gradient, readable
    at any point ``(x, y)`` of the image (pixel centres at integers; grey levels, per px).

    The half-sample-symmetric extension (2H x 2W) is periodic and continuous; its
    trigonometric interpolant, and the exact derivatives of it (the DFT times
    ``2 pi i f``), are evaluated on a grid ``upsample`` times finer by zero padding the
    spectrum (its Nyquist row and column are 0 for a symmetric extension) and read there
    by Lanczos-4. (OpenCV's remap steps positions by 1/32 of a node: ~0.6 % RMS error of the
    gradient at 4x, zero-mean; its energy within 0.5 %.)"""

    MARGIN = 8  # fine nodes kept beyond the image on every side (Lanczos-4 reaches 4)

    def __init__(self, image: np.ndarray, upsample: int = UPSAMPLE) -> None:
        h, w = image.shape
        u = int(upsample)
        ext = np.asarray(image, dtype=np.float64)
        ext = np.concatenate([ext, ext[::-1]], axis=0)
        ext = np.concatenate([ext, ext[:, ::-1]], axis=1)
        F = np.fft.rfft2(ext)  # (2h, w + 1)
        F[h, :] = 0.0  # the Nyquist terms (0 up to rounding for a symmetric extension)
        F[:, w] = 0.0
        fy = np.fft.fftfreq(2 * h)[:, None]  # cycles per pixel
        fx = np.fft.rfftfreq(2 * w)[None, :]
        rows = np.arange(-self.MARGIN, h * u + self.MARGIN) % (2 * h * u)
        cols = np.arange(-self.MARGIN, w * u + self.MARGIN) % (2 * w * u)
        self.u = u
        self.grids = []  # value, d/dx, d/dy on the fine grid
        for factor in (1.0, 2j * np.pi * fx, 2j * np.pi * fy):
            G = (F * factor).astype(np.complex64)
            P = np.zeros((2 * h * u, w * u + 1), np.complex64)
            P[:h, :w + 1] = G[:h]
            P[-h:, :w + 1] = G[h:]
            fine = np.fft.irfft2(P, s=(2 * h * u, 2 * w * u)) * np.float32(u * u)
            self.grids.append(np.ascontiguousarray(fine[rows][:, cols], dtype=np.float32))

    def at(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(value, d/dx, d/dy)`` (N,) float64 at the points ``(x, y)`` (N,)."""
        n = np.size(x)
        rows = -(-n // 1024)  # (remap's maps must stay below 32767 rows)
        maps = []
        for v in (x, y):
            m = np.zeros(rows * 1024, np.float32)
            m[:n] = np.asarray(v, dtype=np.float64).ravel() * self.u + self.MARGIN
            maps.append(m.reshape(rows, 1024))
        return tuple(cv2.remap(g, maps[0], maps[1], cv2.INTER_LANCZOS4,
                               borderMode=cv2.BORDER_REPLICATE).ravel()[:n].astype(np.float64)
                     for g in self.grids)


def frame0_points(cam: PinholeCamera, g_from_cam0: np.ndarray, g_from_cam1: np.ndarray,
                  x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(N, 2): the frame-0 pixel positions of the ground that frame-1 pixels ``(x, y)`` see."""
    M = plane_homography(cam, g_from_cam0) @ np.linalg.inv(plane_homography(cam, g_from_cam1))
    p = M @ np.stack([x, y, np.ones_like(x)])
    return (p[:2] / p[2]).T


def warp_jacobian(cam: PinholeCamera, g_from_cam0: np.ndarray, cam0_from_cam1: np.ndarray,
                  x: np.ndarray, y: np.ndarray, *, h_t: float = GEOMETRY_H_T,
                  h_r: float = GEOMETRY_H_R) -> np.ndarray:
    """(N, 2, 6): ``dw_θ(x)/dθ`` of frame-1 pixels ``(x, y)``, θ = (t, r) of
    ``cam0_from_cam1 = [exp(r) | t]`` (px per m, px per rad), central differences."""
    cols = central_differences(
        cam0_from_cam1, lambda T: frame0_points(cam, g_from_cam0, g_from_cam0 @ T, x, y), h_t, h_r)
    return np.stack(cols, axis=2)


@dataclass(frozen=True)
class SampledModel:
    """The bound from the rendered frames of one pair (module docstring): ``info`` = J^T J
    (6, 6) of ``R[F0](w_θ(x))`` over the frame-1 pixels frame 0 saw; and at the true motion,
    noise-free, the mismatch ``a`` = frame 1 minus that prediction: its mean square
    ``mismatch_ms`` (grey levels^2) and ``floor`` (6,; m, rad), the motion error
    ``(J^T J)^-1 J^T a`` it alone makes in one least-squares step from the truth."""

    info: np.ndarray
    mismatch_ms: float
    floor: np.ndarray


def sampled_model(cam: PinholeCamera, scene: PairScene, renderer) -> SampledModel:
    """:class:`SampledModel` of one pair, its frames rendered noise-free by ``renderer``
    (the pairs' own, optics included)."""
    f0 = BandLimited(renderer.render(scene.g_from_cam0))
    seen = seen_in_frame0(cam, scene.g_from_cam0, scene.g_from_cam1, scene.region)
    x, y = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    x, y = x.ravel()[seen], y.ravel()[seen]
    p = frame0_points(cam, scene.g_from_cam0, scene.g_from_cam1, x, y)
    value, gx, gy = f0.at(p[:, 0], p[:, 1])
    dw = warp_jacobian(cam, scene.g_from_cam0, scene.prev_from_cur, x, y)
    J = gx[:, None] * dw[:, 0, :] + gy[:, None] * dw[:, 1, :]
    info = J.T @ J
    a = renderer.render(scene.g_from_cam1).astype(np.float64).ravel()[seen] - value
    return SampledModel(info, float(np.mean(a ** 2)), np.linalg.solve(info, J.T @ a))


def bound_std(info: np.ndarray, var: float) -> np.ndarray:
    """Per-parameter standard deviation bound (6,): m, and deg for the rotation vector."""
    s = np.sqrt(np.diag(var * np.linalg.inv(info)))
    return np.concatenate([s[:3], np.degrees(s[3:])])


def bound_levels(stds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What per-pair bounds ``stds`` (n, 6; std) allow over the n pairs, per axis (6,): the
    RMS error ``sqrt(mean_i CRB_i)`` and the mean |error| ``sqrt(2/pi) mean_i sqrt(CRB_i)``
    of an efficient, unbiased Gaussian estimator."""
    return (np.sqrt(np.mean(stds ** 2, axis=0)),
            math.sqrt(2.0 / math.pi) * np.mean(stds, axis=0))


def ratio_cells(errs: np.ndarray, stds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """mean |error| / (sqrt(2/pi) mean σ) and RMS error / sqrt(mean σ²) per axis (6,) (6,)."""
    bound_rms, bound_mae = bound_levels(stds)
    return (np.mean(np.abs(errs), axis=0) / bound_mae,
            np.sqrt(np.mean(errs ** 2, axis=0)) / bound_rms)


def crb_table(errs: np.ndarray, sampled: np.ndarray, former: np.ndarray) -> str:
    """Errors (n, 6) beside the per-pair bounds (n, 6; std, same units) from the rendered
    frames and with the texture known."""
    rms = np.sqrt(np.mean(errs ** 2, axis=0))
    mae = np.mean(np.abs(errs), axis=0)
    lines = ["| axis | monovo mean abs | monovo RMS | CRB σ, rendered frames | mean abs / CRB "
             "| RMS / CRB | CRB σ, texture known (former) | mean abs / CRB | RMS / CRB |",
             "|" + " --- |" * 9]
    (s_rms, _), (f_rms, _) = bound_levels(sampled), bound_levels(former)
    (s_mae_r, s_rms_r), (f_mae_r, f_rms_r) = ratio_cells(errs, sampled), ratio_cells(errs, former)
    for i, name in enumerate(AXES):
        lines.append(f"| {name} | {mae[i]:.2e} | {rms[i]:.2e} | {s_rms[i]:.2e} | {s_mae_r[i]:.2f} | "
                     f"{s_rms_r[i]:.2f} | {f_rms[i]:.2e} | {f_mae_r[i]:.2f} | {f_rms_r[i]:.2f} |")
    return "\n".join(lines)


def acceptance(errs: np.ndarray, stds: np.ndarray) -> str:
    """The issue's criterion against ``stds``: error <= MAX_RATIO x the bound on every axis,
    mean abs and RMS."""
    mae_r, rms_r = ratio_cells(errs, stds)
    both = np.stack([mae_r, rms_r])
    k, i = np.unravel_index(int(np.argmax(both)), both.shape)
    worst = f"{both[k, i]:.2f} ({AXES[i].split()[0]}, {('mean abs', 'RMS')[k]})"
    verdict = "holds" if both.max() <= MAX_RATIO else "fails"
    return (f"Acceptance, error <= {MAX_RATIO:g}x the bound from the rendered frames on every axis "
            f"(mean abs {mae_r.min():.2f}-{mae_r.max():.2f}, RMS {rms_r.min():.2f}-{rms_r.max():.2f}): "
            f"worst {worst}: **{verdict}**")


def axis_cells(v: np.ndarray) -> str:
    return ", ".join(f"{a.split()[0]} {x:.2f}" for a, x in zip(AXES, v))


@writes_section("crb", "The pairs against the Cramér–Rao bound", "benchmarks.crb")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_points_option(ap)
    add_frame0_option(ap)
    ap.add_argument("--pairs", type=int, default=50, help="pairs (the first N of paper_tables' pairs)")
    ap.add_argument("--noise-var", type=float, nargs="+", default=[0.0, 10.0, 50.0, 100.0])
    ap.add_argument("--seed", type=int, default=1, help="same default as paper_tables")
    ap.add_argument("--texture", default="procedural", metavar="procedural|gravel|PNG",
                    help="synth's texture of the pairs [procedural]")
    ap.add_argument("--psf", type=float, default=0.0, metavar="SIGMA_PX",
                    help="render the pairs through synth's optical blur (`synth --psf`) [0]")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    one_core()
    texture = None if args.texture == "procedural" else args.texture
    print(f"Machine: {machine()}\n")
    print(scene_header(args.pairs, args.seed, options_note(args), not args.noisy_frame0)
          + f" Texture: {args.texture}; optics: "
          + (f"a Gaussian PSF of {args.psf:g} px before the pixel (`synth --psf {args.psf:g}`)."
             if args.psf > 0 else "none (no blur before the pixel).") + "\n")
    noise_model = 2.0 if args.noisy_frame0 else 1.0  # both images noisy / second image only
    models = None
    t0 = time.perf_counter()
    for nv in args.noise_var:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp) / "pairs"
            errs, ok, _, _ = run_pairs(root, args.pairs, nv, args.seed, track_options(args),
                                       not args.noisy_frame0, texture=texture, psf=args.psf)
            if models is None:  # the geometry and noise-free frames are the same at every level
                cam, tex, scenes = pair_scenes(root)
                renderer = pair_renderer(root, cam, tex)
                infos = [information(cam, tex, sc, renderer) for sc in scenes]
                models = [sampled_model(cam, sc, renderer) for sc in scenes]
                seen = np.array([f for _, _, f in infos])
                print(f"Jacobians of {len(scenes)} pairs in {time.perf_counter() - t0:.0f} s "
                      f"(the texture known: h = {H_T:g} m, {H_R:g} rad; the rendered frames: "
                      f"frame 0's band-limited gradient, {UPSAMPLE}x grid); frame-1 pixels seen by "
                      f"frame 0: {100 * seen.mean():.1f} % on average (min {100 * seen.min():.1f} %)\n")
                s_seen = np.sqrt(np.mean([np.diag(np.linalg.inv(i)) for i, _, _ in infos], 0))
                s_all = np.sqrt(np.mean([np.diag(np.linalg.inv(i)) for _, i, _ in infos], 0))
                s_rend = np.sqrt(np.mean([np.diag(np.linalg.inv(m.info)) for m in models], 0))
                print("Bound from the rendered frames / bound with the texture known (RMS σ over "
                      f"the pairs, any noise level): {axis_cells(s_rend / s_seen)}\n")
                print("Bound with the texture known, over the pixels frame 0 saw / over all of "
                      f"frame 1: {axis_cells(s_seen / s_all)}\n")
                mismatch = math.sqrt(float(np.mean([m.mismatch_ms for m in models])))
                print(f"Frame 1 minus its prediction from frame 0's samples at the true motion, "
                      f"noise-free (the aliasing and the footprints): {mismatch:.2f} grey levels "
                      "RMS over the pixels frame 0 saw\n")
        var = noise_model * (nv + QUANTISATION_VAR)
        sampled = np.array([bound_std(m.info, var) for m in models])
        former = np.array([bound_std(i, var) for i, _, _ in infos])
        print(f"### Noise variance {nv:g} (effective {nv + QUANTISATION_VAR:.3f} with 8-bit "
              f"rounding; bound of {'both images noisy' if args.noisy_frame0 else 'the second image only'}): "
              f"{ok.sum()}/{len(ok)} pairs converged\n")
        print(crb_table(errs[ok], sampled[ok], former[ok]) + "\n")
        print(acceptance(errs[ok], sampled[ok]) + "\n")
        clutter = math.sqrt((var + mismatch ** 2) / var)
        mae_r, rms_r = ratio_cells(errs[ok], sampled[ok] * clutter)
        print(f"For scale, not a lower bound: were the mismatch white noise of its variance, the "
              f"bound would be {clutter:.2f}x larger; mean abs / that: {axis_cells(mae_r)}; "
              f"RMS / that: {axis_cells(rms_r)}\n")


if __name__ == "__main__":
    main()
