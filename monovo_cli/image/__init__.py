"""Image operations: pyramids, sub-pixel sampling (OpenCV remap), gradients and the noise
estimate.
"""
