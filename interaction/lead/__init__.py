"""Lead-through and teach (docs/leadthrough.md): the controller a person guides by hand
(``leadthrough.py``), its settings, tables and state (``settings.py``), its walls
(``walls.py``) and their slow update (``wall_update.py``), teach (``teach.py``), and
their numba kernels (``_lead_kernel.py``, ``_walls_kernel.py``)."""
