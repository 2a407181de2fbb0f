"""MuJoCo's model of a robot (:class:`MujocoRobot`) and the mapping between its
coordinates and Pinocchio's: what the drive loop (:mod:`~sixplus3.control.drive.loop`),
the replays and the cross-checks (:mod:`~sixplus3.control.drive.simulation`) run.

``mujoco`` is an optional dependency (``pip install sixplus3[sim]``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from sixplus3.errors import InputError
from sixplus3.robot_description.mjcf import TIMESTEP, build_mjcf
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.urdf import actuated_joint_names, closure_pairs


def _mujoco() -> Any:
    try:
        # deferred: MuJoCo loads only when this runs
        import mujoco
    except ImportError:  # pragma: no cover - depends on the install
        raise InputError("MuJoCo is not installed: pip install 'sixplus3[sim]'",
                         value="mujoco", valid="the mujoco package installed") from None
    return mujoco


class MujocoRobot:
    """A MuJoCo model of ``robot`` and the mapping to Pinocchio's coordinates."""

    def __init__(self, robot: Robot, timestep: float = TIMESTEP) -> None:
        mj = self.mj = _mujoco()
        self.robot = require_robot(robot)
        # unlimited actuators: the replay reports the torque it commands, saturated or not
        self.model = mj.MjModel.from_xml_string(build_mjcf(self.robot, timestep,
                                                           limits=False))
        self.data = mj.MjData(self.model)
        clm = closed_loop_model(self.robot)
        pm = clm.model
        m = self.model
        self.nv = m.nv
        # Pinocchio joint -> MuJoCo addresses
        self._hinges: list[tuple[int, int, int, int]] = []  # (pin iq, pin iv, mj qadr, dadr)
        self._free: tuple[int, int] | None = None
        for j in range(1, pm.njoints):
            jid = mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, pm.names[j])
            jm = pm.joints[j]
            if jm.shortname() == "JointModelFreeFlyer":
                self._free = (jm.idx_q, int(m.jnt_qposadr[jid]))
            else:
                self._hinges.append((jm.idx_q, jm.idx_v, int(m.jnt_qposadr[jid]),
                                     int(m.jnt_dofadr[jid])))
        self.act_dof = np.array([m.jnt_dofadr[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, n)]
                                 for n in actuated_joint_names()])
        self.act_qpos = np.array([m.jnt_qposadr[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, n)]
                                  for n in actuated_joint_names()])
        self._sites = [(mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, a),
                        mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, b)) for a, b in closure_pairs()]
        self._S = np.zeros((len(self.act_dof), m.nv))
        self._S[np.arange(len(self.act_dof)), self.act_dof] = 1.0

    # ------------------------------------------------------------------ state
    def qpos_from_pinocchio(self, q: np.ndarray) -> np.ndarray:
        qpos = np.zeros(self.model.nq)
        for iq, _iv, qa, _da in self._hinges:
            qpos[qa] = q[iq]
        assert self._free is not None
        iq, qa = self._free
        qpos[qa:qa + 3] = q[iq:iq + 3]
        x, y, z, w = q[iq + 3:iq + 7]
        qpos[qa + 3:qa + 7] = (w, x, y, z)
        return qpos

    def _forward(self, qpos: np.ndarray, qvel: np.ndarray | None = None) -> None:
        d = self.data
        d.qpos[:] = qpos
        d.qvel[:] = 0.0 if qvel is None else qvel
        d.qacc[:] = 0.0
        self.mj.mj_forward(self.model, d)

    def closure_residual(self) -> float:
        """Largest distance between the two sites of a closure, after the last update [m]."""
        d = self.data
        return float(max(np.linalg.norm(d.site_xpos[a] - d.site_xpos[b])
                         for a, b in self._sites))

    def closure_jacobian(self) -> np.ndarray:
        """(27, nv) Jc = J(site1) - J(site2), world frame, at the last update."""
        mj, m, d = self.mj, self.model, self.data
        rows = []
        ja, jb = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for a, b in self._sites:
            mj.mj_jacSite(m, d, ja, None, a)
            mj.mj_jacSite(m, d, jb, None, b)
            rows.append(ja - jb)
        return np.vstack(rows)

    def closure_drift(self) -> np.ndarray:
        """(27,) Jc_dot qvel at the last update (``mj_jacDot`` at the site points)."""
        mj, m, d = self.mj, self.model, self.data
        out = []
        ja, jb, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for a, b in self._sites:
            mj.mj_jacDot(m, d, ja, jr, d.site_xpos[a], m.site_bodyid[a])
            mj.mj_jacDot(m, d, jb, jr, d.site_xpos[b], m.site_bodyid[b])
            out.append((ja - jb) @ d.qvel)
        return np.concatenate(out)

    def set_state(self, q: np.ndarray, theta_dot: np.ndarray) -> tuple[np.ndarray, float]:
        """Put MuJoCo at the configuration q (Pinocchio's coordinates) with the tree
        velocity that realises the actuated rates: [S; Jc] qvel = [theta_dot; 0], from
        MuJoCo's own closure Jacobian.  Returns ([S; Jc], closure residual [m])."""
        qpos = self.qpos_from_pinocchio(q)
        self._forward(qpos)
        res = self.closure_residual()
        A = np.vstack([self._S, self.closure_jacobian()])
        qvel = np.linalg.solve(A, np.r_[theta_dot, np.zeros(len(A) - len(self._S))])
        self._forward(qpos, qvel)
        return A, res

    def inverse_dynamics(self, q: np.ndarray, theta_dot: np.ndarray,
                         theta_ddot: np.ndarray) -> tuple[np.ndarray, float]:
        """(tau [N m], closure residual [m]) of the actuated motion through the
        configuration q (Pinocchio's coordinates) with MuJoCo's dynamics."""
        mj, m, d = self.mj, self.model, self.data
        A, res = self.set_state(q, theta_dot)
        Jc = A[len(self._S):]
        qacc = np.linalg.solve(A, np.r_[theta_ddot, -self.closure_drift()])
        M = np.zeros((m.nv, m.nv))
        mj.mj_fullM(m, d, M)
        rhs = M @ qacc + d.qfrc_bias
        sol = np.linalg.solve(np.hstack([self._S.T, Jc.T]), rhs)
        tau = sol[:len(self.act_dof)] + self.robot.motors.friction(theta_dot)
        return tau, res


__all__ = ["MujocoRobot"]
