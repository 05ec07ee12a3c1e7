"""Every bad input monovo is tested against, one :class:`Case` per row of docs/reliability.md.

``tests/cli/test_reliability.py`` runs each case through the CLI and asserts its exit status
and the key words of its message; ``docs/make_reliability_table.py`` runs the same cases
and writes the table, so the document and the tests cannot drift apart.

A case is a command line with placeholders and an optional ``setup(tmp, seq)`` that
prepares the bad input in ``tmp`` from ``seq``, a small pristine synthetic drive
(:func:`make_base_sequence`, never modified):

* ``{seq}`` -- the pristine sequence (frames/ and init.yaml);
* ``{tmp}`` -- the case's own empty directory; ``{copy}`` is ``{tmp}/seq``, a copy of the
  sequence that ``setup`` damaged (see :func:`_copy`);
* ``{init}`` -- ``{tmp}/init.yaml``, written by the ``_yaml_*`` setups.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

BASE_FRAMES = 6
BASE_SIZE = 128


@dataclass(frozen=True)
class Case:
    """One bad (or awkward but accepted) input and what monovo must answer."""

    id: str
    group: str
    what: str  # the input, as the table shows it
    args: tuple[str, ...]  # the command line after 'monovo', with placeholders
    status: int  # expected exit status
    words: tuple[str, ...]  # key words the message must hold (case-insensitive)
    setup: Callable[[Path, Path], None] | None = None
    note: str = ""  # a remark for the table
    needs: tuple[str, ...] = field(default=())  # commands this case needs in the CLI
    stdout_to: str | None = None  # run in a subprocess with stdout sent to this file


@dataclass(frozen=True)
class Outcome:
    status: int
    stdout: str
    stderr: str

    @property
    def message(self) -> str:
        """The line that answers the case: the ``Error:`` line, else the last warning
        (``monovo: WARNING: ...``, progress bars cut off), else the summary on stdout."""
        lines = [ln for ln in self.stderr.splitlines() if ln.strip()]
        errors = [ln for ln in lines if ln.startswith("Error:")]
        if errors:
            return errors[-1]
        warnings = [ln[ln.index("monovo: WARNING"):] for ln in lines if "monovo: WARNING" in ln]
        if warnings:
            return warnings[-1]
        out = [ln for ln in self.stdout.splitlines() if ln.strip()]
        return out[-1] if out else ""


# ----------------------------------------------------------------------------- fixtures


def make_base_sequence(root: Path) -> Path:
    """A 6-frame 128x128 synthetic drive in ``root/seq`` (frames/, init.yaml, ground truth)."""
    from monovo_cli.synth.write import synthesize

    seq = Path(root) / "seq"
    synthesize(seq, preset="drive", frames=BASE_FRAMES, size=(BASE_SIZE, BASE_SIZE), seed=4)
    return seq


def _frames(seq: Path) -> list[Path]:
    frames = sorted((seq / "frames").glob("*.png"))
    assert frames, f"no frames in {seq}"
    return frames


def _copy(tmp: Path, seq: Path) -> Path:
    dst = tmp / "seq"
    shutil.copytree(seq, dst)
    return dst


def _base_yaml(seq: Path) -> str:
    return (seq / "init.yaml").read_text()


# ----------------------------------------------------------------------------- setups


def _write(path: str, data: bytes | str) -> Callable[[Path, Path], None]:
    def setup(tmp: Path, seq: Path) -> None:  # noqa: ARG001
        p = tmp / path
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data.encode() if isinstance(data, str) else data)
    return setup


def _mkdir(path: str) -> Callable[[Path, Path], None]:
    def setup(tmp: Path, seq: Path) -> None:  # noqa: ARG001
        (tmp / path).mkdir(parents=True)
    return setup


def _damage_frame(index: int, how: str) -> Callable[[Path, Path], None]:
    """Copy the sequence and damage frame ``index``: zero-byte, truncated, text, a dangling
    symlink, or another size."""
    def setup(tmp: Path, seq: Path) -> None:
        f = _frames(_copy(tmp, seq))[index]
        data = f.read_bytes()
        if how == "empty":
            f.write_bytes(b"")
        elif how == "truncated":
            f.write_bytes(data[: len(data) // 2])
        elif how == "text":
            f.write_text("this is not an image\n")
        elif how == "dangling":
            f.unlink()
            f.symlink_to(tmp / "gone.png")
        elif how == "size":
            cv2.imwrite(str(f), np.full((64, 96), 100, np.uint8))
        elif how == "constant":
            cv2.imwrite(str(f), np.full((BASE_SIZE, BASE_SIZE), 128, np.uint8))
        else:
            raise ValueError(how)
    return setup


def _keep_frames(n: int) -> Callable[[Path, Path], None]:
    def setup(tmp: Path, seq: Path) -> None:
        for f in _frames(_copy(tmp, seq))[n:]:
            f.unlink()
    return setup


def _no_init(tmp: Path, seq: Path) -> None:
    (_copy(tmp, seq) / "init.yaml").unlink()


def _convert(kind: str) -> Callable[[Path, Path], None]:
    """Re-encode every frame as 16-bit grey, colour, colour + alpha or palette PNG."""
    def setup(tmp: Path, seq: Path) -> None:
        for f in _frames(_copy(tmp, seq)):
            g = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
            if kind == "16bit":
                cv2.imwrite(str(f), g.astype(np.uint16) * 257)
            elif kind == "colour":
                cv2.imwrite(str(f), cv2.cvtColor(g, cv2.COLOR_GRAY2BGR))
            elif kind == "alpha":
                cv2.imwrite(str(f), cv2.cvtColor(g, cv2.COLOR_GRAY2BGRA))
            elif kind == "palette":
                from PIL import Image

                Image.fromarray(g).convert("P").save(f)
            else:
                raise ValueError(kind)
    return setup


def _times(text: str) -> Callable[[Path, Path], None]:
    def setup(tmp: Path, seq: Path) -> None:
        (_copy(tmp, seq) / "frames" / "times.txt").write_text(text)
    return setup


def _increasing(n: int) -> str:
    return "".join(f"{0.1 * k:.1f}\n" for k in range(n))


def _yaml_text(text: str) -> Callable[[Path, Path], None]:
    """``{init}`` holding exactly ``text``."""
    def setup(tmp: Path, seq: Path) -> None:  # noqa: ARG001
        (tmp / "init.yaml").write_text(text)
    return setup


def _yaml_edit(*pairs: tuple[str, str]) -> Callable[[Path, Path], None]:
    """``{init}``: the sequence's init.yaml with textual replacements (each must apply)."""
    def setup(tmp: Path, seq: Path) -> None:
        text = _base_yaml(seq)
        for old, new in pairs:
            assert old in text, (old, text)
            text = text.replace(old, new, 1)
        (tmp / "init.yaml").write_text(text)
    return setup


