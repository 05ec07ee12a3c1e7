"""One frame's motion against a keyframe: the ground model's observation points, the
observation rows (docs/algorithm.md sections 1-2), robust weights, Gauss-Newton coarse to
fine with its covariance, and the terrain grid solved with the motion (section 9)."""
