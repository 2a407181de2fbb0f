"""The physical parts of the robot beyond its links: motors, payload, tool.

Motor model (per actuated joint, all nine identical; joint-side quantities):

    tau_motor,joint = tau_links(q, v, a) + I_a theta_ddot + b theta_dot
                      + tau_c tanh(theta_dot / omega_c)

- I_a = N^2 J_rotor is the rotor inertia reflected through the belt of ratio N = 72/34
  (motor turns per joint turn).  It is the joint's ``armature`` in Pinocchio
  (``model.armature``, which ``rnea`` and ``crba`` include) and the same term in the
  CasADi model and in the MJCF export.
- b (viscous) and tau_c (Coulomb) are joint-side friction of motor bearings + belt.
  The Coulomb term is smoothed by tanh over omega_c, in the planner, the validator and
  the MuJoCo simulation's feed-forward alike, so that torques stay continuous through
  zero speed (at rest it contributes nothing: static friction is not counted on to hold
  the robot, which is the conservative side).

Defaults and where they come from (docs/robot.md, "Motor model"):

- J_rotor = 51e-4 kg m^2 for the Yaskawa SGMCS-05B (small-capacity SGMCS, 5 N m rated,
  15 N m peak, outer diameter 135 mm).  ASSUMED: the SGMCS ratings table was not found
  in the searchable corpus; 51e-4 is the catalogue value as we recall it and lies
  between the rotor inertias of the neighbouring Sigma-7 direct-drive motors SGM7D-02K
  (60e-4) and SGM7D-06K (70e-4) listed in the SGMCS/SGM7D manual ("3.2.2 Ratings",
  manualshive.com/en/manual/yaskawa/sgmcs/907534?page=49).  Replace it with the value
  of the motors fitted.
- N = 72/34: the paper's belt (§V-A).
- b = 0.01 N m s/rad and tau_c = 0.10 N m at the joint: ASSUMED (bearing + belt losses
  of about 1 % of the 10 N m limit; no datasheet gives them).  Identify them on the
  prototype.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sixplus3.errors import GeometryError
from sixplus3.robot_description.hardware import check_motors

#: The paper's belt: 72-tooth pulley on the joint, 34-tooth on the motor.
BELT_RATIO = 72.0 / 34.0


def _num(name: str, v: Any, valid: str, lo: float = 0.0, hi: float = math.inf,
         lo_open: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise GeometryError(name, v, valid)
    if v < lo or v > hi or (lo_open and v == lo):
        raise GeometryError(name, v, valid)
    return float(v)


def _vec(name: str, v: Any, n: int, unit: str) -> tuple[float, ...]:
    try:
        arr = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise GeometryError(name, v, f"{n} finite numbers [{unit}]") from None
    if len(arr) != n or not all(math.isfinite(x) for x in arr):
        raise GeometryError(name, v, f"{n} finite numbers [{unit}]")
    return arr


@dataclass(frozen=True)
class MotorModel:
    """Motor, transmission and friction of every actuated joint (see module doc).

    ``model`` names the drive train in the hardware catalogue
    (:mod:`sixplus3.robot_description.hardware`): its ratings (``rated_torque``,
    ``gear_ratio``, ``encoder_bits``) must be the catalogue's, so that no robot file can
    raise the envelope.  What a lab measures (rotor inertia, friction, offsets,
    directions) is free."""

    model: str = field(default="SGMCS-05B+belt-72/34", metadata={
        "doc": "the drive train's catalogue key (motor + transmission): the envelope and "
               "the drive units come from the catalogue, never from this file"})
    rotor_inertia: float = field(default=51.0e-4, metadata={
        "doc": "rotor moment of inertia on the motor side [kg m^2] (SGMCS-05B, assumed)"})
    gear_ratio: float = field(default=BELT_RATIO, metadata={
        "doc": "motor turns per joint turn (72/34 belt)"})
    viscous: float = field(default=0.01, metadata={
        "doc": "joint-side viscous friction [N m s/rad] (assumed)"})
    coulomb: float = field(default=0.10, metadata={
        "doc": "joint-side Coulomb friction [N m] (assumed)"})
    coulomb_velocity: float = field(default=0.05, metadata={
        "doc": "speed over which the Coulomb term is smoothed by tanh [rad/s]"})
    encoder_bits: int = field(default=20, metadata={
        "doc": "motor encoder resolution [bit per motor turn] (SGMCS: 20-bit)"})
    rated_torque: float = field(default=5.0, metadata={
        "doc": "motor rated torque [N m] (SGMCS-05B: 5 N m): the unit of the drives' "
               "torque commands (0.1 % of rated)"})
    zero_offsets: tuple[float, ...] = field(default=(0.0,) * 9, metadata={
        "doc": "joint angle [rad] at which each motor's position reads 0 (legs 0..2, "
               "each A, B, C); set at commissioning"})
    directions: tuple[int, ...] = field(default=(1,) * 9, metadata={
        "doc": "+1 or -1: the sign of each motor's positive turn about the joint axis"})
    joint_armature: tuple[float, ...] | None = field(default=None, metadata={
        "doc": "per joint (legs 0..2, each A, B, C): the reflected rotor inertia at the "
               "joint [kg m^2], as identified; None: gear_ratio^2 rotor_inertia for all"})
    joint_viscous: tuple[float, ...] | None = field(default=None, metadata={
        "doc": "per joint: viscous friction [N m s/rad]; None: viscous for all"})
    joint_coulomb: tuple[float, ...] | None = field(default=None, metadata={
        "doc": "per joint: Coulomb friction [N m]; None: coulomb for all"})

    def __post_init__(self) -> None:
        object.__setattr__(self, "rotor_inertia", _num(
            "motors.rotor_inertia", self.rotor_inertia, "in [0, 1] kg m^2", 0.0, 1.0))
        object.__setattr__(self, "gear_ratio", _num(
            "motors.gear_ratio", self.gear_ratio, "in (0, 1000]", 0.0, 1000.0, True))
        object.__setattr__(self, "viscous", _num(
            "motors.viscous", self.viscous, "in [0, 10] N m s/rad", 0.0, 10.0))
        object.__setattr__(self, "coulomb", _num(
            "motors.coulomb", self.coulomb, "in [0, 10] N m", 0.0, 10.0))
        object.__setattr__(self, "coulomb_velocity", _num(
            "motors.coulomb_velocity", self.coulomb_velocity, "in (0, 10] rad/s", 0.0,
            10.0, True))
        b = self.encoder_bits
        if isinstance(b, bool) or not isinstance(b, int) or not 8 <= b <= 32:
            raise GeometryError("motors.encoder_bits", b, "an integer in [8, 32]")
        object.__setattr__(self, "rated_torque", _num(
            "motors.rated_torque", self.rated_torque, "in (0, 1000] N m", 0.0, 1000.0,
            True))
        offs = _vec("motors.zero_offsets", self.zero_offsets, 9, "rad")
        if max(abs(o) for o in offs) > 2 * math.pi:
            raise GeometryError("motors.zero_offsets", offs, "within one turn (|.| <= 2 pi)")
        object.__setattr__(self, "zero_offsets", offs)
        dirs = tuple(self.directions) if isinstance(self.directions, (list, tuple)) else ()
        if len(dirs) != 9 or any(isinstance(d, bool) or d not in (1, -1) for d in dirs):
            raise GeometryError("motors.directions", self.directions, "nine values +1 or -1")
        object.__setattr__(self, "directions", tuple(int(d) for d in dirs))
        for name, hi, unit in (("joint_armature", 1.0, "kg m^2"),
                               ("joint_viscous", 10.0, "N m s/rad"),
                               ("joint_coulomb", 10.0, "N m")):
            v = getattr(self, name)
            if v is None:
                continue
            vals = _vec(f"motors.{name}", v, 9, unit)
            if min(vals) < 0.0 or max(vals) > hi:
                raise GeometryError(f"motors.{name}", vals, f"nine values in [0, {hi:g}] "
                                    f"{unit}")
            object.__setattr__(self, name, vals)
        check_motors(self)

    @property
    def armature(self) -> float:
        """Reflected rotor inertia at the joint, N^2 J_rotor [kg m^2] (the catalogue
        motor's; :attr:`armature_per_joint` is what each joint has)."""
        return self.gear_ratio ** 2 * self.rotor_inertia

    @property
    def armature_per_joint(self) -> np.ndarray:
        """(9,) the reflected rotor inertia of each joint [kg m^2]."""
        if self.joint_armature is not None:
            return np.array(self.joint_armature)
        return np.full(9, self.armature)

    @property
    def viscous_per_joint(self) -> np.ndarray:
        """(9,) each joint's viscous friction [N m s/rad]."""
        return np.array(self.joint_viscous if self.joint_viscous is not None
                        else (self.viscous,) * 9)

    @property
    def coulomb_per_joint(self) -> np.ndarray:
        """(9,) each joint's Coulomb friction [N m]."""
        return np.array(self.joint_coulomb if self.joint_coulomb is not None
                        else (self.coulomb,) * 9)

    def friction(self, theta_dot: np.ndarray) -> np.ndarray:
        """Joint-side friction torque [N m] at joint rates theta_dot [rad/s] (..., 9)
        (per joint; a scalar law when no joint has its own values)."""
        w = np.asarray(theta_dot, dtype=float)
        if self.joint_viscous is None and self.joint_coulomb is None:
            return self.viscous * w + self.coulomb * np.tanh(w / self.coulomb_velocity)
        return (self.viscous_per_joint * w
                + self.coulomb_per_joint * np.tanh(w / self.coulomb_velocity))

    def motor_torque(self, theta_dot: np.ndarray, theta_ddot: np.ndarray) -> np.ndarray:
        """I_a theta_ddot + friction: what the motors add to the links' torque [N m]."""
        return self.armature * np.asarray(theta_ddot, dtype=float) + self.friction(theta_dot)


#: The links-only motor model (no rotor, no friction): the model of the paper.
NO_MOTORS = MotorModel(rotor_inertia=0.0, viscous=0.0, coulomb=0.0)


@dataclass(frozen=True)
class Payload:
    """A rigid load fixed to the platform (a handle, a tool, a hand's share).

    ``com`` [m] in the platform frame; ``inertia`` [kg m^2] about the centre of mass, in
    the platform frame's axes, as (ixx, iyy, izz, ixy, ixz, iyz).
    """

    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (0.0,) * 6

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", _num("payload.mass", self.mass,
                                              "in [0, 20] kg", 0.0, 20.0))
        object.__setattr__(self, "com", _vec("payload.com", self.com, 3, "m"))
        if max(abs(c) for c in self.com) > 1.0:
            raise GeometryError("payload.com", self.com, "within 1 m of the platform centre")
        inertia = _vec("payload.inertia", self.inertia, 6, "kg m^2")
        if max(abs(x) for x in inertia) > 10.0:
            raise GeometryError("payload.inertia", inertia, "components within 10 kg m^2 "
                                "(20 kg at 0.7 m)")
        object.__setattr__(self, "inertia", inertia)
        eig = np.linalg.eigvalsh(self.inertia_matrix)
        tol = 1e-12 + 1e-9 * max(abs(x) for x in inertia)
        if eig[0] < -tol or eig[2] > eig[0] + eig[1] + tol:
            raise GeometryError("payload.inertia", inertia,
                                "a physical inertia: positive semi-definite, principal "
                                "moments satisfying the triangle inequality")

    @property
    def inertia_matrix(self) -> np.ndarray:
        ixx, iyy, izz, ixy, ixz, iyz = self.inertia
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])

    @classmethod
    def point(cls, mass: float, com: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Payload:
        return cls(mass=mass, com=com)


@dataclass(frozen=True)
class Tool:
    """The tool centre point (TCP): its position [m] and orientation (roll, pitch, yaw
    about fixed x, y, z [rad], URDF's rpy) in the platform frame."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "xyz", _vec("tool.xyz", self.xyz, 3, "m"))
        if max(abs(c) for c in self.xyz) > 1.0:
            raise GeometryError("tool.xyz", self.xyz, "within 1 m of the platform centre")
        object.__setattr__(self, "rpy", _vec("tool.rpy", self.rpy, 3, "rad"))

    @property
    def rotation(self) -> np.ndarray:
        """R_platform_tcp (3, 3)."""
        # deferred: scipy.spatial's import (about 0.2 s) is not paid by the commands
        # that never read the tool's rotation (identify check, wrench)
        from scipy.spatial.transform import Rotation

        return Rotation.from_euler("xyz", self.rpy).as_matrix()  # Rz(y) Ry(p) Rx(r)

    def platform_pose(self, p_tcp: np.ndarray, R_tcp: np.ndarray) -> tuple[np.ndarray,
                                                                         np.ndarray]:
        """The platform pose (p, R) that puts the TCP at (p_tcp, R_tcp), robot frame."""
        Rt = self.rotation
        R = np.asarray(R_tcp, dtype=float) @ Rt.T
        return np.asarray(p_tcp, dtype=float) - R @ np.array(self.xyz), R

    def tcp_pose(self, p: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The TCP pose of a platform pose (p, R), robot frame."""
        R = np.asarray(R, dtype=float)
        return np.asarray(p, dtype=float) + R @ np.array(self.xyz), R @ self.rotation
