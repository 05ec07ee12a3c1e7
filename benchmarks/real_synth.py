"""Issue 13's synthetic acceptance runs: sections ``mer``, ``pairs`` and ``speed`` of
``python -m benchmarks.real`` (this module holds them, real.py dispatches).

    python -m benchmarks.real --sections mer pairs       # ~15 min on one core (~10 once
                                                         # the renders are cached)
    python -m benchmarks.real --sections mer pairs --mer-frames 20 --pairs 10   # ~3 min
    python -m benchmarks.real --sections speed           # ~1 min

* ``mer`` -- "your synthetic MER-spacing drive (1024², 0.6-0.75 m steps and 12-18 deg turns
  in place at 1.5 m, 45 deg pitch, suspension bobbing): <= 1 % of the distance, 0 lost".
  ``synthesize(preset="mer")`` (flat terrain, ray cast, the body bobbing), ``--mer-frames``
  frames (default 100), seed ``MER_SEED``, noise variance 10; tracked end to end with default
  options (``pipeline.track.track_sequence`` through ``benchmarks.peers.monovo_on_drive``);
  the ORB and ECC peers of ``benchmarks.peers`` frame to frame on the same PNGs, chained
  (each carries init.yaml's plane with its own motions). Per method: final position error as
  % of the distance, final heading error, lost (monovo) or failed (peers) frames, re-inits,
  the longest run of lost frames, frames/s; then monovo's reasons for its lost frames
  (motion.csv's reason column).
* ``pairs`` -- "paper pairs, three textures, +-5 deg, 100 pairs each: >= 99.5 % converge;
  errors still <= 2x the Cramér-Rao bound". ``synthesize(preset="pairs")`` (688x544, ground
  100 m away, +-5 deg, +-10 m, noise variance 10 on frame 1, frame 0 noise-free as in the
  paper; ``--noisy-frame0`` for both) with seed ``PAIR_SEED`` on three textures: the built-in
  procedural one, the built-in ``gravel``, and a rock surface built here
  (:func:`rock_texture`, never used to tune monovo) given as an image file. ``--pairs`` pairs
  each (default 100). A pair **converges** when the tracker does not call frame 1 lost and
  the error is below ``CONVERGED_M`` m / ``CONVERGED_DEG`` deg on every axis (for a peer: it
  gave an estimate within those bounds). Per texture and method: the converged share, the
  mean |error| per axis over the converged pairs and its ratio to the Cramér-Rao bound of
  ``benchmarks.crb`` (the bound's mean |error| ``sqrt(2/pi) mean_i sigma_i`` over the same
  pairs; the RMS ratio beside it), ms per pair.
* ``speed`` -- "small-motion drives keep their speed: >= 60 frames/s end to end at 512²,
  measured against ECC in the same run". ``benchmarks.speed.measure`` on its 512x512 drive
  (``--speed-frames`` frames, default 200, seed 0, noise variance 10), printed as its row;
  checked as frames/s and, since a shared machine's load slows both alike, as monovo / ECC
  in the same run against 60 / ``ECC_REFERENCE_FPS`` (ECC's frames/s on the idle machine).

Every section ends with the acceptance bounds it checks, the measured value and whether it
holds. Rendered frames (and the pairs' Cramér-Rao information, which depends on the frames
only) are kept in ``--renders`` (default ``RENDERS``), one folder per parameter set and
fingerprint of ``monovo_cli/synth``'s sources, and reused on the next run (``--fresh``: a
temporary folder instead). Rendering the 100 MER frames takes ~2 s each, the Cramér-Rao
Jacobians ~1 s per pair.
"""

from __future__ import annotations

import csv
import hashlib
import math
import os
import shutil
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import AXES, add_frame0_option, load, pair_renderer, pair_scenes
from benchmarks.crb import QUANTISATION_VAR, bound_levels, bound_std, information
from benchmarks.paper_tables import track_pairs
from benchmarks.peers import EccPeer, OrbPeer, monovo_on_drive, peer_on_drive, peer_on_pairs
from monovo_cli.core.options import TrackOptions
from monovo_cli.synth.write import synthesize

