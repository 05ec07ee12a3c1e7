"""Error tables of an estimated trajectory against ground truth (``monovo eval``).

Both trajectories are ``world_from_cam`` poses (N, 4, 4) with timestamps (N,) s. Each
estimated pose is matched to the ground-truth pose nearest in time, within ``max_dt``
(default :func:`default_max_dt`: 0.02 s, or half the estimate's median frame interval if
that is less), each true pose to at most one estimated pose; the measures are taken over the
matched poses, so an estimate covering only part of the ground truth (or a ground truth
sampled faster than the frames) is evaluated over the overlap, and the report says how many
poses matched. The measures:

* **relative motion errors, per axis** -- for every pair of consecutive matched frames the
  relative motion ``T_{k-1}_k = inv(T_0_{k-1}) T_0_k`` of both trajectories is compared
  parameter by parameter: translation components (m) and rotation-vector components (deg),
  ``|t_est - t_gt|`` and ``|r_est - r_gt|``, the way the paper's Tables 10.1 and 10.2 give
  the mean and standard deviation of the absolute estimation error per axis. The rotation
  error per axis is the difference of the two rotation vectors (not the rotation vector of
  the difference rotation; both agree to first order for small motions).
* **ATE** -- the RMSE of the position differences ``|p_est - p_gt|`` (m), without alignment
  and, on request, after the least-squares alignment of the estimated positions onto the
  true ones (Umeyama 1991, eqs. 34-42): rigid (``"se3"``, c = 1), as ``evo_ape tum GT EST
  [--align]`` computes it, or a similarity (``"sim3"``, with the scale c of eq. 42, as
  ``evo_ape --align --correct_scale``) for a run that is only up to scale (``distance: 1.0``
  in init.yaml). With ``"sim3"`` every other measure is also taken on the estimate with its
  translations multiplied by c.
* **final drift** -- the end-point error of the estimated trajectory relative to its first
  pose against the same for the truth, ``|t(inv(E_0) E_n) - t(inv(G_0) G_n)|``, in m and as
  % of the true path length; **rotation drift** -- the angle of the final relative-rotation
  error (deg) per metre of true path.

Pure: arrays in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import se3_inv, so3_log

MAX_DT = 0.02  # s, the default matching tolerance (less for frames closer than 0.04 s)
ALIGNMENTS = ("none", "se3", "sim3")
AXES = ("tx", "ty", "tz", "rx", "ry", "rz")


@dataclass(frozen=True)
class Evaluation:
    """The error measures of one trajectory (module docstring).

    ``poses`` matched of ``estimate_poses`` and ``groundtruth_poses``, within ``max_dt`` s;
    ``relative_mean`` / ``relative_std`` (6,): mean and standard deviation of the absolute
    per-axis relative-motion errors, (tx, ty, tz) m and (rx, ry, rz) deg; ``ate_rmse`` m
    without alignment; ``ate_rmse_aligned`` m after the alignment ``align`` ("se3" or
    "sim3"; None for "none") with ``alignment`` its 4x4 ``gt_from_est`` (``c R | t``) and
    ``scale`` c (1 unless "sim3"); ``final_drift_m``, ``final_drift_pct`` of ``distance_m``
    (the true path length, m), ``final_rotation_deg``, ``rotation_drift_deg_per_m``;
    ``start_offset_m`` the distance between the first matched positions.
    """

    poses: int
    relative_mean: np.ndarray
    relative_std: np.ndarray
    ate_rmse: float
    ate_max: float
    ate_rmse_aligned: float | None
    alignment: np.ndarray | None
    distance_m: float
    final_drift_m: float
    final_drift_pct: float
    final_rotation_deg: float
    rotation_drift_deg_per_m: float
    estimate_poses: int = 0
    groundtruth_poses: int = 0
    max_dt: float = MAX_DT
    align: str = "none"
    scale: float = 1.0
    start_offset_m: float = 0.0

    def as_dict(self) -> dict:
        """Plain numbers for JSON: per-axis means/stds keyed by axis name, units in the keys."""
        def num(x: float | None) -> float | None:
            return None if x is None or not math.isfinite(x) else float(x)

        rel = {}
        for i, a in enumerate(AXES):
            unit = "m" if i < 3 else "deg"
            rel[a] = {f"mean_{unit}": float(self.relative_mean[i]),
                      f"std_{unit}": float(self.relative_std[i])}
        return {
            "poses": self.poses,
            "estimate_poses": self.estimate_poses,
            "groundtruth_poses": self.groundtruth_poses,
            "max_dt_s": float(self.max_dt),
            "alignment": None if self.align == "none" else self.align,
            "scale": float(self.scale),
            "relative_motions": max(self.poses - 1, 0),
            "relative_errors": rel,
            "translation_average": {"mean_m": float(self.relative_mean[:3].mean()),
                                    "std_m": float(self.relative_std[:3].mean())},
            "rotation_average": {"mean_deg": float(self.relative_mean[3:].mean()),
                                 "std_deg": float(self.relative_std[3:].mean())},
            "ate_rmse_m": float(self.ate_rmse),
            "ate_max_m": float(self.ate_max),
            "ate_rmse_aligned_m": num(self.ate_rmse_aligned),
            "distance_m": float(self.distance_m),
            "final_drift_m": float(self.final_drift_m),
            "final_drift_pct": num(self.final_drift_pct),
            "final_rotation_error_deg": float(self.final_rotation_deg),
            "rotation_drift_deg_per_m": num(self.rotation_drift_deg_per_m),
        }


def default_max_dt(ts_est: np.ndarray) -> float:
    """The default matching tolerance (s): ``MAX_DT``, or half the median interval of the
    estimate's timestamps ``ts_est`` (N,) s if that is less, so that no two frames can
    match one true pose."""
    ts = np.sort(np.asarray(ts_est, dtype=float))
    if len(ts) < 2:
        return MAX_DT
    return float(min(MAX_DT, 0.5 * np.median(np.diff(ts))))


def _span(ts: np.ndarray) -> str:
    return f"{float(ts.min())!r}..{float(ts.max())!r} s"


def match_timestamps(ts_est: np.ndarray, ts_gt: np.ndarray, *, max_dt: float | None = None,
                     names: tuple[str, str] = ("estimate", "ground truth"),
                     hint: str = "--max-dt sets the tolerance"
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``(i_est, i_gt)`` pairing each estimated pose with the true pose nearest
    in time, within ``max_dt`` s (None: :func:`default_max_dt`), in the estimate's time order.

    Poses with no partner within ``max_dt`` are left out (a partial run); a true pose nearest
    to two estimated ones goes to the closer. InputError if either holds a timestamp twice
    or no pose matches (the message ends with ``hint``).
    """
    ts_est, ts_gt = np.asarray(ts_est, dtype=float), np.asarray(ts_gt, dtype=float)
    for ts, name in ((ts_est, names[0]), (ts_gt, names[1])):
        if len(ts) == 0:
            raise InputError(f"{name}: no poses")
    for ts, name in ((ts_est, names[0]), (ts_gt, names[1])):
        s = np.sort(ts)
        dup = np.nonzero(np.diff(s) <= 1e-9)[0]
        if len(dup):
            raise InputError(f"{name}: timestamp {float(s[dup[0]])!r} is given more than once")
    tol = default_max_dt(ts_est) if max_dt is None else float(max_dt)
    oe, og = np.argsort(ts_est, kind="stable"), np.argsort(ts_gt, kind="stable")
    se, sg = ts_est[oe], ts_gt[og]
    j = np.clip(np.searchsorted(sg, se), 1, max(len(sg) - 1, 1))
    cand = np.stack([j - 1, np.minimum(j, len(sg) - 1)], 1)
    near = cand[np.arange(len(se)), np.argmin(np.abs(sg[cand] - se[:, None]), axis=1)]
    dt = np.abs(sg[near] - se)
    taken = np.zeros(len(sg), bool)
    keep = np.zeros(len(se), bool)
    for i in np.argsort(dt, kind="stable"):  # the closest pairs first
        if dt[i] > tol:
            break
        if not taken[near[i]]:
            taken[near[i]] = keep[i] = True
    if not keep.any():
        raise InputError(f"none of the {len(se)} timestamps of {names[0]} ({_span(se)}) is "
                         f"within {tol:g} s of one of {names[1]} ({_span(sg)}); is it the "
                         f"ground truth of this sequence? ({hint})")
    return oe[keep], og[near[keep]]


