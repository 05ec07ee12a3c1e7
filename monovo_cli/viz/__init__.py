"""Drawings, pure (arrays in, an image out): the glued-triangle overlay and the trajectory plot.
"""
