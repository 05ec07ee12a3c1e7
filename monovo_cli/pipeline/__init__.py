"""Whole-command jobs: files in, the core run, files out (init and track, overlay, batch).
"""