def path_length(world_from_cam: np.ndarray) -> float:
    """The length (m) of the camera path through poses (N, 4, 4): the sum of the steps."""
    return float(np.linalg.norm(np.diff(world_from_cam[:, :3, 3], axis=0), axis=1).sum())


def relative_motion_errors(est_world_from_cam: np.ndarray,
                           gt_world_from_cam: np.ndarray) -> np.ndarray:
    """Signed per-axis errors (N-1, 6) of consecutive relative motions: translation (m) and
    rotation-vector components (deg), ``est - gt``."""
    est, gt = np.asarray(est_world_from_cam), np.asarray(gt_world_from_cam)
    out = np.zeros((max(len(est) - 1, 0), 6))
    for k in range(1, len(est)):
        e = se3_inv(est[k - 1]) @ est[k]
        g = se3_inv(gt[k - 1]) @ gt[k]
        out[k - 1, :3] = e[:3, 3] - g[:3, 3]
        out[k - 1, 3:] = np.degrees(so3_log(e[:3, :3]) - so3_log(g[:3, :3]))
    return out


def umeyama(src: np.ndarray, dst: np.ndarray, *, with_scale: bool) -> tuple[np.ndarray, float]:
    """The similarity ``dst_from_src`` (4, 4), ``[c R | t]``, minimising
    ``sum |dst_i - (c R src_i + t)|^2`` for points ``src``, ``dst`` (N, 3) (Umeyama 1991),
    and its scale c (1 unless ``with_scale``). InputError if ``src`` has no extent (all
    points equal) when a scale is asked for."""
    src, dst = np.asarray(src, dtype=float), np.asarray(dst, dtype=float)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    cov = (dst - mu_d).T @ (src - mu_s) / len(src)          # eq. 38
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:           # eq. 39: no reflection
        S[2, 2] = -1.0
    R = U @ S @ Vt                                          # eq. 40
    c = 1.0
    if with_scale:
        var_s = float(np.mean(np.sum((src - mu_s) ** 2, axis=1)))   # eq. 36
        if var_s <= 1e-24:
            raise InputError("the estimate does not move: no scale can be fitted (sim3)")
        c = float(np.trace(np.diag(D) @ S)) / var_s         # eq. 42
    T = np.eye(4)
    T[:3, :3] = c * R
    T[:3, 3] = mu_d - c * R @ mu_s                          # eq. 41
    return T, c


