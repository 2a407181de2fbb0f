"""Load the URDF + closures into a Pinocchio closed-loop model (Pinocchio 4 API).

The closures YAML (Extended URDF schema) is validated; every closure becomes a
``RigidConstraintModel(CONTACT_3D, ...)`` between the parent joints of its two frames.
Besides the constraint models used by ``constraintDynamics``, :class:`ClosedLoopModel`
gives the closure residual, its Jacobian and its acceleration drift in the world frame:

    r(q) = o_A(q) - o_B(q)                      (27,)  [m]
    dr/dt = Jc(q) v,  Jc = J_A - J_B            (27, 36), LOCAL_WORLD_ALIGNED linear rows
    d2r/dt2 = Jc a + gamma(q, v)                gamma = classical acc. of A - B at a = 0
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from sixplus3.cache import cached
from sixplus3.errors import InputError
from sixplus3.fileio import read_yaml
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS
from sixplus3.robot_description.urdf import actuated_joint_names, closure_pairs, robot_urdf

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def parse_closures(path: Path) -> tuple[list[tuple[str, str]], list[str], list[str]]:
    """Read and validate a closures YAML; returns (pairs, types, actuated joint names)."""
    doc = read_yaml(path, "closures file")
    if not isinstance(doc, dict):
        raise InputError(f"closures file {path}: expected a mapping with keys closed_loop, "
                         "type, name_mot",
                         value=type(doc).__name__,
                         valid="a mapping with keys closed_loop, type, name_mot")
    for key in ("closed_loop", "type", "name_mot"):
        if key not in doc or not isinstance(doc[key], list):
            raise InputError(f"closures file {path}: missing list '{key}'",
                             value=key, valid="lists closed_loop, type, name_mot")
    pairs = doc["closed_loop"]
    types = doc["type"]
    if len(pairs) != len(types):
        raise InputError(f"closures file {path}: {len(pairs)} closed_loop pairs but "
                         f"{len(types)} types",
                         value=(len(pairs), len(types)),
                         valid="as many types as closed_loop pairs")
    for k, pair in enumerate(pairs):
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(s, str)
                                                                   for s in pair)):
            raise InputError(f"closures file {path}: closed_loop[{k}] must be two frame names",
                             value=pair, valid="two frame names")
    for k, t in enumerate(types):
        if t != "3d":
            raise InputError(f"closures file {path}: type[{k}] = {t!r}; only '3d' (spherical "
                             "joint) closures exist in this robot", value=t, valid="'3d'")
    return [tuple(p) for p in pairs], list(types), [str(n) for n in doc["name_mot"]]


@dataclass(frozen=True)
class ClosureKinematics:
    """What :meth:`ClosedLoopModel.constraint_jacobian_batch` computed for n
    configurations and :meth:`ClosedLoopModel.drift_batch` reuses."""

    J: np.ndarray  # (n, 6, nv) joint Jacobians in the world frame, [v_o; w] per column
    points: np.ndarray  # (n, 9, 3) world position of each closed pair's frame A [m]


@dataclass
class ClosedLoopModel:
    """A Pinocchio model of the spanning tree plus its 3D loop-closure constraints."""

    model: pin.Model
    pairs: list[tuple[str, str]]
    actuated_names: list[str]
    source: str  # where the tree came from (a path, or "Robot <hash>")
    robot: Robot | None = None  # the robot it was built from, if any
    data: pin.Data = field(init=False)
    frame_pairs: list[tuple[int, int]] = field(init=False)
    constraint_models: pin.StdVec_RigidConstraintModel = field(init=False)
    constraint_datas: pin.StdVec_RigidConstraintData = field(init=False)
    idx_q_act: np.ndarray = field(init=False)  # (9,) q indices of the actuated joints
    idx_v_act: np.ndarray = field(init=False)  # (9,)
    idx_v_pas: np.ndarray = field(init=False)  # (nv - 9,)

    def __post_init__(self) -> None:
        m = self.model
        self.data = m.createData()
        self.frame_pairs = []
        self.constraint_models = pin.StdVec_RigidConstraintModel()
        for a, b in self.pairs:
            ids = []
            for name in (a, b):
                if not m.existFrame(name):
                    raise InputError(f"closure frame {name!r} is not in {self.source}",
                                     value=name, valid=f"a frame of {self.source}")
                ids.append(m.getFrameId(name))
            fa, fb = m.frames[ids[0]], m.frames[ids[1]]
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, m, fa.parentJoint,
                                          fa.placement, fb.parentJoint, fb.placement,
                                          pin.ReferenceFrame.LOCAL)
            cm.name = f"{a}-{b}"
            self.constraint_models.append(cm)
            self.frame_pairs.append((ids[0], ids[1]))
        self.constraint_datas = pin.StdVec_RigidConstraintData()
        for cm in self.constraint_models:
            self.constraint_datas.append(cm.createData())
        # the same closures expressed LOCAL_WORLD_ALIGNED: Pinocchio's constraint Jacobian
        # of these is J_A - J_B (linear, world-aligned) in one call
        self._cm_lwa = pin.StdVec_RigidConstraintModel()
        self._cd_lwa = pin.StdVec_RigidConstraintData()
        for ia, ib in self.frame_pairs:
            fa, fb = m.frames[ia], m.frames[ib]
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, m, fa.parentJoint,
                                          fa.placement, fb.parentJoint, fb.placement, LWA)
            self._cm_lwa.append(cm)
            self._cd_lwa.append(cm.createData())
        self._calcs = [(cm.calc, cd) for cm, cd in zip(self._cm_lwa, self._cd_lwa,
                                                         strict=True)]
        self._zero_v = np.zeros(m.nv)
        self._supports: np.ndarray | None = None  # see _closure_supports
        self._frames_a = [ia for ia, _ in self.frame_pairs]
        q_idx, v_idx = [], []
        for name in self.actuated_names:
            if not m.existJointName(name):
                raise InputError(f"actuated joint {name!r} is not in {self.source}",
                                 value=name, valid=f"a joint of {self.source}")
            j = m.joints[m.getJointId(name)]
            if j.nq != 1 or j.nv != 1:
                raise InputError(f"actuated joint {name!r} must be a 1-DoF revolute joint",
                                 value=name, valid="a 1-DoF revolute joint")
            q_idx.append(j.idx_q)
            v_idx.append(j.idx_v)
        self.idx_q_act = np.array(q_idx)
        self.idx_v_act = np.array(v_idx)
        self.idx_v_pas = np.setdiff1d(np.arange(m.nv), self.idx_v_act)

    # ------------------------------------------------------------------ sizes
    @property
    def n_constraints(self) -> int:
        return 3 * len(self.pairs)

    @property
    def mobility(self) -> int:
        """Tree DoF minus independent constraint rows (generic: 36 - 27 = 9)."""
        return self.model.nv - self.n_constraints

    def q_index(self, joint: str) -> int:
        return int(self.model.joints[self.model.getJointId(joint)].idx_q)

    # ------------------------------------------------------------------ closures
    def residual(self, q: np.ndarray) -> np.ndarray:
        """(27,) o_A - o_B in the world frame [m]."""
        m, d = self.model, self.data
        pin.framesForwardKinematics(m, d, q)
        return np.concatenate([d.oMf[a].translation - d.oMf[b].translation
                               for a, b in self.frame_pairs])

    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """(27, nv) Jc = J_A - J_B (linear, world-aligned); also updates the joint
        placements and Jacobians (not the frame placements)."""
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        for calc, cd in self._calcs:
            calc(m, d, cd)
        return pin.getConstraintsJacobian(m, d, self._cm_lwa, self._cd_lwa)

    def drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(27,) gamma: closure acceleration at a = 0 (so that Jc a + gamma = 0) [m/s^2]."""
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, q, v, self._zero_v)
        acc = pin.getFrameClassicalAcceleration
        # the Motion difference in C++, one array per closure (the validator's hot loop)
        return np.array([(acc(m, d, a, LWA) - acc(m, d, b, LWA)).linear
                         for a, b in self.frame_pairs]).ravel()

    def constraint_jacobian_batch(self, q: np.ndarray, drift: bool = True
                                  ) -> tuple[np.ndarray, ClosureKinematics]:
        """:meth:`constraint_jacobian` of n configurations q (n, nq) at once: (Jc (n, 27,
        nv), the joint Jacobians and closure points that :meth:`drift_batch` reuses).

        One Pinocchio pass per configuration: the closure Jacobian, and with ``drift``
        the joints' world-frame Jacobians J = [v_o; w] (spatial velocity at the world
        origin per column) and frame A's world position per pair (without it, these are
        left empty: a static caller needs no drift).
        """
        m, d = self.model, self.data
        q = np.asarray(q, dtype=float)
        n = len(q)
        Jc = np.empty((n, self.n_constraints, m.nv))
        J = np.empty((n if drift else 0, 6, m.nv))
        P = np.empty((n if drift else 0, len(self.frame_pairs), 3))
        jac, frame, fa = self.constraint_jacobian, pin.updateFramePlacement, self._frames_a
        for k in range(n):
            Jc[k] = jac(q[k])
            if drift:
                J[k] = d.J
                P[k] = [frame(m, d, i).translation for i in fa]
        return Jc, ClosureKinematics(J=J, points=P)

    def _closure_supports(self) -> np.ndarray:
        """(9, 2, nv) bool: the velocity coordinates moving each pair's frame A, frame B
        (from the tree's supports; made on first use, not per model copy)."""
        if self._supports is None:
            m = self.model
            sup = np.zeros((len(self.frame_pairs), 2, m.nv), dtype=bool)
            for k, pair in enumerate(self.frame_pairs):
                for side, fid in enumerate(pair):
                    for j in m.supports[m.frames[fid].parentJoint]:
                        if j > 0:
                            jm = m.joints[j]
                            sup[k, side, jm.idx_v:jm.idx_v + jm.nv] = True
            self._supports = sup
        return self._supports

    def drift_batch(self, q: np.ndarray, v: np.ndarray, kin: ClosureKinematics,
                    rows: np.ndarray | None = None) -> np.ndarray:
        """:meth:`drift` of n states (q, v (n, nv)) at once: (n, 27) [m/s^2].

        ``kin`` from :meth:`constraint_jacobian_batch` of the same q.  One Pinocchio call
        per state gives the time variation dJ of the world-frame Jacobian.  Over the
        joints supporting a body, its spatial velocity is V = J v = [v_o; w] and its
        spatial acceleration at a = 0 is A = dJ v; a point p of it moves at
        v_p = v_o + w x p with the classical acceleration a_p = A_lin + A_ang x p + w x v_p.
        gamma is a_p of frame A's body minus that of frame B's, at frame A's point.
        Tested against :meth:`drift` per state.  ``rows``
        (n,) bool: compute only these states (the others, e.g. at rest, get 0).
        """
        m, d = self.model, self.data
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        n = len(q)
        if len(kin.J) != n:
            raise InputError(f"drift_batch: kinematics of {len(kin.J)} states for {n} (made "
                             "by constraint_jacobian_batch with drift=True of the same q?)",
                             value=len(kin.J), valid=n)
        idx = np.arange(n) if rows is None else np.flatnonzero(rows)
        gamma = np.zeros((n, self.n_constraints))
        if len(idx) == 0:
            return gamma
        dJ = np.empty((len(idx), 6, m.nv))
        variation = pin.computeJointJacobiansTimeVariation
        for i, k in enumerate(idx):
            variation(m, d, q[k], v[k])
            dJ[i] = d.dJ
        J, P, vv = kin.J[idx], kin.points[idx], v[idx]
        # the bodies of every pair's frames A and B (columns 2c, 2c + 1): their spatial
        # velocity V = [v_o; w] and acceleration at a = 0, A = dJ v, over their supports
        # (einsum, not a BLAS product: BLAS threads would contend with the validator's
        # worker process for the two cores)
        S = self._closure_supports().reshape(-1, m.nv).astype(float)  # (18, nv)
        nk = len(idx)
        vel = np.einsum("nij,sj->nsi", J * vv[:, None, :], S)  # (n, 18, 6)
        spat = np.einsum("nij,sj->nsi", dJ * vv[:, None, :], S)
        p = np.repeat(P, 2, axis=1)  # frame A's point for both bodies of a pair
        w = vel[..., 3:]
        vp = vel[..., :3] + np.cross(w, p)
        acc = spat[..., :3] + np.cross(spat[..., 3:], p) + np.cross(w, vp)
        gamma[idx] = (acc[:, 0::2] - acc[:, 1::2]).reshape(nk, self.n_constraints)
        return gamma

    def urdf_configuration(self, q: np.ndarray) -> tuple[dict[str, np.ndarray],
                                                          dict[str, float]]:
        """q (nq,) as URDF tools want it: ({floating joint: 4x4 pose of its child in its
        parent link's frame, the URDF origin included}, {1-DoF joint: angle [rad]}).

        yourdfpy's ``update_cfg`` ignores a floating joint's value (its forward kinematics
        uses only the joint origin), so :func:`pose_yourdfpy` puts the pose there."""
        m = self.model
        q = np.asarray(q, dtype=float)
        if q.shape != (m.nq,) or not np.isfinite(q).all():
            raise InputError(f"q must be {m.nq} finite numbers, got shape {q.shape}",
                             value=q.shape, valid=f"({m.nq},) finite")
        floating: dict[str, np.ndarray] = {}
        angles: dict[str, float] = {}
        for jid in range(1, m.njoints):
            j, name = m.joints[jid], m.names[jid]
            if j.nq == 7:  # the free-flyer: xyz, quaternion (x, y, z, w)
                motion = pin.XYZQUATToSE3(q[j.idx_q:j.idx_q + 7])
                floating[name] = (m.jointPlacements[jid] * motion).homogeneous
            elif j.nq == 1:
                angles[name] = float(q[j.idx_q])
            else:
                raise InputError(f"joint {name!r} has {j.nq} coordinates; URDF tools know "
                                 "1-DoF and floating joints", value=j.nq, valid="1 or 7")
        return floating, angles

    def frame_position(self, name: str) -> np.ndarray:
        """World position of a frame after the last kinematics update [m]."""
        return self.data.oMf[self.model.getFrameId(name)].translation.copy()

    def total_mass(self) -> float:
        return float(sum(inertia.mass for inertia in self.model.inertias))


