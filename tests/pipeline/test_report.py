"""report.html of a track run and batch's index.html: self-contained, every section there."""

from __future__ import annotations

import base64
import html
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import cv2
import numpy as np
import pytest

from monovo_cli.core.options import TrackOptions
from monovo_cli.pipeline.report import INDEX_FILE, REPORT_FILE, outcome_rank, write_index
from monovo_cli.pipeline.track import RESULT_FILES, track_sequence
from monovo_cli.synth.write import synthesize

PNG = "data:image/png;base64,"


class _Page(HTMLParser):
    """Every tag's attributes, by tag, and the ids."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def of(self, tag: str) -> list[dict[str, str | None]]:
        return [a for t, a in self.tags if t == tag]


class _Tables(HTMLParser):
    """Every table's cells: ``tables[t][row]`` a list of ``(text, numeric)``."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[tuple[str, bool]]]] = []
        self._cell: list[str] | None = None
        self._numeric = False

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag == "td":
            self._cell, self._numeric = [], ("class", "num") in attrs

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag):
        if tag == "td":
            self.tables[-1][-1].append(("".join(self._cell), self._numeric))
            self._cell = None


def numeric_columns(text: str) -> list[list[str]]:
    """The numbers of every right-aligned column of every table of ``text`` (not "n/a", "-")."""
    p = _Tables()
    p.feed(text)
    columns = []
    for rows in p.tables:
        width = max((len(r) for r in rows), default=0)
        for i in range(width):
            cells = [r[i] for r in rows if i < len(r)]
            if any(numeric for _, numeric in cells):
                columns.append([c for c, _ in cells if c not in ("n/a", "-")])
    return columns


def notation(number: str) -> tuple[bool, int]:
    """(scientific, decimals) of a number as written."""
    float(number)  # a number
    mantissa = number.lower().split("e")[0]
    return "e" in number.lower(), len(mantissa.split(".")[1]) if "." in mantissa else 0


def parse(path: Path) -> _Page:
    p = _Page()
    p.feed(path.read_text(encoding="utf-8"))
    p.close()
    return p


def assert_self_contained(path: Path) -> _Page:
    """Every image embedded as a valid PNG, no external URL, no script, no link element."""
    text = path.read_text(encoding="utf-8")
    page = parse(path)
    imgs = page.of("img")
    assert imgs or path.name == INDEX_FILE
    for a in imgs:
        src = a.get("src") or ""
        assert src.startswith(PNG), src[:60]
        data = base64.b64decode(src[len(PNG):], validate=True)
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) is not None
    assert not page.of("script") and not page.of("link") and not page.of("iframe")
    for _, attrs in page.tags:
        for name in ("src", "href", "srcset", "action", "data"):
            v = attrs.get(name)
            if v is not None and not v.startswith(PNG):
                assert "//" not in v and ":" not in v, f"{name}={v!r}"
    assert "http:" not in text.lower() and "https:" not in text.lower()
    assert "url(" not in text.lower() and "@import" not in text.lower()
    return page


@pytest.fixture(scope="module")
def broken_drive(tmp_path_factory) -> Path:
    """14 frames: frame 5 blank, frames 6.. of another drive: lost, lost, re-initialised."""
    root = tmp_path_factory.mktemp("report")
    seq, other = root / "seq", root / "other"
    synthesize(seq, preset="drive", frames=14, size=(128, 128), seed=4)
    synthesize(other, preset="drive", frames=14, size=(128, 128), seed=9)
    frames = sorted((seq / "frames").glob("*.png"))
    assert len(frames) == 14
    img = cv2.imread(str(frames[5]), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(frames[5]), np.full_like(img, 128))
    for mine, theirs in zip(frames[6:], sorted((other / "frames").glob("*.png"))[6:]):
        shutil.copy(theirs, mine)
    return seq


@pytest.fixture(scope="module")
def broken_run(broken_drive, tmp_path_factory):
    out = tmp_path_factory.mktemp("report_out") / "out"
    run = track_sequence(broken_drive, None, out, TrackOptions(), terrain_out=True,
                         groundtruth=broken_drive / "groundtruth.tum")
    return run, out


