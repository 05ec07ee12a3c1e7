"""Synthetic sequences with ground truth: textures, camera motions, renderers, the writer.

The renderers' image formation (supersampled plane homographies of a texture; rays cast
against a terrain's height field) is independent of the estimator's model; nothing here
imports :mod:`monovo_cli.core`.
"""

from monovo_cli.synth.gravel import gravel_texture
from monovo_cli.synth.motion import body_from_camera, drive_poses, mer_path, pair_poses
from monovo_cli.synth.raycast import TerrainRenderer
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
from monovo_cli.synth.rover import RoverScene, rover_scene
from monovo_cli.synth.terrain import TERRAINS, Rocks, Terrain, load_terrain, make_terrain
from monovo_cli.synth.texture import GroundTexture, load_texture, procedural_texture
from monovo_cli.synth.write import SynthSummary, synthesize

__all__ = [
    "REGION_MIN_DEPRESSION_DEG", "SKY_VALUE", "TERRAINS", "GroundRenderer", "GroundTexture",
    "Rocks", "RoverScene", "SynthSummary", "Terrain", "TerrainRenderer", "body_from_camera",
    "default_camera", "drive_poses", "finish_frame", "gravel_texture", "ground_in_camera",
    "ground_region", "load_terrain", "load_texture", "make_terrain", "mer_path", "pair_poses",
    "pixel_size_on_plane", "plane_homography", "procedural_texture", "ray_depression",
    "render_ground", "rover_scene", "supersample_matrix", "synthesize",
]
