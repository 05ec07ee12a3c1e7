"""After the run: the keyframe planes smoothed over the whole drive, the trajectory
re-scaled with them, and the terrain (points, heights) placed on them."""
