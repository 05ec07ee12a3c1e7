"""Capture beyond the direct estimator's range: an ORB + homography motion over the known
plane, and the hypothesis that carries the pose across lost frames (docs/algorithm.md
sections 7-8)."""
