"""The frame statuses of motion.csv's ``status`` column (docs/guide.md "File formats").

A ``str`` enum: a member is the very string written to the file (``FrameStatus.LOST ==
"lost"``, ``",".join`` and ``f"{status}"`` give ``lost``), so the CSV output does not depend
on it being an enum, and statuses read back from a file compare equal to the members.
"""

from __future__ import annotations

from enum import Enum


class FrameStatus(str, Enum):
    """What the tracker made of one frame."""

    OK = "ok"                  # estimated against the current keyframe
    REANCHORED = "reanchored"  # estimated, and a new keyframe was anchored on this frame
    REINIT = "reinit"          # restarted on a fresh keyframe after a loss (not yet written)
    LOST = "lost"              # the estimate failed its checks: the constant-velocity prediction

    __str__ = str.__str__      # the value, not "FrameStatus.OK", on every Python version
    __format__ = str.__format__


def mostly_lost(lost: int, tracked: int) -> bool:
    """Whether ``lost`` of ``tracked`` frames (those after frame 0) is more than half: the run
    failed on its data (``monovo track`` exits 3, batch records the sequence failed)."""
    return lost > 0.5 * max(tracked, 0)
