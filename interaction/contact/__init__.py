"""The contact guard (docs/safety.md): a controller that runs a validated trajectory
file and stops along it, holds or retracts on a contact (``guard.py``), its frozen
tables and state record (``tables.py``) and its offline parts (``parts.py``)."""
