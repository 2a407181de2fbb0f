"""Named readings of the paper's design conventions (docs/design.md compares them)."""

from __future__ import annotations

import math

from sixplus3.design.search import Reading

READINGS: dict[str, Reading] = {
    "spec": Reading(),
    "paper-match": Reading(
        name="paper-match", mode="++--", ey=0.0, theta_zero=-math.pi / 2, theta_direction=-1,
        theta_max=math.radians(135.0),
        description="E = F (ey = 0, the paper's simplifying assumption); cranks on the other "
        "branch (mode ++--); theta counted from vertical (+z), positive towards the robot "
        "centre (+y), in [0, 135] deg; reproduces the paper's optimum"),
    "paper-mirror": Reading(
        name="paper-mirror", mode="-+++", ey=0.0, theta_zero=-math.pi / 2, theta_direction=1,
        theta_max=math.radians(135.0),
        description="the theta1 mirror of paper-match (mode -+++, D on the other side of "
        "the D-P line), theta counted from -z about +x: the same numbers"),
    "spec-no-theta-limit": Reading(
        name="spec-no-theta-limit", theta_max=2 * math.pi,
        description="our conventions without the 135 deg limit (reachability and torque)"),
}
