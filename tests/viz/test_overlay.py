"""The glued triangle, the video writers and the trajectory plot.

The accuracy bound (< 1 px) is the issue's acceptance criterion; on this short drive the
vertices stay within ~0.1 px (docs/benchmarks.md has the 300-frame figure).
"""

from pathlib import Path

import cv2
import imageio.v2 as iio
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.options import TrackOptions
from monovo_cli.errors import InputError, OutputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, pose_from_vectors
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_trajectory_csv, read_tum
from monovo_cli.io.video import open_sink, output_kind, pad_to_even
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.synth.write import synthesize
from monovo_cli.viz.overlay import (
    OverlayRenderer,
    clip_polygon,
    default_triangle_pixels,
    draw_polygon,
    lift_pixels,
    project_polygon,
    triangle_on_ground,
    vertex_errors,
)
from monovo_cli.viz.plots import on_plane, plot_trajectory


@pytest.fixture(scope="module")
def tracked(synth_drive, tmp_path_factory):
    seq = synth_drive(preset="drive", frames=40, size=(256, 256), noise_var=10.0, seed=7)
    out = tmp_path_factory.mktemp("overlay") / "out"
    track_sequence(seq, None, out, TrackOptions())
    return seq, out


def _setup(seq: Path):
    cfg = load_init(seq / "init.yaml")
    plane = cfg.plane
    return cfg, plane, cfg.region


def test_triangle_stays_glued_within_a_pixel(tracked):
    seq, out = tracked
    cfg, plane, region = _setup(seq)
    tri = triangle_on_ground(cfg.camera, plane, None, region)
    _, _, est = read_trajectory_csv(out / "trajectory.csv")
    _, gt = read_tum(seq / "groundtruth.tum")
    err = vertex_errors(cfg.camera, tri, est, gt)
    seen = np.isfinite(err)
    assert seen[0].all() and seen.any(axis=1).sum() >= 20  # in view for half the drive at least
    assert err[seen].max() < 1.0, err[seen].max()


def test_default_triangle_is_equilateral_in_the_region_and_on_the_plane(tracked):
    seq, _ = tracked
    cfg, plane, region = _setup(seq)
    uv = default_triangle_pixels(region)
    sides = np.linalg.norm(uv - np.roll(uv, 1, axis=0), axis=1)
    np.testing.assert_allclose(sides, min(region[2] - region[0], region[3] - region[1]) / 3)
    np.testing.assert_allclose(uv.mean(axis=0), [(region[0] + region[2] - 1) / 2,
                                                 (region[1] + region[3] - 1) / 2])
    X = triangle_on_ground(cfg.camera, plane, uv)
    np.testing.assert_allclose(X @ plane.normal, plane.distance)
    np.testing.assert_allclose(cfg.camera.project(X), uv, atol=1e-9)


def test_pixels_above_the_horizon_are_refused():
    cam = PinholeCamera(100, 100, 80.0, 80.0, 49.5, 49.5)
    plane = Plane(np.array([0.0, 1.0, 0.0]), 1.5)  # level camera: horizon at the middle row
    with pytest.raises(InputError, match=r"\(50, 20\) px: its viewing ray does not meet"):
        lift_pixels(cam, plane, np.array([[50.0, 80.0], [50.0, 20.0]]))
    with pytest.raises(InputError, match="on one line"):
        triangle_on_ground(cam, plane, np.array([[10.0, 80.0], [20.0, 80.0], [30.0, 80.0]]))


def test_clip_polygon_against_the_near_plane():
    square = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 3.0], [-1.0, 0.0, 3.0]])
    near = np.array([[0.0, 0.0, 1.0, -0.5]])  # z >= 0.5
    out = clip_polygon(square, near)
    assert len(out) == 4 and out[:, 2].min() == pytest.approx(0.5)
    assert sorted(out[:, 2].round(6)) == [0.5, 0.5, 3.0, 3.0]
    assert len(clip_polygon(square - [0, 0, 10], near)) == 0
    tri = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 2.0], [-1.0, 0.0, 2.0]])
    assert len(clip_polygon(tri, near)) == 4  # the tip cut off: a quadrilateral


