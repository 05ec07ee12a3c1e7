"""Sequence listing, timestamps and frame decoding (monovo_cli.frames)."""

from __future__ import annotations

import shutil
import types
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from monovo_cli.errors import InputError
from monovo_cli.io.grey import decode_gray, read_gray
from monovo_cli.io.sources import (
    IMAGE_EXTENSIONS,
    Frame,
    find_init_yaml,
    natural_key,
    open_frames,
    resolve_sequence,
)

RNG = np.random.default_rng(1234)
GREY = RNG.integers(0, 256, (24, 32), dtype=np.uint8)                  # reference grey image
COLOUR = RNG.integers(0, 256, (24, 32, 3), dtype=np.uint8)             # BGR
LUMA = (0.114 * COLOUR[..., 0] + 0.587 * COLOUR[..., 1] + 0.299 * COLOUR[..., 2])


def write(path: Path, img: np.ndarray) -> Path:
    ok, buf = cv2.imencode(path.suffix, img)
    assert ok
    path.write_bytes(buf.tobytes())
    return path


def make_seq(d: Path, n: int, names=None, size=(24, 32)) -> list[Path]:
    d.mkdir(parents=True, exist_ok=True)
    names = names or [f"frame_{i:06d}.png" for i in range(n)]
    out = []
    for i, name in enumerate(names):
        img = np.full(size, (i * 10) % 256, dtype=np.uint8)
        out.append(write(d / name, img))
    return out


# ----------------------------------------------------------------------------- listing


def test_natural_key_orders_numbers_numerically():
    names = ["frame10.png", "frame2.png", "Frame1.png", "frame02b.png", "frame2a.png", "a.png",
             "frame100.png"]
    assert sorted(names, key=natural_key) == [
        "a.png", "Frame1.png", "frame2.png", "frame2a.png", "frame02b.png", "frame10.png", "frame100.png"]


def test_listing_natural_sort_and_other_files_ignored(tmp_path):
    d = tmp_path / "seq"
    make_seq(d, 0, names=["frame10.png", "frame2.png", "frame1.PNG", "frame3.JPG", "frame4.tiff",
                          "frame5.bmp", "frame6.pgm", "frame7.jpeg", "frame8.tif"])
    (d / "notes.txt").write_text("hello")
    (d / "calib.yaml").write_text("a: 1")
    (d / "frame9.png.bak").write_bytes(b"x")
    (d / ".frame0.png").write_bytes(b"AppleDouble junk")
    (d / "frame11.png").mkdir()  # a directory with an image-like name
    seq = open_frames(d)
    assert [p.name for p in seq.paths] == ["frame1.PNG", "frame2.png", "frame3.JPG", "frame4.tiff",
                                           "frame5.bmp", "frame6.pgm", "frame7.jpeg", "frame8.tif",
                                           "frame10.png"]
    assert len(seq) == 9
    assert seq.dir == d
    np.testing.assert_array_equal(seq.timestamps, np.arange(9.0))
    assert seq.times_path is None