RENDERS = Path(tempfile.gettempdir()) / "monovo-bench-renders"
NOISE_VAR = 10.0
MER_SEED = 0
PAIR_SEED = 1  # paper_tables' and crb's default: the procedural pairs are theirs
SPEED_SEED = 0  # benchmarks.speed's default
ROCK_SEED = 20261124
ROCK_SIDE = 2048  # px; load_texture mirrors it to 4096, the procedural texture's side at 688x544
CONVERGED_M = 1.0  # m, every translation axis
CONVERGED_DEG = 1.0  # deg, every rotation axis

MER_MAX_PCT = 1.0  # acceptance: final position error, % of the distance
PAIRS_MIN_SHARE = 99.5  # acceptance: % converged per texture
PAIRS_MAX_CRB = 2.0  # acceptance: error / Cramér-Rao bound, every axis
SPEED_MIN_FPS = 60.0  # acceptance: frames/s end to end at 512x512
# ECC's frames/s on the same 512x512 drive on the idle machine (benchmarks.speed, first run at
# 743ab74, load 1.0-1.1): on a loaded machine monovo / ECC in the same run
# >= SPEED_MIN_FPS / this is the load-independent form of the bound.
ECC_REFERENCE_FPS = 17.2


def add_arguments(ap) -> None:
    """This module's options on ``benchmarks.real``'s parser."""
    ap.add_argument("--mer-frames", type=int, default=100, help="frames of the MER drive [100]")
    ap.add_argument("--mer-seeds", type=int, nargs="*", default=[],
                    help="more seeds of the MER drive, monovo only, after the main one [none]")
    ap.add_argument("--pairs", type=int, default=100, help="pairs per texture [100]")
    ap.add_argument("--speed-frames", type=int, default=200, help="frames of the 512² drive [200]")
    ap.add_argument("--renders", type=Path, default=RENDERS,
                    help=f"keep rendered frames here and reuse them [default: {RENDERS}]")
    ap.add_argument("--fresh", action="store_true",
                    help="render into a temporary folder (nothing kept or reused)")
    add_frame0_option(ap)


# --------------------------------------------------------------------------- renders


def synth_fingerprint() -> str:
    """10 hex digits of the SHA-1 of ``monovo_cli/synth/*.py``: a rendered folder is reused
    only while the renderer is the same."""
    import monovo_cli.synth

    h = hashlib.sha1()
    for p in sorted(Path(monovo_cli.synth.__file__).parent.glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:10]


@contextmanager
def renders_root(args) -> Iterator[Path]:
    """``--renders`` (created), or a temporary folder with ``--fresh``."""
    if args.fresh:
        with tempfile.TemporaryDirectory() as tmp:
            yield Path(tmp)
    else:
        args.renders.mkdir(parents=True, exist_ok=True)
        yield args.renders


def rendered(root: Path, key: str, render: Callable[[Path], object]) -> Path:
    """``root/KEY-FINGERPRINT``, written by ``render(folder)`` unless a complete one exists.

    Rendered into a temporary sibling first and renamed when complete, so an interrupted run
    leaves nothing that a later one would take for finished."""
    dest = root / f"{key}-{synth_fingerprint()}"
    if dest.is_dir():
        return dest
    work = root / f".{dest.name}.{os.getpid()}"
    shutil.rmtree(work, ignore_errors=True)
    t0 = time.perf_counter()
    render(work / "data")
    if dest.exists():  # another run finished it meanwhile
        shutil.rmtree(work)
    else:
        work.rename(dest)
    print(f"(rendered {dest.name} in {time.perf_counter() - t0:.0f} s)\n", flush=True)
    return dest


def verdict(ok: bool) -> str:
    return "**holds**" if ok else "**fails**"


def acceptance_table(rows: list[tuple[str, str, str, bool]]) -> str:
    """``(criterion, case, measured, holds)`` rows as markdown."""
    lines = ["| acceptance bound | case | measured | |", "| --- | --- | --- | --- |"]
    lines += [f"| {c} | {case} | {m} | {verdict(ok)} |" for c, case, m, ok in rows]
    return "\n".join(lines)


# --------------------------------------------------------------------------- mer


def motion_reasons(path: Path) -> list[tuple[str, str]]:
    """``(status, reason)`` of every row of a motion.csv (reason "" where the column is empty
    or absent)."""
    with open(path, newline="") as f:
        return [(r.get("status", "ok"), r.get("reason") or "") for r in csv.DictReader(f)]