def test_triangle_partly_behind_the_camera_is_clipped_and_drawn():
    cam = PinholeCamera(160, 120, 100.0, 100.0, 79.5, 59.5)
    plane = Plane(np.array([0.0, 1.0, 0.0]), 1.0)          # ground 1 m below a level camera
    tri = np.array([[0.0, 1.0, -2.0], [1.0, 1.0, 4.0], [-1.0, 1.0, 4.0]])  # tip behind
    uv = project_polygon(cam, tri, near=1e-3)
    assert len(uv) >= 4 and np.all(np.isfinite(uv))
    assert np.abs(uv).max() < 10 * cam.width                # clipped to the widened frustum
    assert len(project_polygon(cam, tri - [0, 0, 10], near=1e-3)) == 0  # all behind
    r = OverlayRenderer(cam, plane, tri, region=(0, 60, 160, 120))
    img = r.render(0, np.full((120, 160), 100.0, np.float32), np.eye(4))
    assert img.shape == (120, 160, 3)
    changed = np.any(img != 100, axis=2)
    changed[:20, :100] = False                               # the text line
    rows = np.nonzero(changed.any(axis=1))[0]
    assert rows.min() > 60 and rows.max() == 119            # from below the horizon to the bottom


def test_distorted_camera_edges_are_densified():
    cam = PinholeCamera(160, 120, 100.0, 100.0, 79.5, 59.5, (-0.2, 0.05, 0.0, 0.0, 0.0))
    tri = np.array([[0.0, 0.3, 2.0], [0.5, 0.5, 2.0], [-0.5, 0.5, 2.0]])
    uv = project_polygon(cam, tri, near=1e-3)
    assert len(uv) == 3 * 32
    np.testing.assert_allclose(uv[::32], cam.project(tri), atol=1e-9)


def test_drawing_is_subpixel():
    def centroid(dx: float) -> float:
        img = np.zeros((60, 60, 3), np.uint8)
        uv = np.array([[30.0, 10.0], [45.0, 40.0], [15.0, 40.0]]) + [dx, 0.0]
        draw_polygon(img, uv, fill=(255, 255, 255), outline=(255, 255, 255), alpha=1.0,
                     thickness=1)
        w = img[:, :, 0].astype(float)
        return float((w.sum(axis=0) * np.arange(60)).sum() / w.sum())

    base = centroid(0.0)
    for dx in (0.25, 0.5):
        assert centroid(dx) - base == pytest.approx(dx, abs=0.08)


def test_overlay_cli_writes_a_playable_mp4(tracked):
    seq, out = tracked
    video = out / "overlay.mp4"
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", str(out / "trajectory.csv"),
                                  "-o", str(video), "--points", "-q"])
    assert r.exit_code == 0, r.output
    reader = iio.get_reader(video)
    meta = reader.get_meta_data()
    frames = [f for f in reader]
    reader.close()
    assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    assert len(frames) == 40 and frames[0].shape == (256, 256, 3)
    # the triangle is there: orange-ish pixels in frame 0, none in the raw grey frame
    f0 = frames[0].astype(int)
    assert np.count_nonzero((f0[:, :, 0] - f0[:, :, 2]) > 60) > 500
    assert not list(out.glob(".*partial*"))
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", str(out / "trajectory.csv"),
                                  "-o", str(video)])
    assert r.exit_code == 2 and "already exists" in r.output and "--overwrite" in r.output


def test_overlay_gif_and_png_directory_with_odd_size(tmp_path):
    synthesize(tmp_path / "s", preset="drive", frames=3, size=(101, 77), seed=1)
    traj = tmp_path / "s" / "groundtruth.tum"  # a TUM file works as -t too
    gif = tmp_path / "o.gif"
    r = CliRunner().invoke(main, ["overlay", str(tmp_path / "s"), "-t", str(traj), "-o", str(gif),
                                  "--triangle", "50,40,70,70,30,70", "-q"])
    assert r.exit_code == 0, r.output
    frames = iio.mimread(gif)
    assert len(frames) == 3 and frames[0].shape[:2] == (77, 101)
    pngs = tmp_path / "pngs"
    r = CliRunner().invoke(main, ["overlay", str(tmp_path / "s"), "-t", str(traj), "-o",
                                  str(pngs) + "/", "-q"])
    assert r.exit_code == 0, r.output
    files = sorted(pngs.glob("*.png"))
    assert [f.name for f in files] == ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    assert cv2.imread(str(files[0])).shape == (77, 101, 3)
    mp4 = tmp_path / "o.mp4"
    r = CliRunner().invoke(main, ["overlay", str(tmp_path / "s"), "-t", str(traj), "-o", str(mp4),
                                  "-q"])
    assert r.exit_code == 0, r.output
    first = iio.get_reader(mp4).get_data(0)
    assert first.shape == (78, 102, 3)  # padded to even for H.264 4:2:0
    assert pad_to_even(np.zeros((77, 101, 3), np.uint8)).shape == (78, 102, 3)


