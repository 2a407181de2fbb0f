"""The lead-through's slow update (:mod:`~sixplus3.interaction.lead.leadthrough`, module doc
5; docs/leadthrough.md, "Walls and cranks"): every ``slow_every`` ticks, the walls near
the reference pose and the cranks' climb, from exact slacks
(:mod:`~sixplus3.interaction.lead.walls`).

It runs in three stages on consecutive ticks, so that no tick carries the whole of it:

1. :meth:`WallUpdate.first`: the poses (the reference, each crank turned by +-
   CRANK_STEP, the probes ahead) and the slacks of the first five (the reference and
   four of the cranks' poses): the anchor (the reference's inverse kinematics), at once.
2. :meth:`WallUpdate.middle`, the tick after: the other five's slacks, then the cranks'
   wish (the crank score's gradient), the probes (a wall crossed ahead that no gradient
   announced: a *cliff*) and which walls are near.  With none near, the walls are
   decided here.
3. :meth:`WallUpdate.second`, the tick after that, only when a wall is near: its
   gradient in the twist (6 more poses at the first stage's reference) and the crank
   rates (from the first two): each a barrier g . (v, psi_dot) >= -WALL_RATE max(s, 0).

The walls and the cranks' wish found last stay in force meanwhile (two ticks at most).
:meth:`WallUpdate.update` runs all three at once (a guided motion's first tick; an
update every tick or two).

Every kernel the stages call is loaded when a :class:`WallUpdate` is built (numba's
cache costs milliseconds the first time a process calls each), not in the loop."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sixplus3.interaction.lead import _lead_kernel as kern
from sixplus3.interaction.lead import _walls_kernel as wk
from sixplus3.interaction.lead import walls
from sixplus3.robot_description.robot import Robot

#: Crank-score gradients below this are a plateau: the cranks stay.
CRANK_DEADBAND = 0.05
#: [1/s] the barrier's rate: a wall's slack may fall at most this fast per unit slack
#: (an exponential approach: the deceleration it asks is WALL_RATE times the approach
#: speed, 1.25 m/s^2 at the speed cap, within the acceleration cap).
WALL_RATE = 5.0
#: [s] a wall is near when the slack's fall since the last update would reach the band
#: within this: the barrier starts early enough to slow the platform without a jerk.
HORIZON = 0.3
#: [m, metric] probes ahead along the current direction: each must have an assembly and
#: be inside every wall (a leg's reach, a clearance's closest pair changing: walls no
#: gradient announces); the motion approaches the farthest one inside.
PROBES = (0.005, 0.01, 0.02)
#: Finite-difference steps: cranks [rad], the twist (metric units, m).
CRANK_STEP, TWIST_STEP = 0.02, 0.001

#: A wall: (g (9,), b): g . (v, omega L, psi_dot L) >= b.
Wall = tuple[np.ndarray, float]


#: Rows of the poses the first stage evaluates (the rest: the middle one's).
SPLIT = 5


@dataclass
class Found:
    """What the middle stage decided."""

    target: np.ndarray  # the cranks' wish [rad/s]
    walls: list[Wall] | None  # None: a wall is near, its gradient is due (second)
    stand_still: bool  # the reference itself has no assembly


def _twist_steps() -> np.ndarray:
    d = TWIST_STEP * np.eye(6)
    d[:, 3:] /= walls.ANGLE_SCALE
    return d


@dataclass(eq=False)
class _Work:
    """The slow update's arrays (:class:`WallUpdate`'s rows of poses, their slacks and
    angles, the probes', the kernels' work), allocated once."""

    probes: np.ndarray = field(default_factory=lambda: np.array(PROBES))
    tw: np.ndarray = field(default_factory=lambda: np.zeros((10, 6)))
    #: the twist steps along each axis (rotations / ANGLE_SCALE)
    dtw: np.ndarray = field(default_factory=lambda: _twist_steps())
    pos: np.ndarray = field(default_factory=lambda: np.zeros((16, 3)))
    rot: np.ndarray = field(default_factory=lambda: np.zeros((16, 3, 3)))
    psi: np.ndarray = field(default_factory=lambda: np.zeros((16, 3)))
    u: np.ndarray = field(default_factory=lambda: np.zeros(9))
    #: every slack, the clearance too
    sel: np.ndarray = field(default_factory=lambda: np.ones(16, dtype=np.bool_))
    sl: np.ndarray = field(default_factory=lambda: np.zeros((16, 4)))
    angles: np.ndarray = field(default_factory=lambda: np.zeros((16, 9)))
    solved: np.ndarray = field(default_factory=lambda: np.zeros(16, dtype=np.bool_))
    inside: np.ndarray = field(default_factory=lambda: np.zeros(len(PROBES), dtype=np.bool_))
    active: np.ndarray = field(default_factory=lambda: np.zeros(4, dtype=np.bool_))
    grad: np.ndarray = field(default_factory=lambda: np.zeros(3))


class WallUpdate:
    """The slow update's stages on arrays allocated once (module doc).

    Rows of the poses: 0 the reference, 1-3 and 4-6 each crank turned by +-
    CRANK_STEP, 7-9 the probes, 10-15 the reference moved by TWIST_STEP along each
    twist axis (rotations / ANGLE_SCALE).  :attr:`min_margin`, :attr:`min_slack`,
    :attr:`walls_met`: the reference's smallest singularity margin and slack seen, and
    how many updates met a wall."""

    def __init__(self, robot: Robot, tool: np.ndarray, crank_gain: float,
                 crank_rate: float) -> None:
        self.robot = robot
        self.tool = np.asarray(tool, dtype=float)
        self.crank_gain, self.crank_rate = crank_gain, crank_rate
        self._fn = walls.walls_of(robot)
        self.w = _Work()  # the stages' arrays, allocated once
        self.reset()
        self._warm()
        self.reset()

    def reset(self) -> None:
        """Forget the past updates (the rate a slack fell, a stage due, the minima)."""
        self.staged: tuple[float, float, bool, np.ndarray, np.ndarray, np.ndarray] | None
        self.staged = None
        self.pending: tuple[np.ndarray, np.ndarray, Wall | None, np.ndarray, np.ndarray,
                            np.ndarray] | None = None
        self._prev = (np.zeros(4), math.inf)  # the reference's slacks last time, and when
        self.min_margin = math.inf
        self.min_slack = math.inf
        self.walls_met = 0

    def _warm(self) -> None:
        """Every kernel of the stages called once on these arrays (their types), at the
        robot's home: numba loads each from its cache here, not in a tick."""
        p = np.asarray(self.robot.home_position, dtype=float)
        psi = np.asarray(self.robot.home_psi, dtype=float)
        self.first(p, np.eye(3), psi, np.zeros(6), np.zeros(3), 0.0, True)
        self.middle()
        self.pending = (np.zeros(4), np.ones(4, dtype=np.bool_), None, p, np.eye(3), psi)
        self.second()

    def update(self, p: np.ndarray, R: np.ndarray, psi_ref: np.ndarray, v: np.ndarray,
               psi_dot: np.ndarray, t_now: float, lead: bool
               ) -> tuple[np.ndarray | None, Found]:
        """The three stages at once: (the anchor, what was found, the walls decided)."""
        anchor = self.first(p, R, psi_ref, v, psi_dot, t_now, lead)
        found = self.middle()
        if found.walls is None:
            found.walls = self.second()
        return anchor, found

    def first(self, p: np.ndarray, R: np.ndarray, psi_ref: np.ndarray, v: np.ndarray,
              psi_dot: np.ndarray, t_now: float, lead: bool) -> np.ndarray | None:
        """The first stage at the reference (p, R, psi_ref) moving at (v, psi_dot) (the
        tool point's twist, the crank rates), at time ``t_now`` [s]; ``lead``: the
        cranks may climb.  Returns the anchor: the reference's actuated angles (None:
        it has no assembly)."""
        pos, rotm, psi, u, sl = self.w.pos, self.w.rot, self.w.psi, self.w.u, self.w.sl
        nx = kern.update_poses((p, R, psi_ref), (v, psi_dot), R @ self.tool,
                               (walls.ANGLE_SCALE, CRANK_STEP, self.w.probes), self.w.tw,
                               (pos, rotm, psi), u)
        angles, solved, k = self.w.angles, self.w.solved, SPLIT
        self._fn.into(pos[:k], rotm[:k], psi[:k], self.w.sel[:k], sl[:k], angles[:k],
                      solved[:k])
        self.staged = (nx, t_now, lead, p.copy(), R.copy(), psi_ref.copy())
        return angles[0].copy() if solved[0] else None

    def middle(self) -> Found:
        """The middle stage (module doc), from the staged first."""
        assert self.staged is not None, "no first stage is staged"
        nx, t_now, lead, p, R, psi_ref = self.staged
        self.staged = None
        pos, rotm, psi, u, sl, k = self.w.pos, self.w.rot, self.w.psi, self.w.u, self.w.sl, SPLIT
        solved = self.w.solved
        self._fn.into(pos[k:10], rotm[k:10], psi[k:10], self.w.sel[k:10], sl[k:10],
                      self.w.angles[k:10], solved[k:10])
        now = sl[0]
        if now[0] > -1.0:
            self.min_margin = min(self.min_margin, float(now[0]) + self.robot.limits.margin
                                  + walls.MARGIN_GUARD)
        prev, t_prev = self._prev
        inside, active, grad = self.w.inside, self.w.active, self.w.grad
        gnorm, n_active = kern.slow_scalars(sl, solved, len(PROBES), CRANK_STEP,
                                            walls.WALL_BAND, prev, t_now - t_prev,
                                            HORIZON, grad, active, inside)
        self.min_slack = min(self.min_slack, float(now.min()))
        cliff = None
        if nx > 0.0 and not inside[-1]:  # a wall crossed ahead that no gradient announced
            # (no assembly: a leg's reach; a clearance's closest pair changing): approach
            # the farthest probe before it, exponentially (WALL_RATE), along this direction
            reach = 0.0
            for dist, ok in zip(PROBES, inside, strict=True):
                if not ok:
                    break
                reach = dist
            cliff = (-u, -WALL_RATE * reach)
            self.walls_met += 1
        target = np.zeros(3)
        if self.crank_gain > 0 and lead and gnorm > CRANK_DEADBAND:
            # the cranks climb the crank score (walls.crank_score) within crank_rate
            target = self.crank_gain * grad
            if self.crank_gain * gnorm > self.crank_rate:
                target *= self.crank_rate / (self.crank_gain * gnorm)
        # a wall is near when its slack is inside the band, or will be within HORIZON at
        # the rate it fell since the last update (the braking distance at full speed)
        self._prev = (now.copy(), t_now)
        if not n_active:
            return Found(target, [] if cliff is None else [cliff], False)
        self.walls_met += 1
        if now.min() <= -1.0:  # the reference itself unsolvable: stand still
            return Found(np.zeros(3), [], True)
        self.pending = (now.copy(), active.copy(), cliff, p, R, psi_ref)
        return Found(target, None, False)

    def second(self) -> list[Wall]:
        """The last stage (module doc): the walls, from the pending middle one's."""
        assert self.pending is not None, "no middle stage is pending"
        now, active, cliff, p, R, psi_ref = self.pending
        self.pending = None
        pos, rotm, psi, sl, sel = self.w.pos, self.w.rot, self.w.psi, self.w.sl, self.w.sel
        wk.moved(p, R, self.w.dtw, pos[10:], rotm[10:])
        psi[10:] = psi_ref
        sel[10:] = bool(active[3])  # the clearance only when it is near
        self._fn.into(pos[10:], rotm[10:], psi[10:], sel[10:], sl[10:], self.w.angles[10:],
                      self.w.solved[10:])
        found: list[Wall] = []
        scale = 2.0 * CRANK_STEP * walls.ANGLE_SCALE
        for c in np.flatnonzero(active):
            g = np.empty(9)
            g[:6] = (sl[10:, c] - now[c]) / TWIST_STEP
            g[6:] = (sl[1:4, c] - sl[4:7, c]) / scale
            if np.all(np.isfinite(g)) and float(g @ g) > 0.0:
                # beyond a wall (s < 0) the platform goes no deeper, but is not pushed
                # back against the person (that would be active, not passive)
                found.append((g, -WALL_RATE * max(float(now[c]), 0.0)))
        if cliff is not None:
            found.append(cliff)
        return found


__all__ = ["CRANK_DEADBAND", "CRANK_STEP", "HORIZON", "PROBES", "SPLIT", "TWIST_STEP",
           "WALL_RATE", "Found", "Wall", "WallUpdate"]
