"""MeshCat playback and plots of sixplus3 trajectories (heavy imports inside functions)."""
