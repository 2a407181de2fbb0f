"""The names of the leg links a person can touch and of the vertices that bound them
(issue 70; the dynamics in :mod:`sixplus3.dynamics.leg_points`, whose docstring has the
table and the argument that a link's vertices bound its speed).  Data only: the site's
hardware file names links (``pfl_links``), and no layer below dynamics needs more."""

from __future__ import annotations

from sixplus3.errors import InputError
from sixplus3.robot_description.robot_geometry import NUM_LEGS

#: Each reachable leg link and the vertices that bound its speed (module doc).
LINKS: dict[str, tuple[str, ...]] = {
    "proximal": ("D",), "body": ("D", "E", "F", "P"), "crankB": ("G",),
    "distalB": ("G", "E"), "crankC": ("H",), "distalC": ("H", "F")}
#: The vertices in a fixed order.
VERTICES = ("D", "E", "F", "G", "H", "P")
#: The shorthand for every reachable link of every leg.
ALL = "legs"


def link_names(spec: object) -> tuple[str, ...]:
    """The links ``spec`` names, as ``leg{i}_{link}`` in a fixed order: a list of
    ``legs`` (every link of every leg), a link of :data:`LINKS` (on every leg) or
    ``leg{i}_{link}``.  An InputError names what is wrong and the valid names."""
    valid = f"a list of {ALL!r}, {sorted(LINKS)} or leg<0-2>_<link>"
    if spec is None:
        return ()
    if not isinstance(spec, (list, tuple)):
        raise InputError(f"pfl_links must be a list of leg links, got {spec!r}: {valid}",
                         value=spec, valid=valid)
    out: set[str] = set()
    for name in spec:
        s = str(name) if isinstance(name, str) else None
        if s == ALL:
            out |= {f"leg{i}_{k}" for i in range(NUM_LEGS) for k in LINKS}
        elif s in LINKS:
            out |= {f"leg{i}_{s}" for i in range(NUM_LEGS)}
        elif (s is not None and len(s) > 5 and s[:3] == "leg" and s[3] in "012"
              and s[4] == "_" and s[5:] in LINKS):
            out.add(s)
        else:
            raise InputError(f"pfl_links: unknown leg link {name!r}: {valid}", value=name,
                             valid=valid)
    order = [f"leg{i}_{k}" for i in range(NUM_LEGS) for k in LINKS]
    return tuple(n for n in order if n in out)


def vertices_of(links: tuple[str, ...]) -> tuple[tuple[int, str], ...]:
    """The vertices (leg, name) that bound the links ``links`` (:func:`link_names`'s
    form), without repeats, in a fixed order."""
    want = {(int(n[3]), v) for n in links for v in LINKS[n[5:]]}
    return tuple((i, v) for i in range(NUM_LEGS) for v in VERTICES if (i, v) in want)


def vertex_label(vertex: tuple[int, str]) -> str:
    """``leg0_D``: a vertex's name in findings and reports."""
    return f"leg{vertex[0]}_{vertex[1]}"


__all__ = ["ALL", "LINKS", "VERTICES", "link_names", "vertex_label", "vertices_of"]
