"""Controller side: smoothing, validation (the gate), trajectory files, the offline feed."""