def pose_yourdfpy(urdf: Any, clm: ClosedLoopModel, q: np.ndarray) -> None:
    """Pose a ``yourdfpy.URDF`` of this robot at Pinocchio's q (nq,): the platform's
    floating joint through its origin (``update_cfg`` ignores floating values), every
    revolute joint through ``update_cfg``.  Tested: the closure frame pairs coincide and
    every frame is where Pinocchio puts it."""
    floating, angles = clm.urdf_configuration(q)
    for name, T in floating.items():
        urdf.joint_map[name].origin = T
    # a floating joint named in the configuration has its scene edge redone from the
    # origin; its value is not used (its current one is passed, whatever its size)
    names = list(urdf.actuated_joint_names)
    same = {name: np.array(urdf.cfg[urdf.actuated_dof_indices[names.index(name)]])
            for name in floating}
    urdf.update_cfg({**angles, **same})


def _check_sizes(pairs: list[Any], act: list[Any], where: str) -> None:
    if len(pairs) != 3 * NUM_LEGS or len(act) != 3 * NUM_LEGS:
        raise InputError(f"{where}: expected {3 * NUM_LEGS} closures and "
                         f"{3 * NUM_LEGS} actuated joints, got {len(pairs)} and {len(act)}",
                         value=(len(pairs), len(act)),
                         valid=f"{3 * NUM_LEGS} and {3 * NUM_LEGS}")


