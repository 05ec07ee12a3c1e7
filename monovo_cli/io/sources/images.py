"""A directory of image files as frames.

The frames are the files with an image extension (:data:`IMAGE_EXTENSIONS`, any case) in
natural-sort order; other files, subdirectories and hidden files (such as macOS
``._frame.png`` companions) are ignored. Each is decoded when read into float32 grey on a
0..255 scale, whatever its depth, colour layout or format (:mod:`monovo_cli.io.grey`).
Times come from times.txt, else frame k is at k s (:mod:`.folder`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.grey import read_gray
from monovo_cli.io.sources.folder import FolderSource

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm", ".bmp")


def is_image_name(name: str) -> bool:
    """A file name taken for a frame: not hidden, with an image extension (any case)."""
    return not name.startswith(".") and name.lower().endswith(IMAGE_EXTENSIONS)


def list_images(directory: Path) -> list[Path]:
    """The image files of ``directory`` (unsorted); InputError if it cannot be listed.

    A dangling symlink named like a frame counts: skipping it silently would shift every
    later frame's timestamp, so it is a frame that cannot be read."""
    try:
        entries = list(Path(directory).iterdir())
    except OSError as exc:
        raise InputError(f"{directory}: cannot list the directory ({exc.strerror or exc})") from None
    return [p for p in entries if is_image_name(p.name)
            and (p.is_file() or (p.is_symlink() and not p.exists()))]


class ImageFolder(FolderSource):
    """The image files ``paths`` of ``directory`` (:func:`list_images`, not empty) as frames."""

    kind = "images"

    def _decode(self, index: int) -> np.ndarray:
        return read_gray(self.paths[index])