def test_report_is_self_contained_with_every_section(broken_run):
    run, out = broken_run
    assert run.lost == 2 and run.reinit == 1  # the drive does what the test needs
    page = assert_self_contained(out / REPORT_FILE)
    ids = {a.get("id") for _, a in page.tags}
    assert {"trajectory", "timeline", "heightmap", "keyframes", "evaluation", "run"} <= ids
    alts = [a.get("alt") or "" for a in page.of("img")]
    assert any("trajectory" in a for a in alts) and any("height map" in a for a in alts)
    assert any("per frame" in a for a in alts)
    # a thumbnail of frame 0 and of the re-initialised frame
    assert {"keyframe 0", "keyframe 7"} <= set(alts)
    text = (out / REPORT_FILE).read_text()
    # the lost and re-initialised frames with their reasons
    for k in (5, 6, 7):
        assert run.reason[k] and run.reason[k] in text
    assert "<td>5-6</td>" not in text  # two reasons: two rows
    assert "ATE RMSE, SE(3) aligned" in text and "final drift" in text  # eval's figures
    assert "track.reinit_after" in text and "<h3>inputs</h3>" in text  # run.yaml's record
    assert "init_yaml.sha256" in text


def test_report_reads_as_tables_not_python_values(broken_run):
    """No dict, list of dicts, True / False or None as Python prints them; the ground truth's
    figures in tables with units; every numeric column in one notation."""
    run, out = broken_run
    raw = (out / REPORT_FILE).read_text(encoding="utf-8")
    text = html.unescape(raw)
    for repr_ in ("{'", "[{", "True", "False", "None", "': "):
        assert repr_ not in text, repr_
    assert "<td>track.feature_hypothesis</td><td>yes</td>" in raw
    assert "<th>translation mean (m)</th>" in raw and "<th>RPE rotation (deg)</th>" in raw
    assert "<td>5 m</td>" in raw  # the segments by length: one row each, not a list of dicts
    columns = numeric_columns(raw)
    assert len(columns) == 13  # the evaluation's five tables, 1 + 4 + 3 + 3 + 2 columns
    assert sum(len(c) > 1 for c in columns) >= 8  # (this short drive has no 1 m segment)
    for column in columns:
        assert len({notation(c) for c in column}) <= 1, column
    # the relative-motion errors: the paper's table, one row per axis
    p = _Tables()
    p.feed(raw)
    axes = next(t for t in p.tables if t and t[-1] and t[-1][0][0] == "average")
    assert [r[0][0] for r in axes[1:]] == ["x", "y", "z", "average"]


def test_column_format_is_one_notation():
    from monovo_cli.io.report_html import column_format

    f = column_format([4.45345e-05, 0.000979401, 0.0, float("nan")])
    assert [f(v) for v in (4.45345e-05, 0.000979401, 0.0, float("nan"))] == \
        ["0.0000445", "0.0009794", "0.0000000", "n/a"]
    assert [column_format([3, 120])(v) for v in (3, 120)] == ["3", "120"]
    g = column_format([1e-12, 2.0])
    assert [g(1e-12), g(2.0)] == ["1.000e-12", "2.000e+00"]


def test_report_without_terrain_or_truth(small_drive, tmp_path):
    track_sequence(small_drive, None, tmp_path / "o", TrackOptions())
    page = assert_self_contained(tmp_path / "o" / REPORT_FILE)
    ids = {a.get("id") for _, a in page.tags}
    assert {"trajectory", "timeline", "keyframes", "run"} <= ids
    assert not {"heightmap", "evaluation"} & ids
    assert "no frame was lost or re-initialised" in (tmp_path / "o" / REPORT_FILE).read_text()


def test_report_is_a_result_file_and_can_be_left_out(small_drive, tmp_path):
    assert REPORT_FILE in RESULT_FILES  # removed before a rerun, refused without --overwrite
    out = tmp_path / "o"
    track_sequence(small_drive, None, out, TrackOptions())
    assert (out / REPORT_FILE).is_file()
    track_sequence(small_drive, None, out, TrackOptions(), overwrite=True, report=False)
    assert not (out / REPORT_FILE).exists()  # the stale one is gone


def test_an_unmatched_groundtruth_is_a_note(small_drive, tmp_path):
    from monovo_cli.pipeline.report import evaluation_section
    from monovo_cli.pipeline.tracking import track_frames

    run = track_frames(small_drive)
    gt = tmp_path / "gt.tum"
    gt.write_text("1000 0 0 0 0 0 0 1\n1001 0 0 0 0 0 0 1\n")
    assert "not evaluated" in evaluation_section(run, gt)


