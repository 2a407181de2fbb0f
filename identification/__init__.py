"""Identification of the robot's dynamics from drive logs (docs/identification.md)."""
