"""The keyframe plane: measured from the images, fused with its carried belief and the
mounting prior (docs/algorithm.md section 3), and its error in every frame's reported
covariance."""