_CAMERA = "camera: {width: 128, height: 128, fx: 111.36, fy: 111.36, cx: 63.5, cy: 63.5}\n"
_NORMAL = "normal: [0.0, 0.7071067811865476, 0.7071067811865475]"


def _ground(body: str) -> Callable[[Path, Path], None]:
    """``{init}`` with the base camera and this ``ground:`` section (YAML flow mapping body)."""
    return _yaml_text(_CAMERA + "ground: {" + body + "}\n")


def _camera_file(text: str | None) -> Callable[[Path, Path], None]:
    """``{init}`` naming ``cam.yaml`` as camera_file; ``text`` None: the file does not exist."""
    def setup(tmp: Path, seq: Path) -> None:  # noqa: ARG001
        (tmp / "init.yaml").write_text("camera_file: cam.yaml\nground: {" + _NORMAL
                                       + ", distance: 1.5}\n")
        if text is not None:
            (tmp / "cam.yaml").write_text(text)
    return setup


def _read_only_dir(tmp: Path, seq: Path) -> None:  # noqa: ARG001
    d = tmp / "ro"
    d.mkdir()
    d.chmod(0o555)


_MOTION_HEADER = "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status\n"


def _results_exist(tmp: Path, seq: Path) -> None:  # noqa: ARG001
    (tmp / "out").mkdir()
    (tmp / "out" / "motion.csv").write_text(_MOTION_HEADER + "1,0,0,0.05,0,0,0,20.5,4,4000,ok\n")


def _failed_run(tmp: Path, seq: Path) -> None:  # noqa: ARG001
    """What a run that failed before its first tracked frame leaves: a header-only motion.csv
    and frame 0's trajectory."""
    (tmp / "out").mkdir()
    (tmp / "out" / "motion.csv").write_text(_MOTION_HEADER)
    (tmp / "out" / "trajectory.csv").write_text("frame,timestamp,tx,ty,tz,qx,qy,qz,qw\n"
                                                "0,0,0,0,0,0,0,0,1.0\n")
    (tmp / "out" / "trajectory.tum").write_text("0 0 0 0 0 0 0 1.0\n")


def _times_beside(text: str) -> Callable[[Path, Path], None]:
    """times.txt beside frames/ (``text``) and inside it (0, 1, 2, ...)."""
    def setup(tmp: Path, seq: Path) -> None:
        copy = _copy(tmp, seq)
        (copy / "times.txt").write_text(text)
        (copy / "frames" / "times.txt").write_text("".join(f"{k}\n" for k in range(BASE_FRAMES)))
    return setup


def _model_of(other_seed: int | None = None, **options) -> Callable[[Path, Path], None]:
    """``tmp/model.npz`` built by init from ``seq`` (or from a sequence of another seed)."""
    def setup(tmp: Path, seq: Path) -> None:
        from monovo_cli.core.options import TrackOptions
        from monovo_cli.pipeline.track import init_model
        from monovo_cli.synth.write import synthesize

        src = seq
        if other_seed is not None:
            src = tmp / "other"
            synthesize(src, preset="drive", frames=2, size=(BASE_SIZE, BASE_SIZE), seed=other_seed)
        init_model(src, None, tmp / "model.npz", TrackOptions(**options))
    return setup


def _groundtruth_shifted(tmp: Path, seq: Path) -> None:
    lines = (seq / "groundtruth.tum").read_text().splitlines()
    (tmp / "gt.tum").write_text("".join(f"{float(ln.split()[0]) + 100} {ln.split(' ', 1)[1]}\n"
                                        for ln in lines))


def _all(*setups: Callable[[Path, Path], None]) -> Callable[[Path, Path], None]:
    def setup(tmp: Path, seq: Path) -> None:
        for s in setups:
            s(tmp, seq)
    return setup


def _model_other_size(tmp: Path, seq: Path) -> None:
    """A model.npz built on a 96x96 sequence."""
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.track import init_model
    from monovo_cli.synth.write import synthesize

    other = tmp / "other"
    synthesize(other, preset="drive", frames=2, size=(96, 96), seed=1)
    init_model(other, None, tmp / "model.npz", TrackOptions())


def _tracked(tmp: Path, seq: Path) -> Path:
    """Track ``seq`` into ``tmp/out`` (motion.csv, trajectory.csv, trajectory.tum)."""
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.track import track_sequence

    out = tmp / "out"
    if not (out / "trajectory.csv").exists():
        track_sequence(seq, None, out, TrackOptions())
    return out


def _tracked_setup(tmp: Path, seq: Path) -> None:
    _tracked(tmp, seq)


