"""The ``sixplus3`` command line (``sixplus3 --help``), one module per command group:

- :mod:`~sixplus3.cli.app`: the root group, the one place errors become exit codes;
- :mod:`~sixplus3.cli.robot`: ``leg`` and ``robot check | ik | list | show | export``;
- :mod:`~sixplus3.cli.design`: ``design optimize | layout | figures``, ``report``,
  ``atlas``;
- :mod:`~sixplus3.cli.plan`: ``plan``, ``move-to-start``, ``demo``;
- :mod:`~sixplus3.cli.trajectory`: ``validate``, ``export``, ``feed``, ``play``;
- :mod:`~sixplus3.cli.simulate`: ``simulate`` (with :mod:`~sixplus3.cli.contact`: a
  person in the way, a hand guiding the platform);
- :mod:`~sixplus3.cli.identify`: ``identify excite | estimate | check | plant``;
- :mod:`~sixplus3.cli.interaction`: ``wrench``, ``wrench-resolution``;
- :mod:`~sixplus3.cli.commission`: ``commission zero | directions | jog | theta``.

Each command is a thin wrapper over a library function; the CLI is the one place (with
``sixplus3.plan``) that chooses ``Robot.default()``.
"""

from sixplus3.cli import (  # noqa: F401 - registers the commands
    commission,
    design,
    identify,
    interaction,
    plan,
    robot,
    simulate,
    trajectory,
)
from sixplus3.cli.app import main, run

__all__ = ["main", "run"]
