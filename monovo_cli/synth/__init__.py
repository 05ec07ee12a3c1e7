"""Synthetic sequences with ground truth: textures, camera motions, a renderer, the writer.

The renderer's image formation (supersampled plane homographies of a texture) is independent
of the estimator's model; nothing here imports :mod:`monovo_cli.core`.
"""

from monovo_cli.synth.motion import body_from_camera, drive_poses, pair_poses
from monovo_cli.synth.render import (
    REGION_MIN_DEPRESSION_DEG,
    SKY_VALUE,
    GroundRenderer,
    default_camera,
    finish_frame,
    ground_in_camera,
    ground_region,
    pixel_size_on_plane,
    plane_homography,
    ray_depression,
    render_ground,
    supersample_matrix,
)
from monovo_cli.synth.texture import GroundTexture, load_texture, procedural_texture
from monovo_cli.synth.write import SynthSummary, synthesize

__all__ = [
    "REGION_MIN_DEPRESSION_DEG", "SKY_VALUE", "GroundRenderer", "GroundTexture", "SynthSummary",
    "body_from_camera", "default_camera", "drive_poses", "finish_frame", "ground_in_camera",
    "ground_region", "load_texture", "pair_poses", "pixel_size_on_plane", "plane_homography",
    "procedural_texture", "ray_depression", "render_ground", "supersample_matrix", "synthesize",
]