def _trajectory(edit: Callable[[list[str]], list[str]], name: str = "trajectory.csv"):
    """Track the sequence, then rewrite ``tmp/out/<name>``'s lines with ``edit``."""
    def setup(tmp: Path, seq: Path) -> None:
        path = _tracked(tmp, seq) / name
        path.write_text("".join(ln + "\n" for ln in edit(path.read_text().splitlines())))
    return setup


def _tum_pair(edit: Callable[[list[str]], list[str]]):
    """``tmp/est.tum``: the sequence's ground truth with ``edit`` applied to its lines."""
    def setup(tmp: Path, seq: Path) -> None:
        lines = (seq / "groundtruth.tum").read_text().splitlines()
        (tmp / "est.tum").write_text("".join(ln + "\n" for ln in edit(lines)))
    return setup


def _gt_lines(edit: Callable[[list[str]], list[str]]):
    """``tmp/gt.tum``: the sequence's ground truth with ``edit`` applied to its lines."""
    def setup(tmp: Path, seq: Path) -> None:
        lines = (seq / "groundtruth.tum").read_text().splitlines()
        (tmp / "gt.tum").write_text("".join(ln + "\n" for ln in edit(lines)))
    return setup


def _shift_times(lines: list[str]) -> list[str]:
    return [" ".join([str(float(ln.split()[0]) + 0.5), *ln.split()[1:]]) for ln in lines]


def _set_field(row: int, col: int, value: str, sep: str = " "):
    def edit(lines: list[str]) -> list[str]:
        f = lines[row].split(sep)
        f[col] = value
        return [*lines[:row], sep.join(f), *lines[row + 1:]]
    return edit


# ----------------------------------------------------------------------------- the cases

T = ("track",)
OUT = ("-o", "{tmp}/out")
P = ("-p", "{init}")
TRACK_COPY = (*T, "{copy}", *OUT)
TRACK_INIT = (*T, "{seq}", *P, *OUT)
OV = ("overlay", "{seq}")
OV_T = ("-t", "{tmp}/out/trajectory.csv")


def _c(id, group, what, args, status, words, setup=None, **kw) -> Case:  # noqa: A002
    return Case(id, group, what, tuple(args), status, tuple(words), setup, **kw)


