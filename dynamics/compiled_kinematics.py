"""Forward kinematics of a sequence of actuated angles in compiled form: Newton's method
in the minimal coordinates x = (position, rotation vector, crank angles) on the CasADi
model's ``x -> (theta(x), d theta / d x)`` (:func:`~sixplus3.dynamics.symbolic.
kinematics_function`, generated as C like the planner's functions), one sample after
the other.

Each sample starts from the previous one's x moved by J_x^-1 (theta - theta_prev) (a
first-order prediction: at 1 kHz and a few ms between samples one or two corrections
are then enough); it is kept when every angle is reproduced within :data:`TOL` after at
most :data:`NEWTON` corrections and x moved less than :data:`JUMP` from the previous
sample (the same acceptance as :func:`~sixplus3.identification.base.poses_of`'s batched
Newton).  The first sample that is not kept ends the run; the caller decides what to do
from there (the batched method, which splits and retries).

The functions are called through CasADi's buffer interface on preallocated arrays
(LIBRARY-NOTES: about 2 us a call, against about 80 us with numpy conversions)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg import lapack

from sixplus3.dynamics.codegen import compiled_small
from sixplus3.dynamics.symbolic import configuration_function, kinematics_function, structure
from sixplus3.robot_description.robot import Robot, require_robot

#: Newton corrections at most per sample.
NEWTON = 4
#: Converged when every actuated angle is within this of the reading [rad].
TOL = 1e-10
#: A sample whose x moves more than this from the previous one (any coordinate, m or
#: rad) is a jump to another branch: not kept.
JUMP = 0.1
#: Newton steps larger than this (any coordinate) are scaled down to it.
MAX_STEP = 0.2


class Buffered:
    """A CasADi function called on preallocated numpy arrays (its buffer interface).
    Every output must be dense (the buffers are written whole)."""

    def __init__(self, f: Any, shapes: tuple[tuple[int, ...], ...]) -> None:
        self._buf, self._eval = f.buffer()
        self.args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.res = [np.zeros(int(np.prod(s))) for s in shapes]
        for j, s in enumerate(shapes):
            if f.nnz_out(j) != int(np.prod(s)):
                raise ValueError(f"{f.name()}: output {j} is sparse")
        self._shapes = shapes
        for i, a in enumerate(self.args):
            self._buf.set_arg(i, a.data)
        for j, r in enumerate(self.res):
            self._buf.set_res(j, r.data)

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        for dst, src in zip(self.args, args, strict=False):
            dst[:] = src
        self._eval()
        return [r.reshape(s, order="F") for r, s in zip(self.res, self._shapes, strict=True)]

    def evaluate(self) -> None:
        """Evaluate on the arguments already in :attr:`args`; the results are in
        :attr:`res` (flat, column-major: the per-tick kernels read them there)."""
        self._eval()


def wrapped(a: np.ndarray) -> np.ndarray:
    """Angles in [-pi, pi)."""
    return np.mod(a + math.pi, 2.0 * math.pi) - math.pi


def kinematics_buffer(robot: Robot) -> Buffered:
    """``x -> (theta(x), J_x(x))`` of ``robot``'s structure, compiled, on its buffers."""
    r = require_robot(robot)
    return Buffered(compiled_small(lambda: kinematics_function(r), structure(r).hash,
                                   "kin_x"), ((9,), (9, 9)))


class CompiledKinematics:
    """theta(x), J_x(x) and the Pinocchio configuration q(x) of one robot structure,
    compiled (module doc)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = require_robot(robot)
        self.kin = kinematics_buffer(self.robot)
        self._q: Buffered | None = None  # q(x), compiled at its first use

    def configurations(self, x: np.ndarray) -> np.ndarray:
        """(n, nq) the closed configurations q at minimal coordinates x (n, 9)."""
        if self._q is None:
            r = self.robot
            q = compiled_small(lambda: configuration_function(r), structure(r).hash, "q_x")
            self._q = Buffered(q, ((int(q.nnz_out(0)),),))
        x = np.atleast_2d(np.asarray(x, dtype=float))
        out = np.empty((len(x), self._q.res[0].size))
        for k in range(len(x)):
            out[k] = self._q(x[k])[0]
        return out

    def follow(self, theta: np.ndarray, start: np.ndarray, out: np.ndarray) -> int:
        """Solve ``theta`` (n, 9) in order from the pose ``start`` (9,), writing each
        sample's x into ``out`` (n, 9); returns how many samples were solved (a prefix:
        the first sample not kept ends the run, module doc)."""
        x = np.array(start, dtype=float)
        th_x, Jx = self.kin(x)
        lu, piv, info = lapack.dgetrf(Jx)
        if info != 0:
            return 0
        th_prev = th_x.copy()
        for k in range(len(theta)):
            th = theta[k]
            x_new = x + lapack.dgetrs(lu, piv, wrapped(th - th_prev))[0]
            ok = False
            for _ in range(NEWTON + 1):
                th_x, Jx = self.kin(x_new)
                err = wrapped(th - th_x)
                if float(np.abs(err).max()) < TOL:
                    ok = True
                    break
                lu_k, piv_k, info = lapack.dgetrf(Jx)
                if info != 0:
                    break
                lu, piv = lu_k, piv_k
                step = lapack.dgetrs(lu, piv, err)[0]
                big = float(np.abs(step).max())
                if big > MAX_STEP:
                    step *= MAX_STEP / big
                x_new = x_new + step
            if not ok or float(np.abs(x_new - x).max()) >= JUMP:
                return k
            out[k] = x_new
            x, th_prev = x_new, th
        return len(theta)


__all__ = ["JUMP", "NEWTON", "TOL", "Buffered", "CompiledKinematics", "kinematics_buffer",
           "wrapped"]