def test_overlay_cli_bad_input_exit_2(tracked, tmp_path):
    seq, out = tracked
    traj = str(out / "trajectory.csv")
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(tmp_path / "a.mp4"),
                                  "--triangle", "1,2,3"])
    assert r.exit_code == 2 and "'1,2,3'" in r.output
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(tmp_path / "a.avi")])
    assert r.exit_code == 2 and "expected .mp4, .gif, or a directory" in r.output
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(tmp_path / "a.mp4"),
                                  "--triangle", "10,5,20,5,30,5"])
    assert r.exit_code == 2 and "on one line" in r.output
    bad = tmp_path / "t.csv"
    bad.write_text("frame,timestamp,tx,ty,tz,qx,qy,qz,qw\n0,0,0,0,0,0,0,0,1\n99,99,0,0,0,0,0,0,1\n")
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", str(bad), "-o", str(tmp_path / "a.mp4")])
    assert r.exit_code == 2 and "has frame 99" in r.output
    assert not (tmp_path / "a.mp4").exists()


def test_sink_refuses_existing_output_and_cleans_up_on_abort(tmp_path):
    assert output_kind(tmp_path / "x.MP4") == "mp4" and output_kind(tmp_path / "frames") == "png"
    (tmp_path / "x.gif").write_bytes(b"old")
    with pytest.raises(OutputError, match="already exists"):
        open_sink(tmp_path / "x.gif")
    sink = open_sink(tmp_path / "x.gif", overwrite=True)
    sink.write(np.zeros((8, 8, 3), np.uint8))
    sink.abort()
    assert (tmp_path / "x.gif").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.gif"]


def test_renderer_points_and_text(tracked):
    seq, out = tracked
    cfg, plane, region = _setup(seq)
    tri = triangle_on_ground(cfg.camera, plane, None, region)
    r = OverlayRenderer(cfg.camera, plane, tri, region=region, points=True)
    from monovo_cli.io.sources import open_frames

    img0 = open_frames(seq).read(0).image
    a = r.render(0, img0, np.eye(4), status="start", last=39)
    b = OverlayRenderer(cfg.camera, plane, tri, region=region).render(0, img0, np.eye(4))
    green = (a[:, :, 1].astype(int) - a[:, :, 2]) > 80
    assert green.sum() > 200 and ((b[:, :, 1].astype(int) - b[:, :, 2]) > 80).sum() == 0
    nopose = r.render(5, img0, None, last=39)
    assert not np.any((nopose[:, :, 2].astype(int) - nopose[:, :, 0]) > 60)  # no triangle


def test_track_writes_trajectory_png_with_groundtruth(tmp_path):
    synthesize(tmp_path / "s", preset="drive", frames=6, size=(96, 96), seed=2)
    gt = tmp_path / "s" / "groundtruth.tum"
    r = CliRunner().invoke(main, ["track", str(tmp_path / "s"), "-o", str(tmp_path / "o"),
                                  "--groundtruth", str(gt), "-q"])
    assert r.exit_code == 0, r.output
    img = cv2.imread(str(tmp_path / "o" / "trajectory.png"))
    assert img.shape == (800, 800, 3)
    assert np.count_nonzero(np.any(img < 200, axis=2)) > 2000
    assert not list((tmp_path / "o").glob(".*tmp"))
    r = CliRunner().invoke(main, ["track", str(tmp_path / "s"), "-o", str(tmp_path / "o2"),
                                  "--groundtruth", str(tmp_path / "nope.tum")])
    assert r.exit_code == 2 and "nope.tum" in r.output
    assert not (tmp_path / "o2" / "motion.csv").exists()