def test_index_orders_by_outcome_and_links_reports(tmp_path):
    root = tmp_path / "out"
    for name in ("ok", "lossy", "bad"):
        (root / name).mkdir(parents=True)
        (root / name / REPORT_FILE).write_text("<!DOCTYPE html>")
    results = [
        {"sequence": "ok", "out_dir": str(root / "ok"), "status": "ok", "frames": 10, "lost": 0},
        {"sequence": "lossy", "out_dir": str(root / "lossy"), "status": "ok", "frames": 10,
         "lost": 3},
        {"sequence": "gone", "out_dir": str(root / "gone"), "status": "failed", "frames": None,
         "lost": None, "error": "bad init.yaml"},
        {"sequence": "bad", "out_dir": str(root / "bad"), "status": "failed", "frames": 10,
         "lost": 8, "error": "8 of 9 frames lost"},
    ]
    assert [r["sequence"] for r in sorted(results, key=outcome_rank)] == \
        ["bad", "gone", "lossy", "ok"]  # failed ones first, the most lost first
    path = write_index(root, results)
    page = assert_self_contained(path)
    hrefs = [a["href"] for a in page.of("a")]
    assert hrefs == ["bad/report.html", "lossy/report.html", "ok/report.html"]
    assert all((root / h).is_file() for h in hrefs)
    text = path.read_text()
    assert text.index("bad/report.html") < text.index("gone") < text.index("lossy/") \
        < text.index("ok/report.html")
    assert "bad init.yaml" in text and "(no report)" in text


def test_batch_index_links_every_report(broken_drive, small_drive, tmp_path):
    from monovo_cli.pipeline.batch import run_batch

    root = tmp_path / "archive"
    shutil.copytree(broken_drive, root / "lossy")
    shutil.copytree(small_drive, root / "fine")
    shutil.copytree(small_drive, root / "broken")
    (root / "broken" / "init.yaml").write_text("camera: [\n")
    out = tmp_path / "out"
    summary = run_batch(root, out, workers=1)
    assert [r["status"] for r in summary.results] == ["failed", "ok", "ok"]
    page = assert_self_contained(out / INDEX_FILE)
    hrefs = [a["href"] for a in page.of("a")]
    assert hrefs == ["lossy/report.html", "fine/report.html"]  # failed first, then by losses
    for h in hrefs:
        assert not Path(h).is_absolute() and (out / h).is_file()
        assert_self_contained(out / h)
    text = (out / INDEX_FILE).read_text()
    assert text.index("broken") < text.index("lossy/") and "(no report)" in text


def test_an_unreadable_frame_is_left_out_of_the_mean_msd(small_drive, tmp_path):
    from monovo_cli.pipeline.report import run_summary
    from monovo_cli.pipeline.tracking import track_frames

    seq = tmp_path / "seq"
    shutil.copytree(small_drive, seq)
    (seq / "frames" / "frame_000004.png").write_bytes(b"not a png")
    run = track_frames(seq, skip_bad_frames=True)
    assert run.points[4] == 0 and run.msd[4] == 0  # motion.csv's numbers, no measurement
    fitted = [k for k in range(1, 10) if k != 4]
    mean = float(np.mean(run.msd[fitted]))
    assert abs(mean - run.mean_msd) > 0.01  # the zero would pull it down
    assert f"mean msd {mean:.2f} of the 8 frames fitted;" in run_summary(run)


def test_index_fits_its_page_width(tmp_path):
    """batch's index.html ran off a 1100 px window: summary.csv's columns and a long unbroken
    error path widened the table past the page. Its table now scrolls in a box of the page's
    width, and a text cell's long words wrap (numbers do not)."""
    from monovo_cli.io.report_html import STYLE

    root = tmp_path / "out"
    root.mkdir()
    error = "cannot read " + "/".join(["a_very_long_folder_name"] * 12) + "/frame.png"
    path = write_index(root, [{"sequence": "bad", "out_dir": str(root / "bad"),
                               "status": "failed", "frames": None, "lost": None,
                               "error": error}])
    text = path.read_text()
    assert '<div class="wide"><table>' in text and "</table></div>" in text
    rules = {sel.strip(): body for sel, body in re.findall(r"([^{}]+)\{([^}]*)\}", STYLE)}
    assert "overflow-x: auto" in rules[".wide"] and "max-width: 100%" in rules[".wide"]
    assert "overflow-wrap: anywhere" in rules["td"]
    assert "max-width: 1100px" in rules["body"]
