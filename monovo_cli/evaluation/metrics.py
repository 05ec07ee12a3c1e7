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
from monovo_cli.evaluation.sync import MAX_DT, default_max_dt, match_timestamps
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.geometry.trajectory import path_length

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
    return evaluate_matched(est[ie], gt[ig], align=align, max_dt=tol,
                            estimate_poses=len(est), groundtruth_poses=len(gt))


def evaluate_matched(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray, *,
                     align: bool | str = False, max_dt: float = MAX_DT,
                     estimate_poses: int | None = None,
                     groundtruth_poses: int | None = None) -> Evaluation:
    """The error measures of :func:`evaluate` over poses already paired: ``est`` and ``gt``
    (N, 4, 4), pose i with pose i, N >= 2; ``max_dt`` (s) and the pose counts of the two
    trajectories before matching (default N) are recorded in the result."""
    align = _alignment(align)
    est = np.array(est_world_from_cam, dtype=float)
    gt = np.asarray(gt_world_from_cam, dtype=float)
    n_est = len(est) if estimate_poses is None else estimate_poses
    n_gt = len(gt) if groundtruth_poses is None else groundtruth_poses
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
        poses=len(est),
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
        max_dt=max_dt,
        align=align,
        scale=scale,
        start_offset_m=start_offset,
    )


STATS = ("rmse", "mean", "median", "std", "min", "max")


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """RMSE, mean, median, standard deviation, minimum and maximum of ``errors`` (N,), in
    their unit, as evo's ``Result.stats`` gives them (:data:`STATS`; NaN for none)."""
    e = np.asarray(errors, dtype=float)
    if e.size == 0:
        return {k: float("nan") for k in STATS}
    return {"rmse": float(np.sqrt(np.mean(e ** 2))), "mean": float(e.mean()),
            "median": float(np.median(e)), "std": float(e.std()), "min": float(e.min()),
            "max": float(e.max())}


def relative_pose_errors(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray, *,
                         delta: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The relative pose error over ``delta`` poses (evo_rpe's, its "full" relation): for each
    i, ``inv(inv(G_i) G_{i+delta}) inv(P_i) P_{i+delta}`` of the matched estimated poses P
    and true poses G (N, 4, 4); returns its translation norms (N-delta,) m and rotation
    angles (N-delta,) deg."""
    est, gt = np.asarray(est_world_from_cam), np.asarray(gt_world_from_cam)
    n = max(len(est) - delta, 0)
    t, r = np.zeros(n), np.zeros(n)
    for i in range(n):
        E = se3_inv(se3_inv(gt[i]) @ gt[i + delta]) @ (se3_inv(est[i]) @ est[i + delta])
        t[i] = np.linalg.norm(E[:3, 3])
        r[i] = np.degrees(np.linalg.norm(so3_log(E[:3, :3])))
    return t, r