def test_image_extensions_constant():
    assert IMAGE_EXTENSIONS == (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm", ".bmp")


def test_missing_path(tmp_path):
    with pytest.raises(InputError, match=r"nowhere: no such directory"):
        open_frames(tmp_path / "nowhere")


def test_file_instead_of_directory(tmp_path):
    f = write(tmp_path / "a.png", GREY)
    with pytest.raises(InputError, match=r"a\.png: is a file, expected a directory of frames"):
        open_frames(f)


def test_no_images_lists_extensions(tmp_path):
    (tmp_path / "readme.txt").write_text("x")
    with pytest.raises(InputError, match=r"no image files \(accepted: \.png \.jpg \.jpeg \.tif \.tiff "
                                         r"\.pgm \.bmp"):
        open_frames(tmp_path)


def test_resolve_sequence_and_find_init(tmp_path):
    root = tmp_path / "seq"
    make_seq(root / "frames", 3)
    (root / "init.yaml").write_text("x: 1\n")
    assert resolve_sequence(root) == root / "frames"
    assert resolve_sequence(root / "frames") == root / "frames"
    assert open_frames(root).dir == root / "frames"
    assert find_init_yaml(root) == root / "init.yaml"
    assert find_init_yaml(root / "frames") == root / "init.yaml"
    other = tmp_path / "other"
    make_seq(other, 2)
    assert find_init_yaml(other) is None
    (other / "init.yaml").write_text("x: 1\n")
    assert find_init_yaml(other) == other / "init.yaml"


def test_resolve_prefers_own_images(tmp_path):
    make_seq(tmp_path, 2)
    (tmp_path / "frames").mkdir()
    assert resolve_sequence(tmp_path) == tmp_path


def test_non_ascii_paths(tmp_path):
    d = tmp_path / "séquence_日本"
    make_seq(d, 2, names=["imagé_0.png", "imagé_1.png"])
    frames = list(open_frames(d))
    assert [f.index for f in frames] == [0, 1]
    assert frames[1].image.shape == (24, 32)


# ----------------------------------------------------------------------------- times.txt


def test_times_txt(tmp_path):
    make_seq(tmp_path, 3)
    (tmp_path / "times.txt").write_text("0.0\n0.1\n\n0.25\n")
    seq = open_frames(tmp_path)
    np.testing.assert_array_equal(seq.timestamps, [0.0, 0.1, 0.25])
    assert seq.times_path == tmp_path / "times.txt"
    assert [f.timestamp for f in seq] == [0.0, 0.1, 0.25]


@pytest.mark.parametrize("text, msg", [
    ("0\n1\n", r"times\.txt: 2 timestamps for 3 frames"),
    ("0\n1\n2\n3\n", r"times\.txt: 4 timestamps for 3 frames"),
    ("0\nabc\n2\n", r"times\.txt: line 2: expected one timestamp in seconds, got 'abc'"),
    ("0\n1 2\n2\n", r"times\.txt: line 2: expected one timestamp"),
    ("0\n1\nnan\n", r"times\.txt: line 3: timestamp must be finite"),
    ("0\ninf\n2\n", r"times\.txt: line 2: timestamp must be finite"),
    ("0\n1\n1\n", r"times\.txt: line 3: timestamps must increase, 1\.0 follows 1\.0"),
    ("0\n2\n1\n", r"times\.txt: line 3: timestamps must increase"),
])
def test_times_txt_errors(tmp_path, text, msg):
    make_seq(tmp_path, 3)
    (tmp_path / "times.txt").write_text(text)
    with pytest.raises(InputError, match=msg):
        open_frames(tmp_path)


def test_times_txt_not_text(tmp_path):
    make_seq(tmp_path, 1)
    (tmp_path / "times.txt").write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(InputError, match=r"times\.txt: cannot read timestamps"):
        open_frames(tmp_path)


def test_times_txt_beside_frames_is_used_and_a_conflict_refused(small_drive, tmp_path):
    s = tmp_path / "s"
    shutil.copytree(small_drive, s)
    times = "".join(f"{100 + 0.1 * k:.1f}\n" for k in range(10))
    (s / "times.txt").write_text(times)
    np.testing.assert_allclose(open_frames(s).timestamps, 100 + 0.1 * np.arange(10))
    (s / "frames" / "times.txt").write_text(times)  # the same in both places: fine
    np.testing.assert_allclose(open_frames(s).timestamps, 100 + 0.1 * np.arange(10))
    (s / "frames" / "times.txt").write_text("".join(f"{k}\n" for k in range(10)))
    with pytest.raises(InputError, match=r"times\.txt.*and .*times\.txt.* differ"):
        open_frames(s)


# ----------------------------------------------------------------------------- decoding


def _palette_png(path: Path, index: np.ndarray, palette: np.ndarray, transparency=None) -> Path:
    Image = pytest.importorskip("PIL.Image", reason="Pillow is needed to write palette PNGs")
    index = np.ascontiguousarray(index, dtype=np.uint8)
    im = Image.frombytes("P", (index.shape[1], index.shape[0]), index.tobytes())
    im.putpalette(palette.astype(np.uint8).reshape(-1).tolist())
    if transparency is None:
        im.save(path)
    else:
        im.save(path, transparency=transparency)
    return path


def test_grey_variants_decode_identically(tmp_path):
    """8/16-bit, grey/colour/alpha/palette, every format: the same grey image."""
    g3 = np.dstack([GREY] * 3)
    g4 = np.dstack([GREY, GREY, GREY, RNG.integers(0, 256, GREY.shape, dtype=np.uint8)])
    files = [
        write(tmp_path / "g8.png", GREY),
        write(tmp_path / "g16.png", GREY.astype(np.uint16) * 257),
        write(tmp_path / "bgr.png", g3),
        write(tmp_path / "bgra.png", g4),
        write(tmp_path / "bgr16.png", g3.astype(np.uint16) * 257),
        write(tmp_path / "bgra16.tiff", g4.astype(np.uint16) * 257),
        write(tmp_path / "g.bmp", GREY),
        write(tmp_path / "bgr.bmp", g3),
        write(tmp_path / "g.pgm", GREY),
        write(tmp_path / "g16.pgm", GREY.astype(np.uint16) * 257),
        write(tmp_path / "g.tif", GREY),
        write(tmp_path / "f01.tif", GREY.astype(np.float32) / 255),
        write(tmp_path / "f255.tif", g3.astype(np.float32)),
    ]
    pal = np.stack([np.arange(256)] * 3, axis=1)
    files.append(_palette_png(tmp_path / "pal.png", GREY, pal))
    files.append(_palette_png(tmp_path / "palt.png", GREY, pal, transparency=0))
    la = pytest.importorskip("PIL.Image").frombytes(
        "LA", (GREY.shape[1], GREY.shape[0]), np.ascontiguousarray(np.dstack([GREY, GREY])).tobytes())
    la.save(tmp_path / "la.png")
    files.append(tmp_path / "la.png")
    for f in files:
        img = read_gray(f)
        assert img.dtype == np.float32 and img.shape == GREY.shape, f.name
        assert img.flags.c_contiguous
        np.testing.assert_allclose(img, GREY, atol=1e-3, err_msg=f.name)


def test_colour_uses_luma_weights(tmp_path):
    for f in [write(tmp_path / "c.png", COLOUR), write(tmp_path / "c16.png", COLOUR.astype(np.uint16) * 257),
              write(tmp_path / "ca.png", np.dstack([COLOUR, np.full(GREY.shape, 7, np.uint8)]))]:
        np.testing.assert_allclose(read_gray(f), LUMA, atol=1e-3, err_msg=f.name)


def test_palette_colours_use_luma_weights(tmp_path):
    pal = RNG.integers(0, 256, (256, 3))  # RGB palette
    idx = RNG.integers(0, 256, GREY.shape, dtype=np.uint8)
    f = _palette_png(tmp_path / "pal.png", idx, pal)
    rgb = pal[idx]
    expected = 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
    np.testing.assert_allclose(read_gray(f), expected, atol=1e-3)


def test_jpeg_close(tmp_path):
    smooth = cv2.GaussianBlur(GREY, (5, 5), 2.0)
    img = read_gray(write(tmp_path / "a.jpg", smooth))
    assert np.abs(img - smooth).mean() < 3.0


def test_float_tiff_out_of_range_rejected(tmp_path):
    f = write(tmp_path / "f.tif", GREY.astype(np.float32) * 10)
    with pytest.raises(InputError,
                       match=r"f\.tif: float image values span \[0, \d+\]; expected 0\.\.1 or 0\.\.255"):
        read_gray(f)


def test_float_tiff_nan_rejected(tmp_path):
    a = GREY.astype(np.float32)
    a[3, 4] = np.nan
    with pytest.raises(InputError, match="NaN"):
        read_gray(write(tmp_path / "f.tif", a))


def test_signed_pixels_rejected(tmp_path):
    f = write(tmp_path / "s.tif", GREY.astype(np.int16) - 100)
    with pytest.raises(InputError, match=r"unsupported pixel type int16"):
        read_gray(f)


@pytest.mark.parametrize("make", [
    lambda p: p.write_bytes(b""),
    lambda p: p.write_bytes(cv2.imencode(".png", GREY)[1].tobytes()[:200]),
    lambda p: p.write_bytes(cv2.imencode(".png", GREY)[1].tobytes()[:-12]),
    lambda p: p.write_bytes(b"this is not an image at all\n" * 10),
    lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256))),
])
def test_corrupt_frames_one_clean_line(tmp_path, capfd, make):
    p = tmp_path / "bad.png"
    make(p)
    with pytest.raises(InputError) as ei:
        read_gray(p)
    assert str(ei.value) == f"{p}: cannot decode image (empty, truncated or not an image)"
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # cv2 / libpng chatter is suppressed


