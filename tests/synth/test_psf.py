"""``synth --psf``: the optics' Gaussian blur before the pixel.

Without it (or at 0) the renders are those of before the option, byte for byte; with it the
supersampled image is blurred before each pixel averages its area, the ground beyond the
field of view blurring into the border pixels; a bad value is one line naming --psf.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from monovo_cli import synth
from monovo_cli.cli import main
from monovo_cli.errors import InputError
from monovo_cli.synth.render import (
    SUPERSAMPLE,
    GroundRenderer,
    PsfRenderer,
    padded_camera,
    plane_homography,
)

SMALL = (128, 96)


def run(*args) -> tuple[int, str]:
    r = CliRunner().invoke(main, [str(a) for a in args])
    return r.exit_code, r.output


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _frames(root: Path) -> list[np.ndarray]:
    return [cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float64)
            for p in sorted(root.rglob("frame_*.png"))]


def _gradient_energy(img: np.ndarray) -> float:
    return float(np.mean(np.diff(img, axis=1) ** 2) + np.mean(np.diff(img, axis=0) ** 2))


def test_psf_zero_is_the_render_without_the_option(tmp_path):
    kw = dict(preset="drive", frames=3, size=SMALL, seed=11, shadow=0.25)
    synth.synthesize(tmp_path / "omitted", **kw)
    synth.synthesize(tmp_path / "zero", psf=0.0, **kw)
    omitted = _files(tmp_path / "omitted")
    assert omitted == _files(tmp_path / "zero")
    assert "psf" not in yaml.safe_load(omitted["synth.yaml"])


def test_psf_blurs_the_frames(tmp_path):
    kw = dict(preset="pairs", frames=2, size=SMALL, seed=3, texture="gravel", noise_var=0.0)
    synth.synthesize(tmp_path / "sharp", **kw)
    synth.synthesize(tmp_path / "soft", psf=0.7, **kw)
    assert yaml.safe_load((tmp_path / "soft" / "synth.yaml").read_text())["psf"] == 0.7
    assert yaml.safe_load((tmp_path / "soft" / "pair_0001" / "synth.yaml").read_text())["psf"] == 0.7
    for sharp, soft in zip(_frames(tmp_path / "sharp"), _frames(tmp_path / "soft")):
        assert _gradient_energy(soft) < 0.5 * _gradient_energy(sharp)
        assert abs(soft.mean() - sharp.mean()) < 1.0  # a blur moves no light
    # same poses: the ground truth does not depend on the optics
    for name in ("pair_0000/groundtruth_motion.csv", "pair_0001/init.yaml"):
        assert (tmp_path / "sharp" / name).read_bytes() == (tmp_path / "soft" / name).read_bytes()


def _view():
    cam = synth.default_camera(96, 64)
    tex = synth.GroundTexture(synth.gravel_texture(256, 5, metres_per_texel=0.03), 0.03)
    g = np.eye(4)
    g[:3, :3] = synth.body_from_camera(np.radians(50.0))
    g[:3, 3] = [1.0, 2.0, 3.0]
    return cam, tex, g


def test_psf_acts_before_the_pixel():
    """The image equals the supersampled render of a camera SUPERSAMPLE times finer,
    blurred by sigma * SUPERSAMPLE supersamples, then area-averaged (away from the border,
    where that construction lacks the ground beyond the field of view)."""
    cam, tex, g = _view()
    sigma, s = 0.6, SUPERSAMPLE
    img = PsfRenderer(cam, lambda c: GroundRenderer(c, tex), sigma).render(g)
    fine_cam = replace(cam, width=cam.width * s, height=cam.height * s, fx=cam.fx * s,
                       fy=cam.fy * s, cx=cam.cx * s + (s - 1) / 2.0, cy=cam.cy * s + (s - 1) / 2.0)
    fine = GroundRenderer(fine_cam, tex, supersample=1).render(g)
    want = cv2.resize(cv2.GaussianBlur(fine, (0, 0), sigma * s), (cam.width, cam.height),
                      interpolation=cv2.INTER_AREA)
    assert img.shape == (cam.height, cam.width) and img.dtype == np.float32
    np.testing.assert_allclose(img[4:-4, 4:-4], want[4:-4, 4:-4], atol=0.1)  # (mip levels)
    # Blurring the finished pixels instead is another image: the aliasing is already in them.
    after = cv2.GaussianBlur(GroundRenderer(cam, tex).render(g), (0, 0), sigma)
    assert np.abs(after - img)[4:-4, 4:-4].mean() > 0.8


def test_psf_border_pixels_see_beyond_the_field_of_view():
    """The border pixels are those of a larger camera's image cropped to this one's."""
    cam, tex, g = _view()
    make = lambda c: GroundRenderer(c, tex)  # noqa: E731
    img = PsfRenderer(cam, make, 0.8).render(g)
    big = PsfRenderer(padded_camera(cam, 7), make, 0.8).render(g)[7:-7, 7:-7]
    np.testing.assert_allclose(img, big, atol=0.02)
    assert np.allclose(plane_homography(padded_camera(cam, 7), g)[:2],
                       plane_homography(cam, g)[:2] + 7 * plane_homography(cam, g)[2])


def test_psf_on_terrain_with_shadow(tmp_path):
    """The ray-cast renderer takes the blur too, and the camera-fixed shadow lies on the
    ground, under the blur: its edge is spread over rows instead of a one-row step."""
    kw = dict(preset="drive", frames=2, size=(64, 48), seed=2, terrain="flat", noise_var=0.0,
              shadow=0.5, texture=None)
    synth.synthesize(tmp_path / "sharp", **kw)
    synth.synthesize(tmp_path / "soft", psf=1.5, **kw)
    sharp, soft = (_frames(tmp_path / d)[1].mean(axis=1) for d in ("sharp", "soft"))
    edge = 24  # the first shadowed row
    assert sharp[edge - 1] - sharp[edge] > 0.3 * abs(sharp[edge - 4] - sharp[edge + 3])
    assert soft[edge - 1] - soft[edge] < 0.6 * (sharp[edge - 1] - sharp[edge])
    assert soft[edge - 3] > soft[edge + 2]  # still darker below


@pytest.mark.parametrize("value", [-0.5, float("nan"), float("inf"), 11.0, "1", True])
def test_bad_psf(tmp_path, value):
    with pytest.raises(InputError, match=r"^--psf .*: must be a number") as info:
        synth.synthesize(tmp_path / "out", frames=2, size=(32, 32), psf=value)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["-1", "nan", "inf"])
def test_cli_bad_psf_is_one_line_exit_2(tmp_path, value):
    code, output = run("synth", tmp_path / "out", "--frames", "2", "--size", "32x32",
                       "--psf", value)
    assert code == 2
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: --psf "), output
    assert not (tmp_path / "out").exists()


def test_cli_psf_is_recorded(tmp_path):
    code, output = run("synth", tmp_path / "out", "--frames", "2", "--size", "48x32", "--psf",
                       "0.5", "-q")
    assert code == 0, output
    assert yaml.safe_load((tmp_path / "out" / "synth.yaml").read_text())["psf"] == 0.5