def test_plot_plane_coordinates_and_markers():
    plane = Plane(np.array([0.0, np.cos(np.radians(45)), np.sin(np.radians(45))]), 1.5)
    fwd = np.array([0.0, -1.0, 1.0]) / np.sqrt(2)
    poses = [make_pose(np.eye(3), fwd * 0.1 * k + np.array([0.02 * k, 0, 0])) for k in range(30)]
    p = on_plane(np.array([T[:3, 3] for T in poses]), plane)
    np.testing.assert_allclose(p[:, 1], 0.1 * np.arange(30), atol=1e-12)   # forward is up
    np.testing.assert_allclose(p[:, 0], 0.02 * np.arange(30), atol=1e-12)  # camera x is right
    statuses = ["ok"] * 30
    statuses[10], statuses[20] = "reanchored", "lost"
    gt = np.array([pose_from_vectors(T[:3, 3] * 1.05, np.zeros(3)) for T in poses])
    img = plot_trajectory(np.array(poses), plane, statuses=statuses, groundtruth=gt,
                          title="t", size=(640, 480))
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    orange = (img[:, :, 2].astype(int) > 200) & (img[:, :, 1] > 100) & (img[:, :, 1] < 190) \
        & (img[:, :, 0] < 60)
    assert orange.sum() > 10  # the keyframe marker (and its legend entry)
    still = plot_trajectory(np.array([np.eye(4), np.eye(4)]), plane)  # no motion: no crash
    assert still.shape == (800, 800, 3)


# ----------------------------------------------------------------------------- a whole drive


@pytest.fixture(scope="module")
def long_drive(tmp_path_factory):
    """A 120-frame drive: the first triangle leaves the view after ~40 frames."""
    root = tmp_path_factory.mktemp("long")
    synthesize(root / "seq", preset="drive", frames=120, size=(192, 192), noise_var=10.0, seed=3)
    track_sequence(root / "seq", None, root / "out", TrackOptions())
    return root / "seq", root / "out"


def _orange(bgr: np.ndarray) -> int:
    """Pixels of the triangle's orange fill in a BGR frame."""
    return int(np.count_nonzero(bgr[:, :, 2].astype(int) - bgr[:, :, 0] > 60))


@pytest.mark.parametrize("trajectory", ["out/trajectory.csv", "seq/groundtruth.tum"])
def test_every_frame_of_a_long_drive_shows_a_triangle(long_drive, tmp_path, trajectory):
    """With motion.csv (keyframes known) and without it (a TUM file: re-placed when the
    triangle leaves the view)."""
    seq, out = long_drive
    cfg, plane, region = _setup(seq)
    first = triangle_on_ground(cfg.camera, plane, None, region)
    _, gt = read_tum(seq / "groundtruth.tum")
    assert np.isnan(vertex_errors(cfg.camera, first, gt, gt)[60:]).all()  # the first one is gone
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", str(seq.parent / trajectory),
                                  "-o", str(tmp_path / "png") + "/", "-q"])
    assert r.exit_code == 0, r.output
    files = sorted((tmp_path / "png").glob("*.png"))
    assert len(files) == 120
    counts = [_orange(cv2.imread(str(f))) for f in files]
    side = min(region[2] - region[0], region[3] - region[1]) / 3
    assert min(counts) > 0.15 * side ** 2 * np.sqrt(3) / 4, (int(np.argmin(counts)), min(counts))


def test_scaled_and_every_nth_outputs_have_the_right_size_and_count(long_drive, tmp_path):
    seq, out = long_drive
    traj = str(out / "trajectory.csv")
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(tmp_path / "png") + "/",
                                  "--scale", "0.5", "--every", "3"])
    assert r.exit_code == 0, r.output
    assert "wrote 40 frames" in r.output and "triangles)" in r.output
    files = sorted((tmp_path / "png").glob("*.png"))
    assert len(files) == 40 and files[-1].name == "frame_000039.png"
    frames = [cv2.imread(str(f)) for f in files]
    assert all(f.shape == (96, 96, 3) for f in frames)
    assert min(_orange(f) for f in frames) > 50  # a triangle in each, at a quarter of the area
    gif = tmp_path / "o.gif"
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(gif), "-q",
                                  "--scale", "0.25", "--every", "7"])
    assert r.exit_code == 0, r.output
    frames = iio.mimread(gif)
    assert len(frames) == 18 and frames[0].shape[:2] == (48, 48)  # frames 0, 7, ..., 119
    r = CliRunner().invoke(main, ["overlay", str(seq), "-t", traj, "-o", str(gif), "--overwrite",
                                  "--scale", "1.5"])
    assert r.exit_code == 2 and "--scale" in r.output