def umeyama_se3(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The rigid transform ``dst_from_src`` (4, 4) minimising ``sum |dst_i - (R src_i + t)|^2``
    for points ``src``, ``dst`` (N, 3) (Umeyama 1991 without scale)."""
    return umeyama(src, dst, with_scale=False)[0]


def _alignment(align: bool | str) -> str:
    if align is True:
        return "se3"
    if align is False or align is None:
        return "none"
    if align not in ALIGNMENTS:
        raise ValueError(f"align: expected one of {', '.join(ALIGNMENTS)}, got {align!r}")
    return align


def ate(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray, *,
        align: bool | str = False) -> tuple[np.ndarray, np.ndarray]:
    """Position errors (N,) m and the alignment ``gt_from_est`` (4, 4) (identity for
    ``align`` "none" / False; "se3" / True rigid; "sim3" with scale) of matched poses
    (N, 4, 4)."""
    align = _alignment(align)
    pe = np.asarray(est_world_from_cam)[:, :3, 3]
    pg = np.asarray(gt_world_from_cam)[:, :3, 3]
    T = np.eye(4) if align == "none" else umeyama(pe, pg, with_scale=align == "sim3")[0]
    pa = pe @ T[:3, :3].T + T[:3, 3]
    return np.linalg.norm(pa - pg, axis=1), T


def evaluate(ts_est: np.ndarray, est_world_from_cam: np.ndarray, ts_gt: np.ndarray,
             gt_world_from_cam: np.ndarray, *, align: bool | str = False,
             max_dt: float | None = None,
             names: tuple[str, str] = ("estimate", "ground truth")) -> Evaluation:
    """All error measures of the estimate against the ground truth (module docstring).

    ``ts_*`` (N,) s and ``*_world_from_cam`` (N, 4, 4); ``align`` "none", "se3" or "sim3"
    (True: "se3"); ``max_dt`` the matching tolerance, s (None: :func:`default_max_dt`);
    ``names`` name the two in errors. InputError when fewer than 2 poses match.
    """
    align = _alignment(align)
    est, gt = np.asarray(est_world_from_cam, dtype=float), np.asarray(gt_world_from_cam, dtype=float)
    for a, t, name in ((est, ts_est, names[0]), (gt, ts_gt, names[1])):
        if a.ndim != 3 or a.shape[1:] != (4, 4) or len(a) != len(t):
            raise InputError(f"{name}: expected (N, 4, 4) poses with N timestamps, got {a.shape} "
                             f"and {len(t)}")
    tol = default_max_dt(ts_est) if max_dt is None else float(max_dt)
    ie, ig = match_timestamps(ts_est, ts_gt, max_dt=tol, names=names)
    if len(ie) < 2:
        raise InputError(f"{names[0]}: only {len(ie)} pose(s) match the {names[1]} within "
                         f"{tol:g} s; evaluation needs at least 2")
    n_est, n_gt = len(est), len(gt)
    est, gt = est[ie], gt[ig]
    err, _ = ate(est, gt)
    start_offset = float(err[0])
    err_al, T_al = ate(est, gt, align=align) if align != "none" else (None, None)
    scale = 1.0
    if align == "sim3":  # the other measures on the estimate brought to the truth's scale
        scale = float(np.cbrt(np.linalg.det(T_al[:3, :3])))
        est = est.copy()
        est[:, :3, 3] *= scale
    rel = np.abs(relative_motion_errors(est, gt))
    e_end = se3_inv(est[0]) @ est[-1]
    g_end = se3_inv(gt[0]) @ gt[-1]
    drift = float(np.linalg.norm(e_end[:3, 3] - g_end[:3, 3]))
    rot = float(np.degrees(np.linalg.norm(so3_log(g_end[:3, :3].T @ e_end[:3, :3]))))
    dist = path_length(gt)
    return Evaluation(
        poses=len(ie),
        relative_mean=rel.mean(axis=0),
        relative_std=rel.std(axis=0),
        ate_rmse=float(np.sqrt(np.mean(err ** 2))),
        ate_max=float(err.max()),
        ate_rmse_aligned=None if err_al is None else float(np.sqrt(np.mean(err_al ** 2))),
        alignment=T_al,
        distance_m=dist,
        final_drift_m=drift,
        final_drift_pct=100.0 * drift / dist if dist > 0 else float("nan"),
        final_rotation_deg=rot,
        rotation_drift_deg_per_m=rot / dist if dist > 0 else float("nan"),
        estimate_poses=n_est,
        groundtruth_poses=n_gt,
        max_dt=tol,
        align=align,
        scale=scale,
        start_offset_m=start_offset,
    )


def format_report(ev: Evaluation) -> str:
    """The paper-style tables (Tables 10.1 / 10.2) and the trajectory measures as text."""
    def g(x: float) -> str:
        return f"{x:.5f}" if abs(x) >= 1e-5 or x == 0 else f"{x:.3e}"

    lines = [f"{ev.poses} poses matched within {ev.max_dt:g} s (of {ev.estimate_poses} "
             f"estimated, {ev.groundtruth_poses} true), {max(ev.poses - 1, 0)} relative "
             f"motions, true path length {ev.distance_m:.3f} m"]
    if ev.poses < max(ev.estimate_poses, ev.groundtruth_poses):
        lines.append("  (a partial match: the measures cover the matched poses only)")
    if ev.align == "sim3":
        lines.append(f"  estimate scaled by {ev.scale:.6g} (sim3 alignment) for every measure "
                     "but the unaligned ATE")
    lines.append("")
    for title, unit, axes, first in (("translation (Table 10.1)", "m", "TxTyTz", 0),
                                     ("rotation (Table 10.2)", "deg", "wxwywz", 3)):
        part = slice(first, first + 3)
        lines += [f"Absolute relative-motion error, {title}",
                  f"  {'axis':<10}{f'mean ({unit})':>14}{f'std ({unit})':>14}"]
        for i in range(3):
            a = f"|E_{axes[2 * i:2 * i + 2]}|"
            lines.append(f"  {a:<10}{g(ev.relative_mean[first + i]):>14}"
                         f"{g(ev.relative_std[first + i]):>14}")
        lines += [f"  {'average':<10}{g(ev.relative_mean[part].mean()):>14}"
                  f"{g(ev.relative_std[part].mean()):>14}", ""]
    lines += ["Trajectory",
              f"  ATE RMSE, no alignment      {ev.ate_rmse:.6f} m (max {ev.ate_max:.6f} m)"]
    if ev.ate_rmse_aligned is not None:
        what = "SE(3) aligned" if ev.align == "se3" else "Sim(3) aligned"
        lines.append(f"  ATE RMSE, {what:<18}{ev.ate_rmse_aligned:.6f} m")
    elif ev.start_offset_m > 1e-6:
        lines.append(f"  (the trajectories start {ev.start_offset_m:.3g} m apart: another "
                     "world frame? --align compares their shapes)")
    pct = f"{ev.final_drift_pct:.3f} %" if math.isfinite(ev.final_drift_pct) else "n/a"
    rate = (f"{ev.rotation_drift_deg_per_m:.4f} deg/m"
            if math.isfinite(ev.rotation_drift_deg_per_m) else "n/a")
    lines += [f"  final drift                 {ev.final_drift_m:.6f} m = {pct} of the path",
              f"  final rotation error        {ev.final_rotation_deg:.4f} deg = {rate}"]
    return "\n".join(lines)