def test_truncated_jpeg(tmp_path):
    data = cv2.imencode(".jpg", COLOUR)[1].tobytes()
    p = tmp_path / "t.jpg"
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cannot decode image"):
        read_gray(p)


def test_unreadable_path(tmp_path):
    with pytest.raises(InputError, match=r"missing\.png: cannot read image"):
        read_gray(tmp_path / "missing.png")
    with pytest.raises(InputError, match=r"cannot read image"):
        read_gray(tmp_path)


def test_stderr_still_works_after_decoding(tmp_path, capfd):
    p = tmp_path / "bad.png"
    p.write_bytes(b"\x89PNG\r\n\x1a\nxx")
    with pytest.raises(InputError):
        read_gray(p)
    import os
    os.write(2, b"still here\n")
    assert capfd.readouterr().err == "still here\n"


# ----------------------------------------------------------------------------- sequence reading


def test_iteration_streams_frames_lazily(tmp_path):
    paths = make_seq(tmp_path, 4)
    paths[2].write_bytes(b"")  # corrupt, but listing does not decode
    seq = open_frames(tmp_path)
    it = iter(seq)
    assert isinstance(it, types.GeneratorType)
    f0 = next(it)
    assert isinstance(f0, Frame)
    assert (f0.index, f0.timestamp, f0.path) == (0, 0.0, paths[0])
    assert f0.image.dtype == np.float32 and f0.image.shape == (24, 32)
    assert next(it).index == 1
    with pytest.raises(InputError, match=r"frame_000002\.png: cannot decode image"):
        next(it)
    f3 = seq.read(3)
    np.testing.assert_array_equal(f3.image, np.full((24, 32), 30.0, np.float32))


