"""The names the command line offers, in one small table: ``--help`` reads them without
importing numpy or the libraries that hold the registries.  Each tuple is its registry's
keys in order; ``tests/test_cli.py::test_the_name_table_is_the_registries`` compares
them, so a name added to a registry (an export format, a named robot, a reading) shows
up in the help or the test fails."""

from __future__ import annotations

#: ``sixplus3.control.formats.registry.FORMATS`` (rosbag2: a directory)
EXPORT_FORMATS = ("ros2-yaml", "ros2-json", "drive-csv", "rosbag2")
#: ``sixplus3.robot_description.robot.NAMED_ROBOTS``
ROBOTS = ("default", "paper-as-stated", "paper-mirror", "compact")
#: ``sixplus3.design.readings.READINGS``
READINGS = ("spec", "paper-match", "paper-mirror", "spec-no-theta-limit")

__all__ = ["EXPORT_FORMATS", "READINGS", "ROBOTS"]
