"""A benchmark run with ``--write-docs`` writes its own section of the results page: what it
printed, under the exact command that ran; the speed rows set monovo against ECC as a user
gets it (OpenCV's default stop) first."""

from __future__ import annotations

import sys

from benchmarks.docs_section import printed_section, writes_section
from benchmarks.speed import SPEED_HEAD, speed_row

PAGE = "# Results\n\nIntro.\n\n## Drives\n\n<!-- drives:begin -->\nold table\n<!-- drives:end -->\n\nEnd.\n"


def test_printed_section_replaces_only_its_section_with_command_and_output(tmp_path, capsys):
    page = tmp_path / "benchmarks.md"
    page.write_text(PAGE)
    with printed_section("drives", "Drives", "benchmarks.drives", argv=["--frames", "10"], page=page):
        print("Machine: host, monovo abc1234, 2026-11-28\n\n| a |\n| --- |\n| 1 |")
    text = page.read_text()
    assert "old table" not in text and text.startswith("# Results\n\nIntro.\n") and text.endswith("End.\n")
    body = text.split("<!-- drives:begin -->\n")[1].split("<!-- drives:end -->")[0]
    assert body.splitlines()[0] == "`python -m benchmarks.drives --frames 10`"
    assert "monovo abc1234, 2026-11-28" in body and "| 1 |" in body
    assert "| 1 |" in capsys.readouterr().out  # still printed


def test_printed_section_writes_nothing_unless_asked_or_when_the_run_fails(tmp_path):
    page = tmp_path / "benchmarks.md"
    page.write_text(PAGE)
    with printed_section("drives", "Drives", "benchmarks.drives", enabled=False, page=page):
        print("| 2 |")
    try:
        with printed_section("drives", "Drives", "benchmarks.drives", argv=[], page=page):
            print("| 3 |")
            raise RuntimeError("stopped")
    except RuntimeError:
        pass
    assert page.read_text() == PAGE


def test_writes_section_follows_the_write_docs_flag(tmp_path, monkeypatch):
    import benchmarks.docs_section as ds

    page = tmp_path / "benchmarks.md"
    page.write_text(PAGE)
    monkeypatch.setattr(ds, "DOCS", page)

    @writes_section("drives", "Drives", "benchmarks.drives")
    def main() -> None:
        print("| 4 |")

    monkeypatch.setattr(sys, "argv", ["drives.py", "--seed", "3"])
    main()
    assert page.read_text() == PAGE
    monkeypatch.setattr(sys, "argv", ["drives.py", "--seed", "3", "--write-docs"])
    main()
    assert "`python -m benchmarks.drives --seed 3 --write-docs`\n\n| 4 |" in page.read_text()


def test_speed_rows_set_monovo_against_ecc_at_opencvs_default_stop_first():
    e2e = {"fps": 60.0, "fps_cpu": 50.0, "fps_steady": 61.0, "lost": 0, "reanchored": 1,
           "drift_pct": 0.01}
    # ECC at the strict stop 10 frames/s (8 CPU), at OpenCV's default stop 30 (25 CPU)
    row = speed_row("512x512", e2e, (70.0, 65.0), (10.0, 8.0, 30.0, 25.0))
    head = [c.strip() for c in SPEED_HEAD.strip("|").split("|")]
    cells = dict(zip(head, (c.strip() for c in row.strip("|").split("|"))))
    assert len(head) == len(cells) == 13
    assert cells["ECC at OpenCV's default stop (1e-3), end to end"] == "30.0 (25.0)"
    assert cells["monovo / ECC"] == "2.00 (2.00)"
    assert cells["ECC at the strict stop (1e-6), end to end"] == "10.0 (8.0)"
    assert cells["monovo / that"] == "6.00 (6.25)"
