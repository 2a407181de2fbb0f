"""The atlas's admissibility check of a batch of poses (the module doc of
:mod:`sixplus3.design.atlas` lists the checks and the crank candidates): the compiled
kernel's checks 1-6 (:mod:`sixplus3.design._atlas_kernel`) and the compiled statics'
torque check 7, for the locked and the searched (free) cranks."""

from __future__ import annotations

import casadi as ca
import numpy as np

from sixplus3.cache import cached
from sixplus3.design import _atlas_kernel as _kernel
from sixplus3.design.atlas_data import PSI_RANGE_DEG
from sixplus3.dynamics import codegen
from sixplus3.dynamics.symbolic import (
    acceleration_function,
    holding_function,
    setup_parameters,
    structure,
)
from sixplus3.kinematics.rotations import rotvec_from_matrix
from sixplus3.robot_description.geometry import GRAVITY
from sixplus3.robot_description.robot import Robot


class PoseChecker:
    """Admissibility of batches of poses for one robot (module doc)."""

    def __init__(self, robot: Robot, psi_step_deg: float, accel_g: float = 0.0):

        self.robot = robot
        self.lim = robot.limits
        self.accel = float(accel_g) * GRAVITY  # [m/s^2]
        make = acceleration_function if accel_g > 0 else holding_function
        self.hold = codegen.compiled_small(make(robot), structure(robot).hash)
        self.setup = ca.DM(setup_parameters(robot))
        lo, hi = PSI_RANGE_DEG
        self.psi_grid = np.radians(np.arange(lo, hi + 1e-9, psi_step_deg))
        self.home = np.asarray(robot.home_psi, dtype=float)
        self.packed = _kernel.pack(robot)
        # the platform margin depends on the crank angles only: tabulated on the grid
        self.platform_grid = cached(("atlas-platform", f"{robot.hash}:{psi_step_deg}"),
                                     lambda: self._platform_table())
        self.platform_home = float(_kernel.platform_margins(self.home[None], *self.packed[:2])[0])
        self.evaluations = 0  # poses judged (one per admissible() row)

    def _platform_table(self) -> np.ndarray:
        """(G, G, G) platform margins of every crank-grid triple."""
        G = len(self.psi_grid)
        tri = np.stack(np.meshgrid(self.psi_grid, self.psi_grid, self.psi_grid,
                                   indexing="ij"), axis=-1).reshape(-1, 3)
        return _kernel.platform_margins(tri, *self.packed[:2]).reshape(G, G, G)

    def _full(self, pos: np.ndarray, R: np.ndarray, psi: np.ndarray,
              platform: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Checks of (n, k) candidate crank choices psi (n, k, 3) with platform margins
        ``platform`` (n, k): (stage (n, k) = number of checks 1-7 passed, margin (n, k):
        the smallest margin where all pass, else -inf).

        Checks 1-6 are compiled (:mod:`design._atlas_kernel`, each check only where the
        ones before it passed); the holding torque is computed only for the
        best-margin candidate of each pose, then the next best where it fails.
        """
        stage, margin = _kernel.pose_checks(
            np.ascontiguousarray(pos), np.ascontiguousarray(R), np.ascontiguousarray(psi),
            np.ascontiguousarray(platform, dtype=float), self.packed)
        return self._torque(pos, R, psi, stage, margin)

    def _torque(self, pos: np.ndarray, R: np.ndarray, psi: np.ndarray, stage: np.ndarray,
                margin_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Check 7 on candidates psi (n, k, 3) with the results (stage, margin) of 1-6."""
        n, k = psi.shape[:2]
        # torque, lazily: best candidate first, then the next best where it fails
        torque = np.zeros((n, k), dtype=bool)
        order = np.argsort(-margin_all, axis=1)
        undecided = np.ones(n, dtype=bool)
        for r in range(k):
            j = order[:, r]
            cand = undecided & (margin_all[np.arange(n), j] > -np.inf)
            if not cand.any():
                break
            rows = np.flatnonzero(cand)
            tau = self.required_torques(pos[rows], R[rows], psi[rows, j[rows]])
            good = np.all(tau <= self.lim.torque, axis=1)  # NaN (singular): False
            torque[rows[good], j[rows[good]]] = True
            undecided[rows[good]] = False
        stage = stage + torque
        return stage, np.where(torque, margin_all, -np.inf)

    def required_torques(self, pos: np.ndarray, R: np.ndarray, psi: np.ndarray) -> np.ndarray:
        """(n, 9) |torque| [N m] each motor needs at poses whose IK solves (check 7).

        Without ``accel_g``: the static holding torque, from the compiled symbolic statics
        (:func:`dynamics.symbolic.holding_function`, with the robot's payload and mounting),
        equal to Pinocchio's to rounding (tested).  With it: at rest the torques are
        tau_0 + A a for a platform-centre acceleration a (no angular or crank
        acceleration; :func:`dynamics.symbolic.acceleration_function`), so the largest over
        every direction of |a| = accel_g g is |tau_0| + accel_g g |A_j| per motor j.
        """
        x = np.c_[pos, rotvec_from_matrix(R), psi].T
        n = x.shape[1]
        if self.accel <= 0.0:
            return np.abs(np.asarray(self.hold.map(n)(x, self.setup)).T)
        tau0, A = self.hold.map(n)(x, self.setup)
        A = np.asarray(A).reshape(9, n, 3)  # the map puts the 9x3 blocks side by side
        return (np.abs(np.asarray(tau0)).T
                + self.accel * np.linalg.norm(A, axis=2).T)

    def admissible(self, pos: np.ndarray, R: np.ndarray,
                   free: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ok (n,), psi (n, 3) [rad] of the chosen candidate, binding code (n,))."""
        n = len(pos)
        self.evaluations += n
        home = np.broadcast_to(self.home, (n, 1, 3))
        pm_home = np.full((n, 1), self.platform_home)
        if not free:
            s_home, m_home = self._full(pos, R, home, pm_home)
            return self._pick(home, s_home, m_home, np.zeros(n, dtype=np.int8))
        idx, s4, m4, leg_best = _kernel.free_candidates(
            np.ascontiguousarray(pos), np.ascontiguousarray(R), self.psi_grid,
            self.platform_grid, self.packed)
        cand = np.concatenate([self.psi_grid[idx], home], axis=1)  # + home: (n, 5, 3)
        live = np.all(leg_best >= 4, axis=1)
        stage = np.zeros((n, 5), dtype=np.int8)
        margin = np.full((n, 5), -np.inf)
        stage[:, :4], margin[:, :4] = self._torque(pos, R, cand[:, :4], s4, m4)
        # the home candidate wherever no searched one passed: free >= locked by construction
        rest = ~np.any(margin[:, :4] > -np.inf, axis=1)
        if rest.any():
            s, m = self._full(pos[rest], R[rest], home[rest], pm_home[rest])
            stage[rest, 4:], margin[rest, 4:] = s, m
        # then, where still none passed, the three cranks at one grid value each: the
        # leg-wise choice does not see the legs' interference, which equal cranks keep
        # symmetric (on the default robot the largest tilt about x, 78.75 deg, is there)
        G = len(self.psi_grid)
        diag = np.repeat(self.psi_grid[:, None], 3, axis=1)  # (G, 3)
        cand = np.concatenate([cand, np.broadcast_to(diag, (n, G, 3))], axis=1)
        stage = np.concatenate([stage, np.zeros((n, G), dtype=np.int8)], axis=1)
        margin = np.concatenate([margin, np.full((n, G), -np.inf)], axis=1)
        rest = live & ~np.any(margin[:, :5] > -np.inf, axis=1)
        if rest.any():
            k = int(rest.sum())
            pm_diag = self.platform_grid[np.arange(G), np.arange(G), np.arange(G)]
            s, m = self._full(pos[rest], R[rest], np.broadcast_to(diag, (k, G, 3)).copy(),
                              np.broadcast_to(pm_diag, (k, G)).copy())
            stage[rest, 5:], margin[rest, 5:] = s, m
        dead = np.where(live, 0, leg_best.min(axis=1)).astype(np.int8)
        return self._pick(cand, stage, margin, dead)

    @staticmethod
    def _pick(cand: np.ndarray, stage: np.ndarray, margin: np.ndarray,
              dead: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = len(cand)
        best = np.argmax(margin, axis=1)
        ok = margin[np.arange(n), best] > -np.inf
        psi = cand[np.arange(n), best]
        reached = np.maximum(stage.max(axis=1), dead)
        binding = np.where(ok, 0, reached + 1).astype(np.int8)  # 1 = reach .. 7 = torque
        return ok, psi, binding
