"""``python -m sixplus3.cli``: the ``sixplus3`` program."""

from sixplus3.cli.app import run

run()