def test_a_new_triangle_at_each_keyframe_and_when_the_old_one_leaves_the_view(tracked):
    seq, out = tracked
    cfg, plane, region = _setup(seq)
    px = default_triangle_pixels(region)
    tri = triangle_on_ground(cfg.camera, plane, px, region)
    r = OverlayRenderer(cfg.camera, plane, tri, region=region, pixels=px)
    T = pose_from_vectors(np.r_[0.0, 0.0, 0.05], np.zeros(3))
    assert r.visible(np.eye(4)) == pytest.approx(1.0)
    assert not r.advance(T, "ok") and r.triangles == 1
    assert r.advance(T, "reanchored") and r.triangles == 2
    # the new triangle sits at the same pixels in the keyframe
    outline = r.triangle_outline(T)
    np.testing.assert_allclose(np.sort(outline, axis=0), np.sort(px, axis=0), atol=1e-6)
    ahead = np.cross([1.0, 0.0, 0.0], plane.normal)  # forward along the ground
    far = pose_from_vectors(3.0 * ahead / np.linalg.norm(ahead), np.zeros(3))  # walked past it
    assert r.visible(far) < 0.5 and r.advance(far, "ok") and r.visible(far) == pytest.approx(1.0)
    assert "new triangle" in _text_of(r, seq, far)
    up = pose_from_vectors(np.zeros(3), np.radians([80.0, 0.0, 0.0]))  # looking at the sky
    kept = r.triangle.copy()
    assert not r.advance(up, "reanchored")
    np.testing.assert_array_equal(r.triangle, kept)
    assert not OverlayRenderer(cfg.camera, plane, tri).advance(far, "reanchored")  # no pixels


def _text_of(renderer, seq, pose):
    """The text line is drawn, not returned: render twice and compare the band."""
    from monovo_cli.io.sources import open_frames

    img = open_frames(seq).read(0).image
    a = renderer.render(1, img, pose)
    b = renderer.render(1, img, pose)  # "new triangle" only once
    return "new triangle" if not np.array_equal(a[:20], b[:20]) else ""


def test_a_wrong_height_does_not_show_in_the_overlay_only_in_the_lengths(small_drive, tmp_path):
    """Monocular scale ambiguity (docs/guide.md, "init.yaml for a real camera"): with the
    height doubled every translation doubles and the overlay is pixel-identical."""
    init = (small_drive / "init.yaml").read_text()
    assert "distance: 1.5" in init
    frames, paths = {}, {}
    for height in ("1.5", "3.0"):
        params = tmp_path / f"init_{height}.yaml"
        params.write_text(init.replace("distance: 1.5", f"distance: {height}"))
        out, pngs = tmp_path / f"out_{height}", tmp_path / f"overlay_{height}"
        r = CliRunner().invoke(main, ["track", str(small_drive), "-p", str(params), "-o",
                                      str(out), "-q"])
        assert r.exit_code == 0, r.output
        r = CliRunner().invoke(main, ["overlay", str(small_drive), "-p", str(params), "-t",
                                      str(out / "trajectory.csv"), "-o", f"{pngs}/", "-q",
                                      "--points"])
        assert r.exit_code == 0, r.output
        frames[height] = [f.read_bytes() for f in sorted(pngs.glob("*.png"))]
        paths[height] = read_tum(out / "trajectory.tum")[1][:, :3, 3]
    assert len(frames["1.5"]) == 10
    assert frames["1.5"] == frames["3.0"]
    np.testing.assert_allclose(paths["3.0"], 2 * paths["1.5"], atol=1e-9)
