"""Dynamics of sixplus3: Pinocchio closed-loop model, constrained forward/inverse dynamics."""
