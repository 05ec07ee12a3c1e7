"""The estimator, pure (arrays in, arrays out): ground model, one frame's motion, plane
refinement, the sequence loop, error tables.
"""
