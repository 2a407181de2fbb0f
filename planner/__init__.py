"""Time-optimal planning of the (6+3)-DoF robot with CasADi (minimal coordinates)."""
