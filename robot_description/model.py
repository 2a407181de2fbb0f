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

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from sixplus3.robot_description.robot import NUM_LEGS
from sixplus3.robot_description.urdf import CLOSURES_PATH, POINT_MASS_URDF_PATH, URDF_PATH
from sixplus3.errors import InputError

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def parse_closures(path: Path) -> tuple[list[tuple[str, str]], list[str], list[str]]:
    """Read and validate a closures YAML; returns (pairs, types, actuated joint names)."""
    try:
        doc = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"cannot read closures file {path}: {exc}") from exc
    if not isinstance(doc, dict):
        raise InputError(f"closures file {path}: expected a mapping with keys closed_loop, "
                         "type, name_mot")
    for key in ("closed_loop", "type", "name_mot"):
        if key not in doc or not isinstance(doc[key], list):
            raise InputError(f"closures file {path}: missing list '{key}'")
    pairs = doc["closed_loop"]
    types = doc["type"]
    if len(pairs) != len(types):
        raise InputError(f"closures file {path}: {len(pairs)} closed_loop pairs but "
                         f"{len(types)} types")
    for k, pair in enumerate(pairs):
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(s, str)
                                                                   for s in pair)):
            raise InputError(f"closures file {path}: closed_loop[{k}] must be two frame names")
    for k, t in enumerate(types):
        if t != "3d":
            raise InputError(f"closures file {path}: type[{k}] = {t!r}; only '3d' (spherical "
                             "joint) closures exist in this robot")
    return [tuple(p) for p in pairs], list(types), [str(n) for n in doc["name_mot"]]


@dataclass
class ClosedLoopModel:
    """A Pinocchio model of the spanning tree plus its 3D loop-closure constraints."""

    model: pin.Model
    pairs: list[tuple[str, str]]
    actuated_names: list[str]
    urdf_path: Path
    closures_path: Path
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
                    raise InputError(f"closure frame {name!r} is not in {self.urdf_path.name}")
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
        q_idx, v_idx = [], []
        for name in self.actuated_names:
            if not m.existJointName(name):
                raise InputError(f"actuated joint {name!r} is not in {self.urdf_path.name}")
            j = m.joints[m.getJointId(name)]
            if j.nq != 1 or j.nv != 1:
                raise InputError(f"actuated joint {name!r} must be a 1-DoF revolute joint")
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

    def v_index(self, joint: str) -> int:
        return int(self.model.joints[self.model.getJointId(joint)].idx_v)

    # ------------------------------------------------------------------ closures
    def residual(self, q: np.ndarray) -> np.ndarray:
        """(27,) o_A - o_B in the world frame [m]."""
        m, d = self.model, self.data
        pin.framesForwardKinematics(m, d, q)
        return np.concatenate([d.oMf[a].translation - d.oMf[b].translation
                               for a, b in self.frame_pairs])

    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """(27, nv) Jc = J_A - J_B (linear, world-aligned); also updates frame placements."""
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        return np.vstack([
            pin.getFrameJacobian(m, d, a, LWA)[:3] - pin.getFrameJacobian(m, d, b, LWA)[:3]
            for a, b in self.frame_pairs])

    def drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(27,) gamma: closure acceleration at a = 0 (so that Jc a + gamma = 0) [m/s^2]."""
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, q, v, np.zeros(m.nv))
        return np.concatenate([
            pin.getFrameClassicalAcceleration(m, d, a, LWA).linear
            - pin.getFrameClassicalAcceleration(m, d, b, LWA).linear
            for a, b in self.frame_pairs])

    def frame_position(self, name: str) -> np.ndarray:
        """World position of a frame after the last kinematics update [m]."""
        return self.data.oMf[self.model.getFrameId(name)].translation.copy()

    def total_mass(self) -> float:
        return float(sum(inertia.mass for inertia in self.model.inertias))


def _load(urdf: Path, closures: Path) -> ClosedLoopModel:
    if not Path(urdf).exists():
        raise InputError(f"URDF not found: {urdf} (run: python -m sixplus3.robot_description.urdf)")
    model = pin.buildModelFromUrdf(str(urdf))
    pairs, _types, act = parse_closures(closures)
    if len(pairs) != 3 * NUM_LEGS or len(act) != 3 * NUM_LEGS:
        raise InputError(f"{closures}: expected {3 * NUM_LEGS} closures and "
                         f"{3 * NUM_LEGS} actuated joints, got {len(pairs)} and {len(act)}")
    return ClosedLoopModel(model, pairs, act, Path(urdf), Path(closures))


@functools.lru_cache(maxsize=4)
def load_model(point_mass: bool = False) -> ClosedLoopModel:
    """The committed robot (or its point-mass variant) as a closed-loop model (cached).

    The returned object owns mutable Pinocchio data: use one per thread.
    """
    return _load(POINT_MASS_URDF_PATH if point_mass else URDF_PATH, CLOSURES_PATH)


def load_model_from(urdf: Path, closures: Path) -> ClosedLoopModel:
    """Load another URDF + closures pair (not cached)."""
    return _load(Path(urdf), Path(closures))
