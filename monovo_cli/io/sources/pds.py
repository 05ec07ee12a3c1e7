"""A directory of PDS3/PDS4 products as frames (the products are read by
:mod:`monovo_cli.io.pds`).

One product is one frame: a PDS3 ``.IMG`` with its attached label, a detached ``.LBL`` or a
PDS4 ``.xml`` label (:func:`~monovo_cli.io.pds.list_products`), in natural-sort order;
``paths`` are those files (the labels, for detached ones). Times come from times.txt, else
from the labels' start times, else frame k is at k s.
"""

from __future__ import annotations

import numpy as np

from monovo_cli.io.pds import label_times, read_product
from monovo_cli.io.sources.folder import TIMES_FILE, FolderSource


class PdsFolder(FolderSource):
    """The products ``paths`` of ``directory`` (:func:`~monovo_cli.io.pds.list_products`,
    not empty) as frames. Raises InputError when only some labels have a time or their
    times do not increase (and no times.txt gives them)."""

    kind = "pds"

    def _default_times(self) -> np.ndarray:
        """The labels' times (s, UTC, Unix epoch); frame k at k s when no label has one."""
        from_labels = label_times(self.paths, TIMES_FILE)
        return from_labels if from_labels is not None else super()._default_times()

    def _decode(self, index: int) -> np.ndarray:
        return read_product(self.paths[index]).image