CASES: list[Case] = [
    # --- the sequence ------------------------------------------------------------------
    _c("seq-missing", "sequence", "sequence path does not exist",
       (*T, "{tmp}/nope", *OUT), 2, ("nope", "no such directory")),
    _c("seq-is-file", "sequence", "a file instead of a directory",
       (*T, "{tmp}/one.png", "-p", "{seq}/init.yaml", *OUT), 2, ("one.png", "is a file", "directory"),
       _write("one.png", b"x")),
    _c("seq-empty", "sequence", "an empty directory (no images)",
       (*T, "{tmp}/empty", "-p", "{seq}/init.yaml", *OUT), 2, ("empty", "no image files", ".png"),
       _mkdir("empty")),
    _c("seq-no-images", "sequence", "a directory of other files only (.gif, .txt)",
       (*T, "{tmp}/other", "-p", "{seq}/init.yaml", *OUT), 2, ("no image files", "accepted"),
       _all(_write("other/a.gif", b"GIF89a"), _write("other/notes.txt", "x"))),
    _c("seq-one-frame", "sequence", "one image only (track needs two)",
       TRACK_COPY, 2, ("only 1 frame", "at least 2"), _keep_frames(1)),
    _c("seq-no-init", "sequence", "no init.yaml beside the frames and no -p",
       TRACK_COPY, 2, ("no init.yaml", "-p init.yaml"), _no_init),
    _c("frame0-empty", "sequence", "zero-byte first frame",
       TRACK_COPY, 2, ("frame_000000.png", "cannot decode"), _damage_frame(0, "empty")),
    _c("frame0-truncated", "sequence", "truncated first frame (half a PNG)",
       TRACK_COPY, 2, ("frame_000000.png", "cannot decode"), _damage_frame(0, "truncated")),
    _c("frame0-not-image", "sequence", "first frame is not an image (text named .png)",
       TRACK_COPY, 2, ("frame_000000.png", "cannot decode"), _damage_frame(0, "text")),
    _c("frame0-unreadable", "sequence", "unreadable first frame (dangling symlink)",
       TRACK_COPY, 2, ("frame_000000.png", "cannot read image", "no such file"),
       _damage_frame(0, "dangling")),
    _c("frame-mid-empty", "sequence", "zero-byte frame in the middle",
       TRACK_COPY, 2, ("frame_000003.png", "cannot decode", "stopped at frame 3", "frames 0..2",
                       "--skip-bad-frames"), _damage_frame(3, "empty"),
       note="motion.csv and the trajectory keep frames 0..2"),
    _c("frame-mid-truncated", "sequence", "truncated frame in the middle",
       TRACK_COPY, 2, ("frame_000003.png", "cannot decode", "--skip-bad-frames"),
       _damage_frame(3, "truncated")),
    _c("frame-mid-not-image", "sequence", "text file named .png in the middle",
       TRACK_COPY, 2, ("frame_000003.png", "cannot decode", "--skip-bad-frames"),
       _damage_frame(3, "text")),
    _c("frame-mid-unreadable", "sequence", "unreadable frame in the middle (dangling symlink)",
       TRACK_COPY, 2, ("frame_000003.png", "cannot read image", "--skip-bad-frames"),
       _damage_frame(3, "dangling")),
    _c("frame-mid-skip", "sequence", "a bad frame in the middle with --skip-bad-frames",
       (*TRACK_COPY, "--skip-bad-frames"), 0, ("frame_000003.png", "recorded as lost"),
       _damage_frame(3, "empty"), note="its row says lost, tracking goes on"),
    _c("frame-mid-stream", "sequence", "a bad frame in the middle with -o - (streaming)",
       (*T, "{copy}", "-o", "-"), 2, ("frame_000003.png", "cannot decode", "went to stdout"),
       _damage_frame(3, "empty"), note="stdout holds the header and the rows of frames 1..2"),
    _c("frames-mixed-sizes", "sequence", "frames of mixed sizes",
       TRACK_COPY, 2, ("frame_000002.png", "96x64", "128x128", "one size"),
       _damage_frame(2, "size")),
    _c("frames-vs-init-size", "sequence", "frame size differs from init.yaml",
       (*T, "{seq}", *P, *OUT), 2, ("init.yaml", "130x128", "128x128", "frames"),
       _yaml_edit(("width: 128", "width: 130"))),
    _c("png-16bit", "sequence", "16-bit grey PNG frames", TRACK_COPY, 0, ("tracked 6 frames",),
       _convert("16bit"), note="scaled by 255/65535"),
    _c("png-colour", "sequence", "colour PNG frames", TRACK_COPY, 0, ("tracked 6 frames",),
       _convert("colour"), note="converted to grey"),
    _c("png-alpha", "sequence", "colour + alpha PNG frames", TRACK_COPY, 0, ("tracked 6 frames",),
       _convert("alpha"), note="alpha ignored"),
    _c("png-palette", "sequence", "palette PNG frames", TRACK_COPY, 0, ("tracked 6 frames",),
       _convert("palette"), note="palette colours to grey"),
    _c("times-too-few", "sequence", "times.txt with fewer lines than frames",
       TRACK_COPY, 2, ("times.txt", "5 timestamps for 6 frames", "one line per frame"),
       _times(_increasing(5))),
    _c("times-too-many", "sequence", "times.txt with more lines than frames",
       TRACK_COPY, 2, ("times.txt", "7 timestamps for 6 frames"), _times(_increasing(7))),
    _c("times-not-increasing", "sequence", "times.txt with non-increasing times",
       TRACK_COPY, 2, ("times.txt", "line 3", "must increase"),
       _times("0.0\n0.1\n0.1\n0.3\n0.4\n0.5\n")),
    _c("times-not-number", "sequence", "times.txt with a non-numeric line",
       TRACK_COPY, 2, ("times.txt", "line 2", "expected one timestamp"),
       _times("0.0\nabc\n0.2\n0.3\n0.4\n0.5\n")),
    _c("times-nan", "sequence", "times.txt with nan", TRACK_COPY, 2,
       ("times.txt", "line 4", "finite"), _times("0.0\n0.1\n0.2\nnan\n0.4\n0.5\n")),
    _c("times-beside-differ", "sequence", "times.txt beside frames/ and in it, differing",
       TRACK_COPY, 2, ("times.txt", "differ", "frame 1", "keep one"),
       _times_beside(_increasing(BASE_FRAMES)),
       note="one times.txt beside frames/ alone is used"),
    _c("groundtruth-other-seq", "sequence", "--groundtruth of another sequence (its times)",
       (*T, "{seq}", *OUT, "--groundtruth", "{tmp}/gt.tum"), 2,
       ("gt.tum", "timestamps", "ground truth of these frames"), _groundtruth_shifted,
       note="one matching only some frames is drawn for those, with a warning"),
    # --- init.yaml ---------------------------------------------------------------------
    _c("init-missing", "init.yaml", "-p names a file that does not exist",
       (*T, "{seq}", "-p", "{tmp}/missing.yaml", *OUT), 2, ("missing.yaml", "cannot read",
                                                           "no such file")),
    _c("init-directory", "init.yaml", "-p names a directory",
       (*T, "{seq}", "-p", "{tmp}", *OUT), 2, ("is a directory", "init.yaml file")),
    _c("init-not-yaml", "init.yaml", "not YAML (unclosed bracket)",
       TRACK_INIT, 2, ("init.yaml", "not valid YAML", "line"), _yaml_text("camera: [1, 2\n")),
    _c("init-empty", "init.yaml", "an empty file", TRACK_INIT, 2, ("init.yaml", "empty",
                                                                   "camera:", "ground:"),
       _yaml_text("")),
    _c("init-list", "init.yaml", "not a mapping (a list)", TRACK_INIT, 2,
       ("expected a mapping", "a list"), _yaml_text("- camera\n- ground\n")),
    _c("init-scalar", "init.yaml", "not a mapping (plain text)", TRACK_INIT, 2,
       ("expected a mapping",), _yaml_text("hello world\n")),
    _c("init-no-camera", "init.yaml", "no camera section", TRACK_INIT, 2,
       ("missing 'camera'", "camera_file"), _yaml_text("ground: {" + _NORMAL + ", distance: 1.5}\n")),
    _c("init-no-ground", "init.yaml", "no ground section", TRACK_INIT, 2,
       ("missing 'ground'",), _yaml_text(_CAMERA)),
    _c("init-unknown-top", "init.yaml", "unknown top-level key (grund)", TRACK_INIT, 2,
       ("unknown key 'grund'", "did you mean 'ground'"), _yaml_edit(("ground:", "grund:"))),
    _c("init-unknown-camera", "init.yaml", "unknown camera key (fxx)", TRACK_INIT, 2,
       ("unknown key 'camera.fxx'", "did you mean 'fx'"), _yaml_edit(("fx:", "fxx:"))),
    _c("init-unknown-ground", "init.yaml", "unknown ground key (normals)", TRACK_INIT, 2,
       ("unknown key 'ground.normals'", "did you mean 'normal'"),
       _yaml_edit(("normal:", "normals:"))),
    _c("init-duplicate-key", "init.yaml", "a key given twice", TRACK_INIT, 2,
       ("given twice", "line"), _yaml_edit(("  fy:", "  fx: 1.0\n  fy:"))),
    _c("init-fx-text", "init.yaml", "non-numeric value (fx: abc)", TRACK_INIT, 2,
       ("camera.fx", "must be a number", "'abc'"), _yaml_edit(("fx: 111.36", "fx: abc"))),
    _c("init-fx-nan", "init.yaml", "NaN value (fx: .nan)", TRACK_INIT, 2,
       ("camera.fx", "finite"), _yaml_edit(("fx: 111.36", "fx: .nan"))),
    _c("init-fx-inf", "init.yaml", "infinite value (fx: .inf)", TRACK_INIT, 2,
       ("camera.fx", "finite"), _yaml_edit(("fx: 111.36", "fx: .inf"))),
    _c("init-fx-zero", "init.yaml", "fx = 0", TRACK_INIT, 2, ("camera.fx", "> 0", "got 0"),
       _yaml_edit(("fx: 111.36", "fx: 0"))),
    _c("init-fy-negative", "init.yaml", "fy < 0", TRACK_INIT, 2, ("camera.fy", "> 0", "-111.36"),
       _yaml_edit(("fy: 111.36", "fy: -111.36"))),
    _c("init-width-fraction", "init.yaml", "width not a whole number", TRACK_INIT, 2,
       ("camera.width", "whole number"), _yaml_edit(("width: 128", "width: 128.5"))),
    _c("init-cx-missing", "init.yaml", "camera.cx missing", TRACK_INIT, 2,
       ("camera.cx is missing",), _yaml_edit(("  cx: 63.5\n", ""))),
    _c("init-distortion-length", "init.yaml", "distortion with 3 coefficients", TRACK_INIT, 2,
       ("camera.distortion", "4, 5 or 8"),
       _yaml_edit(("  distortion: [0.0, 0.0, 0.0, 0.0, 0.0]", "  distortion: [0, 0, 0]"))),
    _c("init-normal-zero", "init.yaml", "ground normal of zero length", TRACK_INIT, 2,
       ("ground.normal", "zero-length", "unit normal"), _ground("normal: [0, 0, 0], distance: 1.5")),
    _c("init-normal-not-unit", "init.yaml", "ground normal not of unit length", TRACK_INIT, 0,
       ("ground.normal", "normalised"), _ground("normal: [0, 1, 1], distance: 1.5"),
       note="normalised, with a warning"),
    _c("init-normal-text", "init.yaml", "ground normal with a non-number", TRACK_INIT, 2,
       ("ground.normal[1]", "must be a number"), _ground("normal: [0, x, 1], distance: 1.5")),
    _c("init-normal-short", "init.yaml", "ground normal with 2 numbers", TRACK_INIT, 2,
       ("ground.normal", "3 numbers"), _ground("normal: [0, 1], distance: 1.5")),
    _c("init-distance-zero", "init.yaml", "distance = 0", TRACK_INIT, 2,
       ("ground.distance", "> 0"), _yaml_edit(("distance: 1.5", "distance: 0"))),
    _c("init-distance-negative", "init.yaml", "distance < 0", TRACK_INIT, 2,
       ("ground.distance", "> 0", "-1.5"), _yaml_edit(("distance: 1.5", "distance: -1.5"))),
    _c("init-plane-behind", "init.yaml", "plane behind the camera (normal points away)",
       TRACK_INIT, 2, ("not in front of the camera", "check normal"),
       _ground("normal: [0, -0.7071067811865476, -0.7071067811865475], distance: 1.5")),
    _c("init-plane-parallel", "init.yaml", "plane parallel to the optical axis (normal z = 0)",
       TRACK_INIT, 2, ("not visible in region", "ground.region"),
       _ground("normal: [0, 1, 0], distance: 1.5")),
    _c("init-plane-horizon", "init.yaml", "plane not seen in part of the region (horizon in view)",
       TRACK_INIT, 2, ("not visible in region", "ground.region"),
       _ground("normal: [0, 0.9961946980917455, 0.08715574274765817], distance: 1.5")),
    _c("init-region-outside", "init.yaml", "region outside the image", TRACK_INIT, 2,
       ("ground.region", "outside the 128x128 image"),
       _yaml_edit(("region: [0, 0, 128, 128]", "region: [0, 64, 128, 200]"))),
    _c("init-region-inverted", "init.yaml", "region inverted (x1 < x0)", TRACK_INIT, 2,
       ("ground.region", "inverted", "x0 < x1"),
       _yaml_edit(("region: [0, 0, 128, 128]", "region: [100, 0, 20, 128]"))),
    _c("init-region-tiny", "init.yaml", "region under 1 % of the image", TRACK_INIT, 2,
       ("ground.region", "at least 1%"),
       _yaml_edit(("region: [0, 0, 128, 128]", "region: [0, 0, 10, 10]"))),
    _c("init-region-short", "init.yaml", "region of 3 numbers", TRACK_INIT, 2,
       ("ground.region", "4 whole numbers"),
       _yaml_edit(("region: [0, 0, 128, 128]", "region: [0, 0, 128]"))),
    _c("init-both-forms", "init.yaml", "both normal/distance and height/pitch_deg", TRACK_INIT, 2,
       ("both", "either normal + distance or height + pitch_deg"),
       _ground(_NORMAL + ", distance: 1.5, height: 1.5, pitch_deg: 45")),
    _c("init-height-only", "init.yaml", "height without pitch_deg", TRACK_INIT, 2,
       ("ground.pitch_deg is missing",), _ground("height: 1.5")),
    _c("init-pitch-range", "init.yaml", "pitch_deg out of range (200)", TRACK_INIT, 2,
       ("ground.pitch_deg", "(0, 180)", "200"), _ground("height: 1.5, pitch_deg: 200")),
    _c("init-camera-and-file", "init.yaml", "both camera and camera_file", TRACK_INIT, 2,
       ("either 'camera' or 'camera_file'",), _yaml_edit(("ground:", "camera_file: cam.yaml\nground:"))),
    _c("camera-file-missing", "init.yaml", "camera_file that does not exist", TRACK_INIT, 2,
       ("cam.yaml", "cannot read", "camera_file"), _camera_file(None)),
    _c("camera-file-not-info", "init.yaml", "camera_file that is not a camera_info", TRACK_INIT, 2,
       ("cam.yaml", "not a camera_info", "image_width"), _camera_file("just: [some, yaml]\n")),
    _c("camera-file-bad-matrix", "init.yaml", "camera_info with a 6-number camera_matrix",
       TRACK_INIT, 2, ("cam.yaml", "camera_matrix.data", "9 numbers"),
       _camera_file("image_width: 128\nimage_height: 128\ncamera_matrix: {rows: 3, cols: 3, "
                    "data: [1, 0, 64, 0, 1, 64]}\n")),
    # --- the ground model --------------------------------------------------------------
    _c("textureless-frame0", "ground model", "textureless first frame (constant grey)",
       TRACK_COPY, 2, ("observation points", "no threshold would give enough", "check the frame",
                       "another region"),
       _damage_frame(0, "constant"), note="no threshold helps, so none is suggested"),
    _c("threshold-too-high", "ground model", "--threshold above every gradient",
       (*T, "{seq}", *OUT, "--threshold", "1e9"), 2, ("observation points", "lower --threshold")),
    # --- outputs -------------------------------------------------------------------------
    _c("out-has-results", "outputs", "output directory already holds results",
       (*T, "{seq}", *OUT), 2, ("already holds results", "motion.csv", "--overwrite"),
       _results_exist),
    _c("out-not-writable", "outputs", "output directory not writable",
       (*T, "{seq}", "-o", "{tmp}/ro"), 2, ("not writable", "permission denied"), _read_only_dir,
       note="as root, where permissions do not bind, /sys stands in"),
    _c("out-failed-run", "outputs", "output directory holding a failed run's header-only "
       "motion.csv", (*T, "{seq}", *OUT), 0, ("tracked 6 frames",), _failed_run,
       note="no frame was tracked there: nothing to keep, so the rerun is not refused"),
    _c("out-is-file", "outputs", "-o names a file", (*T, "{seq}", "-o", "{tmp}/f.txt"), 2,
       ("f.txt", "not a directory", "give -o a directory"), _write("f.txt", "x")),
    _c("out-under-file", "outputs", "-o below a file (f.txt/out)",
       (*T, "{seq}", "-o", "{tmp}/f.txt/out"), 2, ("cannot create output directory",),
       _write("f.txt", "x")),
    _c("model-out-missing-dir", "outputs", "init -o into a directory that does not exist",
       ("init", "{seq}", "-o", "{tmp}/no/dir/model.npz"), 2, ("no/dir", "cannot write")),
    _c("out-disk-full", "outputs", "-o - into a full device (stdout is /dev/full)",
       (*T, "{seq}", "-o", "-"), 2, ("cannot write the outputs", "no space left", "free some space"),
       stdout_to="/dev/full"),
    _c("stdout-groundtruth", "outputs", "--groundtruth with -o - (nothing to draw it in)",
       (*T, "{seq}", "-o", "-", "--groundtruth", "{seq}/groundtruth.tum"), 2,
       ("--groundtruth", "trajectory.png", "-o DIR")),
    _c("stdout-terrain-out", "outputs", "--terrain-out with -o - (it writes files)",
       (*T, "{seq}", "-o", "-", "--terrain-out"), 2, ("--terrain-out", "-o DIR")),
    _c("covariance-no-dir", "outputs", "--covariance in a directory that does not exist",
       (*T, "{seq}", *OUT, "--covariance", "{tmp}/no/cov.csv"), 2,
       ("no/cov.csv", "no such directory"),
       note="checked before anything is written: no output folder is left behind"),
    _c("covariance-dash", "outputs", "--covariance - (stdout)",
       (*T, "{seq}", *OUT, "--covariance", "-"), 2, ("--covariance -", "not streamed")),
    _c("model-out-exists", "outputs", "init -o names an existing model (no --overwrite)",
       ("init", "{seq}", "-o", "{tmp}/model.npz"), 2, ("model.npz", "already exists",
                                                      "--overwrite"), _model_of()),
    _c("model-missing", "outputs", "--model file does not exist",
       (*T, "{seq}", *OUT, "--model", "{tmp}/model.npz"), 2, ("model.npz", "cannot read model")),
    _c("model-not-model", "outputs", "--model is not a model (init.yaml)",
       (*T, "{seq}", *OUT, "--model", "{seq}/init.yaml"), 2, ("init.yaml", "monovo init")),
    _c("model-other-size", "outputs", "--model built for frames of another size",
       (*T, "{seq}", *OUT, "--model", "{tmp}/model.npz"), 2, ("model.npz", "96x96", "128x128", "monovo init"),
       _model_other_size),
    _c("model-other-seq", "outputs", "--model built from another sequence's frame 0",
       (*T, "{seq}", *OUT, "--model", "{tmp}/model.npz"), 2,
       ("model.npz", "another frame 0", "monovo init"), _model_of(other_seed=9)),
    _c("model-other-plane", "outputs", "--model built with another init.yaml (plane)",
       (*T, "{seq}", *P, *OUT, "--model", "{tmp}/model.npz"), 2,
       ("model.npz", "another ground plane", "init.yaml"),
       _all(_model_of(), _yaml_edit(("distance: 1.5", "distance: 1.6")))),
    _c("model-other-options", "outputs", "--model with another --max-points than init's",
       (*T, "{seq}", *OUT, "--model", "{tmp}/model.npz", "--max-points", "600"), 2,
       ("--max-points 600", "differs from the model's (500)", "monovo init"),
       _model_of(max_points=500)),
    # --- usage ---------------------------------------------------------------------------
    _c("usage-no-output", "usage", "track without -o", (*T, "{seq}"), 2,
       ("missing option", "-o")),
    _c("usage-threshold-negative", "usage", "--threshold -1", (*T, "{seq}", *OUT, "--threshold", "-1"),
       2, ("--threshold", "-1")),
    _c("usage-max-points-word", "usage", "--max-points neither a number nor 'all'",
       (*T, "{seq}", *OUT, "--max-points", "lots"), 2, ("--max-points", "'all'", "lots")),
    _c("usage-max-points-small", "usage", "--max-points 10 (below 50)",
       (*T, "{seq}", *OUT, "--max-points", "10"), 2, ("--max-points", "minimum 50")),
    _c("usage-unknown-option", "usage", "an unknown option (--fast)", (*T, "{seq}", *OUT, "--fast"),
       2, ("no such option", "--fast")),
    _c("synth-bad-size", "usage", "synth --size 12", ("synth", "{tmp}/s", "--size", "12"), 2,
       ("--size", "WxH")),
    _c("config-unknown-key", "usage", "--config with an unknown key",
       (*T, "{seq}", *OUT, "--config", "{tmp}/monovo.yaml"), 2,
       ("monovo.yaml", "unknown key 'track.thresold'", "did you mean 'threshold'"),
       _write("monovo.yaml", "track:\n  thresold: 5\n")),
    _c("config-bad-value", "usage", "--config with a value the option refuses",
       (*T, "{seq}", *OUT, "--config", "{tmp}/monovo.yaml"), 2,
       ("monovo.yaml", "max-points", "minimum 50"), _write("monovo.yaml", "max-points: 10\n")),
    _c("synth-out-not-empty", "usage", "synth into a non-empty directory",
       ("synth", "{tmp}/s"), 2, ("already exists", "--overwrite"), _write("s/x.txt", "x")),
    # --- overlay -------------------------------------------------------------------------
    _c("overlay-traj-missing", "overlay", "-t names a file that does not exist",
       (*OV, "-t", "{tmp}/none.csv", "-o", "{tmp}/ov.mp4"), 2, ("none.csv", "no such file"),
       needs=("overlay",)),
    _c("overlay-traj-fewer-rows", "overlay", "a trajectory with fewer rows than frames",
       (*OV, *OV_T, "-o", "{tmp}/ov.mp4"), 0,
       ("trajectory.csv", "poses for 3 of the 6 frames", "no triangle", "frame 2"),
       _trajectory(lambda ls: ls[:4]), needs=("overlay",),
       note="rendered up to its last pose with a warning, not an error: the trajectory of an "
            "interrupted run is worth seeing; a trajectory that does not fit the sequence "
            "is an error (next rows)"),
    _c("overlay-traj-other-seq", "overlay", "a trajectory of another, longer sequence",
       (*OV, *OV_T, "-o", "{tmp}/ov.mp4"), 2, ("trajectory.csv", "frame 9", "6 frames"),
       _trajectory(lambda ls: [*ls, *(f"{k}," + ls[-1].split(",", 1)[1] for k in (6, 7, 8, 9))]),
       needs=("overlay",)),
    _c("overlay-traj-tum-times", "overlay", "a TUM trajectory whose timestamps are not the frames'",
       (*OV, "-t", "{tmp}/out/trajectory.tum", "-o", "{tmp}/ov.mp4"), 2,
       ("trajectory.tum", "timestamp", "matches no frame"),
       _trajectory(_shift_times, "trajectory.tum"), needs=("overlay",)),
    _c("overlay-traj-is-motion", "overlay", "-t names motion.csv, not a trajectory",
       (*OV, "-t", "{tmp}/out/motion.csv", "-o", "{tmp}/ov.mp4"), 2,
       ("motion.csv", "header"), _tracked_setup,
       needs=("overlay",)),
    _c("overlay-traj-bad-row", "overlay", "a trajectory row with a non-number",
       (*OV, *OV_T, "-o", "{tmp}/ov.mp4"), 2, ("trajectory.csv", "line 3", "expected numbers"),
       _trajectory(_set_field(2, 3, "abc", ",")), needs=("overlay",)),
    _c("overlay-bad-extension", "overlay", "an unknown output extension (.avi)",
       (*OV, *OV_T, "-o", "{tmp}/ov.avi"), 2, ("ov.avi",), _tracked_setup, needs=("overlay",)),
    _c("overlay-out-exists", "overlay", "the output exists (no --overwrite)",
       (*OV, *OV_T, "-o", "{tmp}/ov.mp4"), 2, ("ov.mp4", "--overwrite"),
       _all(_tracked_setup, _write("ov.mp4", "x")), needs=("overlay",)),
    _c("overlay-bad-scale", "overlay", "--scale 0",
       (*OV, *OV_T, "-o", "{tmp}/ov.gif", "--scale", "0"), 2, ("--scale", "0"),
       needs=("overlay",)),
    _c("overlay-bad-triangle", "overlay", "--triangle with 3 numbers",
       (*OV, *OV_T, "-o", "{tmp}/ov.mp4", "--triangle", "1,2,3"), 2, ("--triangle", "6 numbers"),
       _tracked_setup, needs=("overlay",)),
    # --- eval ----------------------------------------------------------------------------
    _c("eval-missing", "eval", "the estimate does not exist",
       ("eval", "{tmp}/none.tum", "{seq}/groundtruth.tum"), 2, ("none.tum", "cannot read",
                                                             "no such file"),
       needs=("eval",)),
    _c("eval-other-times", "eval", "no timestamp within --max-dt of the other file's",
       ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"), 2, ("timestamps", "within 0.02 s",
                                                             "--max-dt"),
       _tum_pair(_shift_times), needs=("eval",)),
    _c("eval-row-short", "eval", "a row of 7 numbers", ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"),
       2, ("est.tum", "line 3", "expected 8 numbers"),
       _tum_pair(lambda ls: [*ls[:2], " ".join(ls[2].split()[:7]), *ls[3:]]), needs=("eval",)),
    _c("eval-row-text", "eval", "a row with a non-number", ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"),
       2, ("est.tum", "line 2", "expected numbers"), _tum_pair(_set_field(1, 2, "x")),
       needs=("eval",)),
    _c("eval-row-nan", "eval", "a row with nan", ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"),
       2, ("est.tum", "line 4", "non-finite"), _tum_pair(_set_field(3, 1, "nan")), needs=("eval",)),
    _c("eval-zero-quaternion", "eval", "a row with a zero quaternion",
       ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"), 2, ("est.tum", "line 2", "zero quaternion"),
       _tum_pair(lambda ls: [ls[0], " ".join(ls[1].split()[:4] + ["0"] * 4), *ls[2:]]),
       needs=("eval",)),
    _c("eval-empty", "eval", "an empty estimate", ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"),
       2, ("est.tum", "no poses"), _tum_pair(lambda ls: []), needs=("eval",)),
    _c("eval-csv-given", "eval", "trajectory.csv read as TUM (--format tum)",
       ("eval", "{tmp}/out/trajectory.csv", "{seq}/groundtruth.tum", "--format", "tum"), 2,
       ("trajectory.csv", "not a TUM trajectory", "use trajectory.tum"),
       _tracked_setup, needs=("eval",)),
    _c("eval-sparse-truth", "eval", "a ground truth matching 2 of the 6 poses",
       ("eval", "{tmp}/est.tum", "{tmp}/gt.tum"), 2,
       ("only 2 of its 6 poses", "--partial"),
       _all(_tum_pair(lambda ls: ls), _gt_lines(lambda ls: ls[::3])), needs=("eval",)),
    _c("eval-unknown-format", "eval", "a file of 5 numbers a line",
       ("eval", "{tmp}/est.txt", "{seq}/groundtruth.tum"), 2,
       ("est.txt", "cannot tell its format", "--format"),
       _write("est.txt", "0 0 0 0 1\n1 0 0 0 1\n"), needs=("eval",)),
    _c("eval-kitti-row-short", "eval", "a KITTI pose line of 11 numbers",
       ("eval", "{tmp}/est.txt", "{seq}/groundtruth.tum", "--format", "kitti"), 2,
       ("est.txt", "line 2", "expected 12 numbers"),
       _write("est.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n"),
       needs=("eval",)),
    _c("eval-times-count", "eval", "--times with fewer timestamps than poses",
       ("eval", "{tmp}/est.txt", "{seq}/groundtruth.tum", "--times", "{tmp}/times.txt"), 2,
       ("times.txt", "2 timestamps for 3 poses"),
       _all(_write("est.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n" * 3), _write("times.txt", "0\n1\n")),
       needs=("eval",)),
    _c("eval-duplicate-time", "eval", "a timestamp given twice",
       ("eval", "{tmp}/est.tum", "{seq}/groundtruth.tum"), 2, ("est.tum", "more than once"),
       _tum_pair(lambda ls: [*ls[:3], ls[2], *ls[3:]]), needs=("eval",)),
]


