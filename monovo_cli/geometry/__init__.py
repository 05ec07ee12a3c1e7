"""Geometry: SO(3)/SE(3), the pinhole camera with OpenCV distortion, the ground plane.
"""