def closed_loop_model(robot: Robot) -> ClosedLoopModel:
    """A new closed-loop model of ``robot``, caller-owned.

    The Pinocchio model parsed from ``robot_urdf(robot)`` is cached by the robot's hash; each
    call returns a copy of it with gravity set from ``robot.gravity`` and its own data and
    constraint models: one object per thread, no shared mutable state.
    """
    robot = require_robot(robot)

    def parse() -> pin.Model:
        return pin.buildModelFromXML(robot_urdf(robot))

    model = cached(("pinocchio", f"{robot.hash}:{robot.name}"), parse).copy()
    model.gravity = pin.Motion(np.array(robot.gravity), np.zeros(3))
    pairs, act = closure_pairs(), actuated_joint_names()
    _check_sizes(pairs, act, "robot")
    clm = ClosedLoopModel(model, pairs, act, f"robot {robot.hash[:12]}", robot)
    # the reflected rotor inertia of the motors: rnea and crba include model.armature
    model.armature[clm.idx_v_act] = robot.motors.armature_per_joint
    return clm


def load_model_from(urdf: Path, closures: Path) -> ClosedLoopModel:
    """Load another URDF + closures pair from files (not cached; gravity -z)."""
    if not Path(urdf).exists():
        raise InputError(f"URDF not found: {urdf}", value=str(urdf), valid="an existing URDF file")
    model = pin.buildModelFromUrdf(str(urdf))
    pairs, _types, act = parse_closures(closures)
    _check_sizes(pairs, act, str(closures))
    return ClosedLoopModel(model, pairs, act, str(urdf))