def longest_run(flags) -> int:
    longest = run = 0
    for x in flags:
        run = run + 1 if x else 0
        longest = max(longest, run)
    return longest


def section_mer(seqs, args) -> None:
    n = args.mer_frames
    print(f"### MER-spacing drive: `synth --preset mer --frames {n} --seed {MER_SEED}` "
          f"(1024x1024, noise variance {NOISE_VAR:g})\n")
    with renders_root(args) as root, tempfile.TemporaryDirectory() as tmp:
        seq = rendered(root, f"mer_{n}_{MER_SEED}_{NOISE_VAR:g}", lambda d: synthesize(
            d, preset="mer", frames=n, noise_var=NOISE_VAR, seed=MER_SEED)) / "data"
        mono = monovo_on_drive(seq, Path(tmp) / "out", TrackOptions())
        rows = motion_reasons(Path(tmp) / "out" / "motion.csv")
        peers = [peer_on_drive(p, seq) for p in (OrbPeer(), EccPeer())]
    lost = [s == "lost" for s, _ in rows]
    reinit = sum(s == "reinit" for s, _ in rows)
    print("Every method end to end on the same PNGs (decoding included), one core; monovo "
          "with default options; the peers frame to frame, chained, carrying init.yaml's "
          "plane with their own motions (a failed frame repeats the previous motion).\n")
    head = ("| method | frames | distance (m) | final position error (m) | % of distance | final "
            "heading error (deg) | lost (peers: failed) | re-inits | longest lost run | "
            "frames/s wall (CPU) |")
    lines = [head, "|" + " --- |" * (head.count("|") - 1)]
    for r in [mono] + peers:
        err, dist, heading = r.drift
        is_mono = r is mono
        lines.append(
            f"| {r.name} | {r.count} | {dist:.2f} | {err:.3f} | {100 * err / dist:.2f} | "
            f"{heading:.2f} | {sum(lost) if is_mono else r.failed} | "
            f"{reinit if is_mono else '—'} | {longest_run(lost) if is_mono else '—'} | "
            f"{r.count / r.seconds:.1f} ({r.count / r.cpu:.1f}) |")
    print("\n".join(lines) + "\n")
    why = Counter(reason or "(none given)" for s, reason in rows if s in ("lost", "reinit"))
    print("monovo's reasons (lost and re-init frames): "
          + ("; ".join(f"{k} ({v})" for k, v in why.most_common()) or "—") + "\n")
    err, dist, _ = mono.drift
    pct = 100 * err / dist
    print(acceptance_table([
        (f"final position error ≤ {MER_MAX_PCT:g} % of the distance", f"MER drive, {n} frames",
         f"{pct:.2f} %", pct <= MER_MAX_PCT),
        ("0 lost frames", f"MER drive, {n} frames", f"{sum(lost)} lost, {reinit} re-init",
         sum(lost) == 0)]) + "\n")
    if args.mer_seeds:
        mer_other_seeds(args, n)


def mer_other_seeds(args, n: int) -> None:
    """The MER drive on other seeds (another terrain texture, bobbing and path), monovo only."""
    print(f"Other seeds of the MER drive ({n} frames), monovo with default options:\n")
    head = ("| seed | distance (m) | final position error (m) | % of distance | final heading "
            "error (deg) | lost | re-inits | frames/s wall (CPU) |")
    lines = [head, "|" + " --- |" * (head.count("|") - 1)]
    with renders_root(args) as root, tempfile.TemporaryDirectory() as tmp:
        for seed in args.mer_seeds:
            seq = rendered(root, f"mer_{n}_{seed}_{NOISE_VAR:g}", lambda d, s=seed: synthesize(
                d, preset="mer", frames=n, noise_var=NOISE_VAR, seed=s)) / "data"
            mono = monovo_on_drive(seq, Path(tmp) / f"out{seed}", TrackOptions())
            rows = motion_reasons(Path(tmp) / f"out{seed}" / "motion.csv")
            err, dist, heading = mono.drift
            lines.append(f"| {seed} | {dist:.2f} | {err:.3f} | {100 * err / dist:.2f} | "
                         f"{heading:.2f} | {sum(st == 'lost' for st, _ in rows)} | "
                         f"{sum(st == 'reinit' for st, _ in rows)} | "
                         f"{mono.count / mono.seconds:.1f} ({mono.count / mono.cpu:.1f}) |")
            print(lines[-1], flush=True)
    print("\n" + "\n".join(lines) + "\n")


