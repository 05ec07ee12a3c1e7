"""Frame sources (docs/guide.md "File formats"): where file paths stop and grey images start.

An input sequence is one of

- a directory of image files (:mod:`.images`),
- a directory of PDS3/PDS4 products (:mod:`.pds`),
- a video file (:mod:`.video`),
- a ROS 1/ROS 2 bag whose image ``topic`` is named (:mod:`.bag`),

each opened as a :class:`~.base.FrameSource`: frames read one at a time as
:class:`~.base.Frame` (float32 grey, 0..255), with their timestamps, names and the input's
fingerprint. :func:`open_frames` is the one place that tells which a path is;
:func:`resolve_sequence` the one that finds the input in a sequence folder. Every problem
is an :class:`~monovo_cli.errors.InputError` with one line naming the file.
"""

from __future__ import annotations

from pathlib import Path

from monovo_cli.errors import InputError
from monovo_cli.io.pds import PDS_EXTENSIONS, list_products
from monovo_cli.io.sources.bag import RosBag, bag_root, is_bag
from monovo_cli.io.sources.base import Frame, FrameSource
from monovo_cli.io.sources.folder import FRAMES_SUBDIR, TIMES_FILE, natural_key
from monovo_cli.io.sources.images import IMAGE_EXTENSIONS, ImageFolder, list_images
from monovo_cli.io.sources.pds import PdsFolder
from monovo_cli.io.sources.video import VIDEO_EXTENSIONS, VideoFile, is_video_name

__all__ = ["FRAMES_SUBDIR", "IMAGE_EXTENSIONS", "INIT_FILE", "TIMES_FILE", "VIDEO_EXTENSIONS",
           "Frame", "FrameSource", "ImageFolder", "PdsFolder", "RosBag", "VideoFile",
           "find_init_yaml", "is_container", "list_containers", "natural_key", "open_frames",
           "resolve_sequence"]

INIT_FILE = "init.yaml"


def is_container(path: Path) -> bool:
    """A video file (by its extension, :data:`VIDEO_EXTENSIONS`) or a ROS bag; hidden
    names never are."""
    path = Path(path)
    if path.name.startswith("."):
        return False
    return (path.is_file() and (is_video_name(path) or is_bag(path))) or (path.is_dir() and is_bag(path))


def list_containers(directory: Path) -> list[Path]:
    """The videos and ROS bags directly in ``directory`` (unsorted; none if it is unreadable)."""
    try:
        return [p for p in Path(directory).iterdir() if is_container(p)]
    except OSError:
        return []


def resolve_sequence(path: Path) -> Path:
    """The input of a sequence: ``path`` itself (a directory of frames or PDS products, a
    video file, a ROS bag), ``path/frames`` when ``path`` is a sequence folder as written by
    ``monovo synth`` (no images of its own), or the one video or bag in a folder that holds
    no frames of its own. InputError for a missing path or a single image file."""
    path = Path(path)
    if not path.exists():
        what = "file" if path.suffix.lower() in VIDEO_EXTENSIONS + (".bag",) else "directory"
        raise InputError(f"{path}: no such {what} (expected a directory of frames, a video, "
                         f"a ROS bag, or a folder holding {FRAMES_SUBDIR}/)")
    if path.is_file():
        if path.name.lower().endswith(IMAGE_EXTENSIONS + PDS_EXTENSIONS):
            raise InputError(f"{path}: is a file, expected a directory of frames "
                             f"(or a folder holding {FRAMES_SUBDIR}/, a video or a ROS bag)")
        return bag_root(path)  # a video or a bag (given by one of a ROS 2 bag's files)
    if is_bag(path) or list_images(path):
        return path
    sub = path / FRAMES_SUBDIR
    if sub.is_dir():
        return sub
    if not list_products(path):
        containers = list_containers(path)
        if len(containers) == 1:
            return containers[0]
    return path


def open_frames(path: Path, *, topic: str | None = None) -> FrameSource:
    """The frames of the sequence at ``path`` (:func:`resolve_sequence`): a ROS bag
    (``topic`` its image topic, may be None when it has one; other sources ignore it), a
    video (any other file), a directory of image files, else one of PDS products.
    Listed and checked now, decoded when read. InputError when there is no such input or
    it holds no frame."""
    found = resolve_sequence(Path(path))
    if is_bag(found):
        return RosBag(found, topic)
    if found.is_file():
        return VideoFile(found)
    images = list_images(found)
    if images:
        return ImageFolder(found, images)
    products = list_products(found)
    if products:
        return PdsFolder(found, products)
    raise InputError(f"{found}: no image files (accepted: {' '.join(IMAGE_EXTENSIONS)}, any "
                     "case; or PDS products .IMG .LBL .xml; or a video or a ROS bag)")


def find_init_yaml(seq: Path) -> Path | None:
    """``init.yaml`` in ``seq``, else in its parent when ``seq`` is a ``frames/`` directory,
    a video or a ROS bag; None without one."""
    seq = Path(seq)
    candidates = [seq / INIT_FILE]
    if seq.name == FRAMES_SUBDIR or seq.is_file() or is_bag(seq):
        candidates.append(seq.parent / INIT_FILE)
    for c in candidates:
        if c.is_file():
            return c
    return None
