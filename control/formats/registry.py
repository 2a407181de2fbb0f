"""The export formats, by name: one line per format (its module defines it).  The CLI's
``export --format`` choices are these (``rosbag2`` writes a directory, not text:
:mod:`sixplus3.control.formats.rosbag`); ``sixplus3/cli/names.py`` holds the names for a
light ``--help``, and a test keeps it equal to this table."""

from __future__ import annotations

from sixplus3.control.formats import drive_csv, ros2, rosbag
from sixplus3.control.formats.export_format import ExportFormat

FORMATS: dict[str, ExportFormat] = {f.name: f for f in (
    ros2.YAML,
    ros2.JSON,
    drive_csv.FORMAT,
    rosbag.FORMAT,
)}

__all__ = ["FORMATS"]
