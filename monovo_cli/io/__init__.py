"""Files: atomic writes, init.yaml, frames, model.npz, the CSV/TUM formats, images and videos
out. The layers below never touch a path.
"""
