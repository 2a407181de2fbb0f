"""The external torque and wrench a person applies, from the drives alone
(docs/interaction.md): the one momentum observer (``momentum.py``), the batch estimate
of a log (``wrench.py``), the 1 kHz stream (``stream.py``) on Pinocchio's state or the
compiled CasADi model's (``compiled_state.py``), force resolution
(``resolution.py``), and their per-tick numba kernels (``_tick_kernel.py``)."""
