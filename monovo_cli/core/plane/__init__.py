"""The keyframe plane: measured from the images, fused with its propagated belief and the
mounting prior (docs/algorithm.md section 4), and its error in every frame's reported
covariance (section 3, "Covariance")."""