def test_size_lazy_and_cached(tmp_path):
    paths = make_seq(tmp_path, 3)
    seq = open_frames(tmp_path)
    assert seq._size is None
    assert (seq.width, seq.height) == (32, 24)
    paths[0].unlink()  # size is cached: not read again
    assert (seq.width, seq.height) == (32, 24)
    assert seq.read(1).index == 1


def test_mixed_sizes(tmp_path):
    make_seq(tmp_path, 2)
    write(tmp_path / "frame_000002.png", np.zeros((20, 30), np.uint8))
    seq = open_frames(tmp_path)
    frames = []
    with pytest.raises(InputError) as ei:
        for f in seq:
            frames.append(f)
    assert len(frames) == 2
    assert str(ei.value) == (f"{tmp_path / 'frame_000002.png'}: frame is 30x20 but frame_000000.png "
                             "is 32x24 (all frames must have one size)")


def test_mixed_sizes_read_out_of_order(tmp_path):
    make_seq(tmp_path, 2)
    write(tmp_path / "frame_000002.png", np.zeros((20, 30), np.uint8))
    with pytest.raises(InputError, match=r"frame is 30x20 but frame_000000\.png is 32x24"):
        open_frames(tmp_path).read(2)


def test_read_index_range(tmp_path):
    make_seq(tmp_path, 2)
    seq = open_frames(tmp_path)
    with pytest.raises(IndexError):
        seq.read(2)
    with pytest.raises(IndexError):
        seq.read(-1)


# ----------------------------------------------------------------------------- properties


def _encoded_samples() -> list[bytes]:
    out = []
    for ext in (".png", ".jpg", ".bmp", ".pgm", ".tif"):
        img = GREY if ext == ".pgm" else COLOUR
        out.append(cv2.imencode(ext, img)[1].tobytes())
    out.append(cv2.imencode(".png", GREY.astype(np.uint16) * 257)[1].tobytes())
    return out


_SAMPLES = _encoded_samples()


@st.composite
def _damaged_image(draw):
    data = bytearray(draw(st.sampled_from(_SAMPLES)))
    how = draw(st.sampled_from(["truncate", "flip", "splice"]))
    if how == "truncate":
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif how == "flip":
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
    else:
        i = draw(st.integers(0, len(data)))
        data[i:i] = draw(st.binary(max_size=64))
    return bytes(data)


def _check_read(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        img = read_gray(path)
    except InputError as exc:
        assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
        event("rejected")
        return
    event("decoded")
    assert isinstance(img, np.ndarray) and img.dtype == np.float32 and img.ndim == 2
    assert img.size > 0 and np.all(np.isfinite(img))


@settings(max_examples=500, deadline=None)
@given(data=st.one_of(
    st.binary(max_size=512),
    st.binary(max_size=256).map(lambda b: b"\x89PNG\r\n\x1a\n" + b),
    st.binary(max_size=256).map(lambda b: b"\xff\xd8\xff\xe0" + b),
    st.binary(max_size=256).map(lambda b: b"BM" + b),
    st.binary(max_size=256).map(lambda b: b"II*\x00" + b),
    st.binary(max_size=64).map(lambda b: b"P5 4 4 255\n" + b),
))
def test_property_read_gray_random_bytes(tmp_path_factory, data):
    _check_read(tmp_path_factory.mktemp("rb") / "f.png", data)


@settings(max_examples=500, deadline=None)
@given(data=_damaged_image())
def test_property_read_gray_damaged_images(tmp_path_factory, data):
    _check_read(tmp_path_factory.mktemp("dm") / "f.png", data)


def test_decode_gray_bytes():
    img = decode_gray(cv2.imencode(".png", GREY)[1].tobytes(), Path("mem.png"))
    np.testing.assert_array_equal(img, GREY.astype(np.float32))


def test_concurrent_decoding_threads(tmp_path, capfd):
    from concurrent.futures import ThreadPoolExecutor

    good = write(tmp_path / "good.png", GREY)
    bad = tmp_path / "bad.png"
    bad.write_bytes(cv2.imencode(".png", GREY)[1].tobytes()[:-20])

    def work(i):
        if i % 2:
            with pytest.raises(InputError):
                read_gray(bad)
            return None
        return read_gray(good)

    with ThreadPoolExecutor(8) as pool:
        results = list(pool.map(work, range(64)))
    for r in results[::2]:
        np.testing.assert_array_equal(r, GREY.astype(np.float32))
    import os
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"
