"""The gate: every check of a motion (findings per family, the interpolant between
samples, the dynamics worker, the input caps) and the validation that runs them."""