# --------------------------------------------------------------------------- pairs


def rock_texture(n: int = ROCK_SIDE, seed: int = ROCK_SEED) -> np.ndarray:
    """A rock surface (n x n uint8), built here independently of ``monovo_cli.synth``.

    A rough height field (value noise: random grids every 2..n/4 texels, bicubically
    interpolated, amplitude ~ spacing^0.8) lit by a low sun from the right (Lambert), times
    a patchy albedo (coarse value noise) with bright and dark mineral grains (thresholded fine
    noise), darkened along cracks (the zero lines of a mid-scale noise). Mean ~120, std ~40.
    """
    rng = np.random.default_rng(seed)

    def value_noise(cell: int) -> np.ndarray:
        k = n // cell + 3
        grid = rng.standard_normal((k, k)).astype(np.float32)
        up = cv2.resize(grid, (k * cell, k * cell), interpolation=cv2.INTER_CUBIC)
        return up[cell: cell + n, cell: cell + n]

    def fbm(cells, power: float) -> np.ndarray:
        out = np.zeros((n, n), np.float32)
        for c in cells:
            out += np.float32(c ** power) * value_noise(c)
        return out / np.float32(out.std())

    spacings = [2 ** j for j in range(1, int(math.log2(n // 4)) + 1)]
    height = 6.0 * fbm(spacings, 0.8)
    gy, gx = np.gradient(height)
    light = np.array([0.8, -0.2, 0.55]) / np.linalg.norm([0.8, -0.2, 0.55])
    shade = np.maximum((-light[0] * gx - light[1] * gy + light[2]) / np.sqrt(1 + gx * gx + gy * gy),
                       0.0)
    albedo = 1.0 + 0.25 * fbm([64, 128, 256], 1.0)
    grains = value_noise(2)
    albedo += 0.35 * (grains > 1.6) - 0.3 * (grains < -1.8)
    crack = np.exp(-((value_noise(96) + 0.3 * value_noise(24)) / 0.06) ** 2)
    img = (0.25 + shade) * albedo * (1.0 - 0.6 * crack)
    img = (img - img.mean()) * (40.0 / img.std()) + 120.0
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def rock_png(root: Path) -> Path:
    path = root / f"rock_{ROCK_SIDE}_{ROCK_SEED}.png"
    if not path.exists():
        tmp = path.with_name(f".{path.name}.{os.getpid()}.png")
        cv2.imwrite(str(tmp), rock_texture())
        tmp.rename(path)
    return path


def crb_stds(pairs: Path, var: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-pair Cramér-Rao std bounds (n, 6) (m, deg) of a pairs folder at noise variance
    ``var`` (second image only), and the share of frame 1 seen by frame 0 (n,). The
    information matrices (``benchmarks.crb.information``) are cached in the folder."""
    cache = pairs / "crb_information.npz"
    if not cache.exists():
        cam, tex, scenes = pair_scenes(pairs)
        renderer = pair_renderer(pairs, cam, tex)
        infos = [information(cam, tex, sc, renderer) for sc in scenes]
        tmp = pairs / f".crb.{os.getpid()}.npz"
        np.savez(tmp, seen=np.array([i for i, _, _ in infos]),
                 share=np.array([s for _, _, s in infos]))
        tmp.rename(cache)
    data = np.load(cache)
    return np.array([bound_std(i, var) for i in data["seen"]]), data["share"]


def pair_row(texture: str, name: str, errs: np.ndarray, conv: np.ndarray, stds: np.ndarray,
             ms: tuple[float, float]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """One table row, and the mean-abs and RMS ratios to the bound (6,) over ``conv``."""
    e = errs[conv] if conv.any() else np.full((1, 6), np.nan)  # none converged: "—"
    mae, rms = np.mean(np.abs(e), axis=0), np.sqrt(np.mean(e ** 2, axis=0))
    bound_rms, bound_mae = bound_levels(stds[conv] if conv.any() else stds)
    r_mae, r_rms = mae / bound_mae, rms / bound_rms

    def trio(v, fmt):
        return " / ".join(fmt.format(x) if np.isfinite(x) else "—" for x in v)

    row = [texture, name, f"{conv.sum()}/{len(conv)} ({100 * conv.mean():.1f} %)",
           trio(mae[:3], "{:.5f}"), trio(mae[3:], "{:.5f}"), trio(r_mae, "{:.2f}"),
           trio(r_rms, "{:.2f}"), f"{ms[0]:.1f} ({ms[1]:.1f})"]
    return row, r_mae, r_rms


def within(errs: np.ndarray) -> np.ndarray:
    """(n,) bool: an estimate below CONVERGED_M / CONVERGED_DEG on every axis."""
    e = np.abs(np.nan_to_num(errs, nan=np.inf))
    return (e[:, :3].max(axis=1) < CONVERGED_M) & (e[:, 3:].max(axis=1) < CONVERGED_DEG)


def section_pairs(seqs, args) -> None:
    n, clean = args.pairs, not args.noisy_frame0
    print(f"### Paper pairs on three textures: `synth --preset pairs --frames {n} --seed "
          f"{PAIR_SEED}` (688x544, ±5°, ±10 m, noise variance {NOISE_VAR:g} on "
          f"{'frame 1, frame 0 noise-free' if clean else 'both frames'})\n")
    var = NOISE_VAR + QUANTISATION_VAR
    both = 1.0 if clean else math.sqrt(2.0)  # the bound of benchmarks.crb for that noise
    rows, bounds, accept = [], [], []
    with renders_root(args) as root:
        rock = rock_png(root)
        t0 = time.perf_counter()
        for label, texture in (("procedural", None), ("gravel", "gravel"), ("rock (image file)", rock)):
            tag = label.split()[0]
            if texture == rock:
                tag += "-" + hashlib.sha1(rock.read_bytes()).hexdigest()[:8]
            key = f"pairs_{tag}_{n}_{PAIR_SEED}_{NOISE_VAR:g}_{'clean0' if clean else 'noisy0'}"
            pairs_dir = rendered(root, key, lambda d, t=texture: synthesize(
                d, preset="pairs", frames=n, noise_var=NOISE_VAR, seed=PAIR_SEED,
                texture=t, clean_frame0=clean)) / "data"
            pairs = sorted(p for p in pairs_dir.iterdir() if p.name.startswith("pair_"))
            errs, results, secs, cpu = track_pairs(pairs_dir, TrackOptions())
            stds, seen = crb_stds(pairs_dir, var)
            stds = stds * both
            conv = within(errs) & np.array([r.status != "lost" for r in results])
            row, r_mae, r_rms = pair_row(label, "monovo", errs, conv, stds,
                                         (1000 * secs.mean(), 1000 * cpu.mean()))
            rows.append(row)
            accept.append((label, conv, r_mae, r_rms))
            for peer in (OrbPeer(), EccPeer()):
                cv2.setRNGSeed(0)  # RANSAC draws
                res = peer_on_pairs(peer, pairs)
                rows.append(pair_row(label, res.name, res.errors, within(res.errors), stds,
                                     (1000 * res.seconds / res.count, 1000 * res.cpu / res.count))[0])
            b_rms, _ = bound_levels(stds)
            bounds.append([label, " / ".join(f"{x:.2e}" for x in b_rms[:3]),
                           " / ".join(f"{x:.2e}" for x in b_rms[3:]),
                           f"{100 * seen.mean():.1f} %",
                           str(sum(r.status == "lost" for r in results))])
            print(f"({label} done, {time.perf_counter() - t0:.0f} s so far, {load()})", flush=True)
    print(f"\nConverged: monovo does not call frame 1 lost and the error is below "
          f"{CONVERGED_M:g} m / {CONVERGED_DEG:g}° on every axis (a peer: it gives an "
          "estimate within those bounds). Errors and ratios over each method's converged "
          "pairs; ratio to the Cramér–Rao bound of `benchmarks.crb` over the same pairs "
          f"({'second image only' if clean else 'both images noisy'}): mean |error| / "
          "(√(2/π) mean σ_CRB), RMS / √(mean σ²_CRB); 1 = the bound is attained. Time: frames "
          "in memory, tracking incl. the frame-0 model (monovo), features + RANSAC (ORB), "
          "pyramids + alignment (ECC), one core.\n")
    head = ("| texture | method | converged | mean abs error tx / ty / tz (m) | rx / ry / rz (deg) "
            "| mean abs / CRB tx / ty / tz / rx / ry / rz | RMS / CRB tx / ty / tz / rx / ry / rz "
            "| ms/pair wall (CPU) |")
    print("\n".join([head, "|" + " --- |" * 8] + ["| " + " | ".join(r) + " |" for r in rows]))
    print("\nThe bound per texture (σ_CRB, RMS over the pairs; frame-1 pixels that frame 0 "
          "saw), and monovo's lost pairs:\n")
    print("\n".join(["| texture | σ_CRB tx / ty / tz (m) | σ_CRB rx / ry / rz (deg) | frame 1 "
                     "seen by frame 0 | monovo: frame 1 lost |", "|" + " --- |" * 5]
                    + ["| " + " | ".join(b) + " |" for b in bounds]) + "\n")
    checks = []
    for label, conv, r_mae, r_rms in accept:
        share = 100 * conv.mean()
        checks.append((f"≥ {PAIRS_MIN_SHARE:g} % converge", label,
                       f"{conv.sum()}/{len(conv)} ({share:.1f} %)", share >= PAIRS_MIN_SHARE))
        worst = max(float(r_mae.max()), float(r_rms.max()))
        axis = AXES[int(np.argmax(np.maximum(r_mae, r_rms)))].split()[0]
        checks.append((f"error ≤ {PAIRS_MAX_CRB:g}x the Cramér–Rao bound, every axis (mean "
                       "abs and RMS)", label, f"worst {worst:.2f}x ({axis}); mean abs "
                       f"{r_mae.min():.2f}–{r_mae.max():.2f}x, RMS {r_rms.min():.2f}–"
                       f"{r_rms.max():.2f}x", worst <= PAIRS_MAX_CRB))
    print(acceptance_table(checks) + "\n")


# --------------------------------------------------------------------------- speed


def section_speed(seqs, args) -> None:
    from benchmarks.speed import SPEED_HEAD, measure, speed_row

    n = args.speed_frames
    print(f"### Small-motion speed: `benchmarks.speed` on its 512x512 drive (`synth --preset "
          f"drive --frames {n} --seed {SPEED_SEED}`, noise variance {NOISE_VAR:g}); wall "
          "clock, CPU time of this process in brackets\n")
    with renders_root(args) as root, tempfile.TemporaryDirectory() as tmp:
        seq = rendered(root, f"drive_512_{n}_{SPEED_SEED}_{NOISE_VAR:g}", lambda d: synthesize(
            d, preset="drive", frames=n, size=(512, 512), noise_var=NOISE_VAR,
            seed=SPEED_SEED)) / "data"
        e2e, est, ecc = measure(seq, Path(tmp) / "out")
    print(SPEED_HEAD)
    print("|" + " --- |" * 11)
    print(speed_row("512x512", e2e, est, ecc, target=SPEED_MIN_FPS) + "\n")
    need = SPEED_MIN_FPS / ECC_REFERENCE_FPS
    print(acceptance_table([
        (f"≥ {SPEED_MIN_FPS:g} frames/s end to end at 512² (wall; CPU)", f"{n}-frame drive",
         f"{e2e['fps']:.1f} ({e2e['fps_cpu']:.1f})", e2e["fps"] >= SPEED_MIN_FPS),
        (f"the same against ECC in this run: monovo / ECC ≥ {SPEED_MIN_FPS:g} / "
         f"{ECC_REFERENCE_FPS:g} = {need:.2f} (ECC's frames/s on the idle machine), CPU time "
         "(wall)", f"{n}-frame drive", f"{e2e['fps_cpu'] / ecc[1]:.2f} "
         f"({e2e['fps'] / ecc[0]:.2f}), i.e. ~{ECC_REFERENCE_FPS * e2e['fps_cpu'] / ecc[1]:.0f} "
         "frames/s on the idle machine", e2e["fps_cpu"] / ecc[1] >= need),
        ("0 lost frames", f"{n}-frame drive", str(e2e["lost"]), e2e["lost"] == 0)]) + "\n")
    print(f"({load()} at the end of the section.)\n")


SECTIONS = {"mer": section_mer, "pairs": section_pairs, "speed": section_speed}
