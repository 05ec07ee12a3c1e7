"""report.html of a ``monovo track`` run and batch's index.html, from the run in memory.

:func:`write_report` puts one run on one self-contained page (:mod:`monovo_cli.io.report_html`):
the trajectory from above, the timeline of every frame (:mod:`monovo_cli.viz.timeline`) with
the reasons of the frames not ``ok``, the height map when the terrain was kept, keyframe
thumbnails with the ground region and the glued triangle (:mod:`monovo_cli.viz.thumbnails`),
the errors against the ground truth when one was given (:func:`evaluation_section`) and
run.yaml's options and inputs. :func:`write_index` links every sequence's report of a batch,
the failed ones first.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from monovo_cli.core.run import TrackRun
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import MonovoError
from monovo_cli.io.config import InitConfig
from monovo_cli.io.report_html import Markup, esc, img_tag, link, page, table, write_page

REPORT_FILE = "report.html"
INDEX_FILE = "index.html"
THUMBNAILS = 16          # keyframe thumbnails kept at most (Tracking's ``thumbnails``)
THUMBNAIL_SIDE = 200     # px, their longer side


def write_report(out_dir: Path, run: TrackRun, config: InitConfig, record: Mapping[str, Any], *,
                 title: str, trajectory_image: np.ndarray | bytes,
                 heightmap_image: np.ndarray | bytes | None = None,
                 thumbnails: Mapping[int, np.ndarray] | None = None,
                 groundtruth: Path | None = None) -> Path:
    """Write ``out_dir/report.html`` of ``run`` atomically; returns its path.

    ``config`` the run's init.yaml; ``record`` run.yaml's dict
    (:func:`~monovo_cli.io.run_record.run_record`); ``title`` the sequence's name;
    ``trajectory_image`` / ``heightmap_image`` the figures of trajectory.png / heightmap.png,
    BGR uint8 or the PNG files' bytes (None: no height map); ``thumbnails`` frame index -> grey uint8 keyframe
    image scaled down (:class:`~monovo_cli.pipeline.tracking.Tracking`'s ``thumbnails``);
    ``groundtruth`` a TUM file the run is evaluated against.
    """
    from monovo_cli.viz.thumbnails import keyframe_thumbnails
    from monovo_cli.viz.timeline import plot_timeline

    body = [f"<h1>{esc(title)}</h1>", f"<p>{esc(run_summary(run))}</p>"]
    figures = ["<section id=trajectory><h2>Trajectory from above</h2>",
               img_tag(trajectory_image, "the trajectory seen from above", width=520),
               "</section>"]
    if heightmap_image is not None:
        figures += ["<section id=heightmap><h2>Height map</h2>",
                    img_tag(heightmap_image, "the height map of the driven strip", width=520),
                    "</section>"]
    body += ['<div class="pair">', *figures, "</div>"]
    body += ["<section id=timeline><h2>Timeline</h2>",
             img_tag(plot_timeline(run.index, run.status, run.msd, run.points, run.std),
                     "status, msd, points and reported std per frame"),
             events_table(run), "</section>"]
    body.append("<section id=keyframes><h2>Keyframes</h2>")
    if thumbnails:
        drawn = keyframe_thumbnails(thumbnails, config.camera, config.plane, config.region,
                                    run.index, run.trajectory, run.status)
        status = dict(zip((int(k) for k in run.index), run.status))
        body.append(f'<p class="note">{len(run.keyframes)} keyframe(s), {len(drawn)} shown: the '
                    "ground region (cyan) and the glued triangle as the poses carried it "
                    "to the keyframe, before it is placed again there.</p>")
        body += [f"<figure>{img_tag(img, f'keyframe {k}')}<figcaption>frame {k} "
                 f"({esc(status.get(k, ''))})</figcaption></figure>" for k, img in drawn.items()]
    else:
        body.append('<p class="note">no keyframe images were kept</p>')
    body.append("</section>")
    if groundtruth is not None:
        body += ["<section id=evaluation><h2>Against the ground truth</h2>",
                 evaluation_section(run, Path(groundtruth)), "</section>"]
    body += ["<section id=run><h2>Options and inputs (run.yaml)</h2>", record_tables(record),
             "</section>"]
    path = Path(out_dir) / REPORT_FILE
    write_page(path, page(f"monovo: {title}", body))
    return path


def run_summary(run: TrackRun) -> str:
    """One line of the run's figures; the mean msd is over the frames fitted on some
    observation point (an unreadable frame's msd 0 in motion.csv is no measurement)."""
    fitted = np.asarray(run.points[1:]) > 0
    msd = np.asarray(run.msd[1:], dtype=float)[fitted]
    mean = f"{float(msd.mean()):.2f}" if len(msd) else "n/a"
    unfitted = "" if fitted.all() else f" of the {int(fitted.sum())} frames fitted"
    return (f"{run.frames} frames in {run.seconds:.1f} s; {run.count(FrameStatus.OK)} ok, "
            f"{run.reanchored} re-anchored, {run.reinit} re-initialised, {run.lost} lost; "
            f"mean msd {mean}{unfitted}; path length {run.path_length:.3f} m")


def events_table(run: TrackRun) -> str:
    """The frames that are not ``ok`` or ``reanchored``, consecutive ones of one status and
    reason on one row."""
    rows: list[list[str]] = []
    last: tuple[str, str] | None = None
    for k, st, why in zip(run.index[1:], run.status[1:], run.reason[1:]):
        if st in (FrameStatus.OK, FrameStatus.REANCHORED):
            last = None
            continue
        if last == (st, why) and rows:
            rows[-1][0] = f"{rows[-1][0].split('-')[0]}-{int(k)}"
        else:
            rows.append([f"{int(k)}", str(st), why])
        last = (st, why)
    if not rows:
        return '<p class="note">no frame was lost or re-initialised</p>'
    return table(("frames", "status", "reason"), rows,
                 row_classes=["lost" if r[1] == FrameStatus.LOST else "" for r in rows])


def evaluation_section(run: TrackRun, groundtruth: Path) -> str:
    """The run's trajectory against the ground truth file ``groundtruth`` as ``monovo eval
    --align se3`` measures it (:func:`~monovo_cli.pipeline.evaluate.evaluate_run`): a line
    of how the poses were paired, its figures as tables (:func:`evaluation_tables`) and its
    plots; a note when it cannot be evaluated."""
    from monovo_cli.pipeline.evaluate import EvalOptions, eval_plot_images, evaluate_run

    try:
        result = evaluate_run(run, groundtruth, EvalOptions(align="se3", partial=True),
                              name="this run")
    except MonovoError as exc:
        return f'<p class="note">not evaluated: {esc(exc)}</p>'
    plots = "".join(img_tag(image, name) for name, image in eval_plot_images(result).items())
    return (f'<p class="note">against {esc(groundtruth.name)}, SE(3) aligned, as '
            "<code>monovo eval --align se3</code> gives it: APE, RPE by frame and by distance "
            "travelled, and each relative motion's error against its reported std</p>"
            + evaluation_tables(result.as_dict()) + plots)


AXES = ("tx", "ty", "tz", "rx", "ry", "rz")
ALIGNED = {None: "no alignment", "se3": "SE(3) aligned", "sim3": "Sim(3) aligned"}


def evaluation_tables(d: Mapping[str, Any]) -> str:
    """``monovo eval``'s figures (:meth:`~monovo_cli.pipeline.evaluate.EvalResult.as_dict`'s
    ``d``) as a line and tables a person reads: the pairing; the trajectory's errors; the
    relative-motion errors per axis (the paper's Tables 10.1 and 10.2); APE and RPE
    statistics; the errors by travelled distance; the share of errors inside the reported
    std's band. Units in the headers, one number format per column."""
    paired = (f"by time, within {d['max_dt_s']:g} s" if d.get("pairing") == "time"
              else "by frame number")
    line = (f"{d['poses']} of {d['estimate_poses']} estimated and {d['groundtruth_poses']} "
            f"true poses paired {paired}: {d['relative_motions']} relative motions over "
            f"{d['distance_m']:.3f} m of true path")
    if d.get("partial"):
        line += " (a partial match: the measures cover the paired poses only)"
    if d.get("alignment") == "sim3":
        line += f"; the estimate scaled by {d['scale']:.6g}"
    out = [f'<p>{esc(line)}.</p>', "<h3>Trajectory</h3>"]
    rows = [("ATE RMSE, no alignment", d["ate_rmse_m"], "m"),
            ("ATE max, no alignment", d["ate_max_m"], "m")]
    if d.get("ate_rmse_aligned_m") is not None:
        rows.append((f"ATE RMSE, {ALIGNED[d.get('alignment')]}", d["ate_rmse_aligned_m"], "m"))
    rows += [("final drift", d["final_drift_m"], "m"),
             ("final drift, of the path", _na(d.get("final_drift_pct")), "%"),
             ("final rotation error", d["final_rotation_error_deg"], "deg"),
             ("rotation drift", _na(d.get("rotation_drift_deg_per_m")), "deg/m")]
    out.append(table(("measure", "value", "unit"), rows, numeric=(False, True, False)))

    rel = d["relative_errors"]
    rows = [[axis, rel["t" + axis]["mean_m"], rel["t" + axis]["std_m"],
             rel["r" + axis]["mean_deg"], rel["r" + axis]["std_deg"]] for axis in "xyz"]
    rows.append(["average", d["translation_average"]["mean_m"], d["translation_average"]["std_m"],
                 d["rotation_average"]["mean_deg"], d["rotation_average"]["std_deg"]])
    out += ["<h3>Absolute relative-motion errors per axis (Tables 10.1 and 10.2)</h3>",
            table(("axis", "translation mean (m)", "translation std (m)", "rotation mean (deg)",
                   "rotation std (deg)"), rows, numeric=(False, True, True, True, True))]

    ape, rpe = d["ape"]["translation_m"], d["rpe"]
    stats = ("rmse", "mean", "median", "std", "min", "max")
    rows = [[k, _na(ape[k]), _na(rpe["translation_m"][k]), _na(rpe["rotation_deg"][k])]
            for k in stats]
    out += [f"<h3>APE ({esc(ALIGNED[d['ape'].get('alignment')])}) and RPE (between poses "
            f"{int(rpe['delta_poses'])} apart)</h3>",
            table(("statistic", "APE translation (m)", "RPE translation (m)",
                   "RPE rotation (deg)"), rows, numeric=(False, True, True, True))]

    seg = d["segments"]
    rows = [[f"{m['length_m']:g} m", m["segments"], _na(m["translation_pct"]),
             _na(m["rotation_deg_per_m"])] for m in seg["by_length"]]
    rows.append(["all", seg["segments"], _na(seg["translation_pct"]),
                 _na(seg["rotation_deg_per_m"])])
    starts = ("every paired pose" if seg["step_poses"] == 1
              else f"every {seg['step_poses']}th paired pose")
    out += [f"<h3>Errors by travelled distance ({esc(starts)} starts a segment of each "
            "length)</h3>",
            table(("segment length", "segments", "translation error (%)",
                   "rotation error (deg/m)"), rows, numeric=(False, True, True, True))]

    band = d.get("std_band")
    if band:
        rows = [[a, _pct(band["inside_fraction_by_axis"][a]), _na(band["normalised_std"][a])]
                for a in AXES]
        rows.append(["all", _pct(band["inside_fraction"]), "-"])
        out += [f"<h3>The reported std: errors inside ±{band['sigmas']:g} std "
                f"({band['motions']} relative motions)</h3>",
                table(("axis", f"inside ±{band['sigmas']:g} std (%)",
                       "std of error / reported std"), rows, numeric=(False, True, True)),
                '<p class="note">where the reported std is honest (and the errors Gaussian), '
                "the errors' std is 1 reported std and 99.7 % of them lie inside ±3 std</p>"]
    return "\n".join(out)


def _na(v: Any) -> Any:
    """A measure, or "n/a" where there is none (None, not finite)."""
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else v


def _pct(fraction: Any) -> Any:
    return _na(fraction) if _na(fraction) == "n/a" else 100.0 * float(fraction)


def record_tables(record: Mapping[str, Any]) -> str:
    """run.yaml's record, its options and its inputs as three tables of dotted names and
    values (lists of values joined by commas, yes / no, "-" for none)."""
    out = []
    for part in ("options", "inputs"):
        rows = _flat(record.get(part, {}))
        out.append(f"<h3>{part}</h3>" + table(("name", "value"), rows))
    head = {k: v for k, v in record.items() if k not in ("options", "inputs")}
    return table(("name", "value"), _flat(head)) + "\n".join(out)


def _flat(value: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted name, leaf) of a nested mapping; a list of mappings gives ``name[i].key``
    rows, a list of plain values stays whole."""
    if isinstance(value, Mapping):
        out: list[tuple[str, Any]] = []
        for k, v in value.items():
            out += _flat(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    if isinstance(value, (list, tuple)) and any(isinstance(v, Mapping) for v in value):
        return [row for i, v in enumerate(value) for row in _flat(v, f"{prefix}[{i}]")]
    return [(prefix, value)]


# ----------------------------------------------------------------------------- batch


def outcome_rank(result: Mapping[str, Any]) -> tuple[int, float]:
    """The order of a sequence in the index: failed, then not run, then by the share of
    frames lost (most first)."""
    status = result.get("status")
    frames, lost = result.get("frames") or 0, result.get("lost") or 0
    share = lost / (frames - 1) if frames > 1 else 0.0
    return ({"failed": 0, "pending": 1}.get(str(status), 2), -share)


def write_index(out_root: Path, results: Sequence[Mapping[str, Any]]) -> Path:
    """Write ``out_root/index.html`` atomically: one row per sequence of ``results`` (batch's
    result dicts, ``out_dir`` where its outputs are) with summary.csv's columns, sorted by
    :func:`outcome_rank`, its name linked to its report.html (a relative link) when there is
    one. Returns its path."""
    from monovo_cli.pipeline.batch_summary import SUMMARY_COLUMNS, summary_rows

    out_root = Path(out_root)
    ordered = sorted(results, key=outcome_rank)
    rows, classes = [], []
    for res, row in zip(ordered, summary_rows(ordered)):
        report = Path(str(res.get("out_dir", ""))) / REPORT_FILE
        if res.get("out_dir") and report.is_file():
            rel = Path(os.path.relpath(report, out_root)).as_posix()
            row = [link(rel, row[0]), *row[1:]]
        else:
            row = [Markup(f"{esc(row[0])} <span class=note>(no report)</span>"), *row[1:]]
        rows.append(row)
        classes.append("failed" if res.get("status") == "failed"
                       else "lost" if (res.get("lost") or 0) > 0 else "")
    numeric = [c not in ("sequence", "status", "error") for c in SUMMARY_COLUMNS]
    counts = {s: sum(r.get("status") == s for r in results) for s in
              ("ok", "skipped", "failed", "pending")}
    line = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
    body = [f"<h1>{esc(out_root.name)}: {len(results)} sequence(s)</h1>", f"<p>{esc(line)}</p>",
            table(SUMMARY_COLUMNS, rows, numeric=numeric, row_classes=classes)]
    path = out_root / INDEX_FILE
    write_page(path, page(f"monovo batch: {out_root.name}", body))
    return path
