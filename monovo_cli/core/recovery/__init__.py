"""Capture beyond the direct estimator's range: an ORB + homography motion over the known
plane, and the hypothesis that carries the pose across lost frames."""