# ----------------------------------------------------------------------------- running


def substitute(args: tuple[str, ...], tmp: Path, seq: Path) -> list[str]:
    return [a.format(tmp=tmp, seq=seq, copy=tmp / "seq", init=tmp / "init.yaml") for a in args]


@contextlib.contextmanager
def _fresh_logging():
    """Let the CLI's logging.basicConfig bind to this run's stderr (CliRunner swaps it)."""
    root = logging.getLogger()
    saved, level = root.handlers[:], root.level
    for h in saved:
        root.removeHandler(h)
    try:
        yield
    finally:
        for h in root.handlers[:]:
            root.removeHandler(h)
        for h in saved:
            root.addHandler(h)
        root.setLevel(level)


def run_case(case: Case, tmp: Path, seq: Path) -> Outcome:
    """Prepare ``case`` in the empty directory ``tmp`` and run it through the CLI in-process."""
    from click.testing import CliRunner

    from monovo_cli.cli import main

    tmp = Path(tmp)
    if case.setup is not None:
        case.setup(tmp, seq)
    args = substitute(case.args, tmp, seq)
    if case.id == "out-not-writable" and os.geteuid() == 0:
        args[args.index(str(tmp / "ro"))] = "/sys"
    if case.stdout_to is not None:
        import subprocess
        import sys

        with open(case.stdout_to, "w") as out:
            proc = subprocess.run([sys.executable, "-m", "monovo_cli", *args], stdout=out,
                                  stderr=subprocess.PIPE, text=True, timeout=300)
        return Outcome(proc.returncode, "", proc.stderr)
    try:
        runner = CliRunner(mix_stderr=False)
    except TypeError:  # click >= 8.2 always keeps stderr apart
        runner = CliRunner()
    try:
        with _fresh_logging():
            r = runner.invoke(main, args)
    finally:
        ro = tmp / "ro"
        if ro.exists():
            ro.chmod(0o755)
    return Outcome(r.exit_code, r.stdout, r.stderr)
