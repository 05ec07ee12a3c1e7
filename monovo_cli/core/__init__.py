"""The estimator, pure (arrays in, arrays out): the sequence loop and its keyframes
(top level), one frame's motion (:mod:`.estimator`), the keyframe plane and the reported
covariance (:mod:`.plane`), and the capture of frames the prediction misses (:mod:`.recovery`).
"""
