"""The gate's power and force limiting check (docs/safety.md): from the file's own
samples, recomputed independently of the planner, the largest contact energy over every
direction and every body region named, at the tool centre point, (under a tool) the
platform centre, and the vertices of every leg link judged (issue 70: the legs a person
can touch, :mod:`sixplus3.dynamics.leg_points`), against what the region's spring holds
at its ISO/TS 15066 limit.

The regions judged are the union of the file's header (``pfl``: the set it was planned
for) and the site's hardware file (``pfl``: the set the site requires, which no file can
drop).  The leg links likewise: the header's ``pfl_links`` (every reachable link when a
file names regions but no links) and the site's, which no file can drop.  The
configurations come from the gate's own forward kinematics (the report's platform pose
and crank angles), the platform's velocity from the actuated rates through the IK
Jacobian, a leg vertex's from Pinocchio's frame Jacobians through the closures, the
effective masses from Pinocchio's reduced inertia (rotors included).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sixplus3.control.gate.findings import finding
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.drive_contact import drive_cap, drive_ratio, reference_stop
from sixplus3.dynamics.effective_mass import (
    point_inverse_mass,
    point_jacobian,
    point_map,
    worst_direction,
    worst_normal,
)
from sixplus3.dynamics.leg_points import rates_from, vertex_jacobians
from sixplus3.errors import InputError
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import RobotConfig, robot_ik
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.motion import Motion
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import BodyRegion, names_of, regions
from sixplus3.robot_description.leg_links import vertex_label, vertices_of
from sixplus3.robot_description.robot import Robot

#: Points evaluated at a time (the reduced inertia of each: one Pinocchio pass).
CHUNK = 4096


@dataclass(frozen=True)
class Judged:
    """What power and force limiting is judged for: the body regions, and the leg links
    (``leg{i}_{link}``) whose vertices join the platform's points."""

    regions: tuple[BodyRegion, ...] = ()
    links: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.regions)

    def header(self) -> dict[str, list[str]]:
        """The header's record of what the file was judged for."""
        return {"pfl": names_of(self.regions), "pfl_links": list(self.links)} if self \
            else {}


def judged_regions(*named: object) -> tuple[BodyRegion, ...]:
    """The regions named by each of ``named`` (a header's list, a task's, ...) and those
    the site's hardware file requires, without repeats, in the standard's order."""
    names: list[str] = list(hardware.active().pfl)
    for n in named:
        if n is None:
            continue
        if not isinstance(n, (list, tuple)):
            raise InputError(f"pfl must be a list of body region names, got {n!r}",
                             value=n, valid="a list of region names")
        names += [str(x) for x in n]
    return regions(names)


def judged(pfl: object, links: object = None) -> Judged:
    """The regions (:func:`judged_regions`) and leg links judged for a file or task whose
    ``pfl`` names regions and ``links`` leg links (None: every reachable link), with the
    site's required ones, which no file can drop.  No region: nothing is judged."""
    regs = judged_regions(pfl)
    return Judged(regs, hardware.judged_links(links)) if regs else Judged()


def platform_twist(cfg: RobotConfig, theta_dot: np.ndarray) -> np.ndarray:
    """(n, 9) (v, omega, psi_dot) of the platform from the actuated rates through the
    inverse of the IK Jacobian (inf where it is singular)."""
    J = ik_jacobian(cfg)
    out = np.full((len(theta_dot), 9), np.inf)
    ok = np.all(np.isfinite(J), axis=(1, 2))
    if ok.any():
        out[ok] = np.linalg.solve(J[ok], np.asarray(theta_dot, dtype=float)[ok][:, :, None])[
            :, :, 0]
    return out


@dataclass(frozen=True)
class PflProfile:
    """Power and force limiting along a file, point by point (the gate's numbers):
    ``points`` the labels (``tcp``, ``centre``, ``leg0_D``, ...), ``speed`` (n, P)
    [m/s], ``mass`` (n, P, R) [kg] the effective mass along each region's worst
    direction, ``ratio`` (n, P, R) the worst direction's contact energy over the
    region's limit (the two-body force is ``sqrt(ratio)`` x the region's F_max);
    ``position`` (n, P, 3) [m] the points in the base frame."""

    points: tuple[str, ...]
    regions: tuple[BodyRegion, ...]
    position: np.ndarray
    speed: np.ndarray
    mass: np.ndarray
    ratio: np.ndarray

    def worst(self) -> tuple[int, str, int]:
        """(sample, point, region index) of the largest ratio (the first of equals)."""
        k, p, r = np.unravel_index(int(np.argmax(self.ratio)), self.ratio.shape)
        return int(k), self.points[int(p)], int(r)

    @property
    def force(self) -> np.ndarray:
        """(n, P, R) [N] the two-body model's contact force along the worst direction."""
        fmax = np.array([r.transient_force for r in self.regions])
        return np.sqrt(np.maximum(self.ratio, 0.0)) * fmax


def _worst(A: np.ndarray, v: np.ndarray, regs: tuple[BodyRegion, ...]
           ) -> tuple[np.ndarray, np.ndarray]:
    """(ratio (n, R), mass (n, R)) of points with inverse mass A (n, 3, 3) moving at v
    (n, 3): per region, E / E_max with E = 1/2 v^T (A + I/m_H)^-1 v (the worst direction
    n* along (A + I/m_H)^-1 v, :mod:`sixplus3.dynamics.effective_mass`) and the
    effective mass 1 / n*^T A n* along it (inf at rest)."""
    ratio = np.empty((len(v), len(regs)))
    mass = np.empty((len(v), len(regs)))
    ok = np.isfinite(A).all(axis=(1, 2)) & np.isfinite(v).all(axis=1)
    A, v = np.where(ok[:, None, None], A, 0.0), np.where(ok[:, None], v, 0.0)
    for k, r in enumerate(regs):
        energy, mass[:, k] = worst_direction(A, v, r)
        ratio[:, k] = energy / r.energy
    ratio[~ok], mass[~ok] = np.inf, np.nan
    return np.nan_to_num(ratio, nan=np.inf), mass


def _with_drive(ratio: np.ndarray, Jp: np.ndarray, M: np.ndarray, A: np.ndarray,
                thd: np.ndarray, tau: np.ndarray, cap: np.ndarray,
                regs: tuple[BodyRegion, ...], rate: float) -> np.ndarray:
    """``ratio`` (n, R) with each region's contact judged with the site's position loop
    in it too (:func:`sixplus3.dynamics.drive_contact.drive_ratio`; a clamp's reference
    stands after the guard's detection and one tick), along the two-body model's worst
    direction and the direction of motion: the larger of the two models.  No loop
    declared: ``ratio`` itself.  A: the points' inverse mass (n, 3, 3), from Jp and M."""
    hw = hardware.active()
    if hw.position_loop is None:
        return ratio
    ratio = ratio.copy()
    v = np.einsum("nij,nj->ni", Jp, thd)
    with np.errstate(all="ignore"):
        along = v / np.linalg.norm(v, axis=1, keepdims=True)
    for k, r in enumerate(regs):
        ratio[:, k] = np.maximum(ratio[:, k], drive_ratio(
            Jp, M, thd, tau, cap, r, hw.position_loop, rate,
            [worst_normal(A, v, r), along], reference_stop(r, rate)))
    return ratio


def pfl_profile(rep: ValidationReport, robot: Robot, motion: Motion, what: Judged
                ) -> PflProfile:
    """:class:`PflProfile` of ``motion``'s samples (a report whose forward kinematics
    went through: ``rep.position``, ``rep.quaternion``, ``rep.psi``).  A site that
    declares its drives' position loop has every region judged with it too
    (:func:`_with_drive`), on the gate's own torques (``rep.tau``)."""
    assert rep.position is not None and rep.quaternion is not None and rep.psi is not None
    dyn = ClosedLoopDynamics(robot)
    tool = tuple(float(c) for c in robot.tool.xyz)
    plat = [("tcp", tool)] + ([] if tool == (0.0, 0.0, 0.0) else [("centre", (0.0,) * 3)])
    verts = vertices_of(what.links)
    labels = tuple(p for p, _ in plat) + tuple(vertex_label(v) for v in verts)
    n, P, R = len(rep.position), len(labels), len(what.regions)
    speed, mass, ratio = np.empty((n, P)), np.empty((n, P, R)), np.empty((n, P, R))
    position = np.empty((n, P, 3))
    drive = hardware.active().position_loop is not None
    tau = np.zeros((n, 9)) if rep.tau is None else np.asarray(rep.tau, dtype=float)
    cap = drive_cap()  # the drives' own limit: the loop may ask up to it in a contact
    for i in range(0, n, CHUNK):
        sl = slice(i, min(n, i + CHUNK))
        R_ = rot.matrix_from_quat(rep.quaternion[sl])
        cfg = robot_ik(rep.position[sl], R_, rep.psi[sl], robot, platform_margins=False)
        twist = platform_twist(cfg, motion.theta_dot[sl])
        for j, (_, point) in enumerate(plat):
            if drive:  # the point's Jacobian and M once: the loop's model needs them too
                Jp, M = point_jacobian(dyn, cfg, point)
                A = rates_from(Jp[:, None], M, motion.theta_dot[sl])[1][:, 0]
            else:
                A = point_inverse_mass(dyn, cfg, point=point)
            r = np.einsum("nij,j->ni", cfg.rotation, np.asarray(point, dtype=float))
            v = np.einsum("nij,nj->ni", point_map(r), twist)
            position[sl, j] = cfg.position + r
            speed[sl, j] = np.linalg.norm(v, axis=1)
            ratio[sl, j], mass[sl, j] = _worst(A, v, what.regions)
            if drive:
                ratio[sl, j] = _with_drive(ratio[sl, j], Jp, M, A, motion.theta_dot[sl],
                                           tau[sl], cap, what.regions, motion.rate)
        if verts:
            pos, Jth, M = vertex_jacobians(dyn, cfg.q, verts)
            vel, A = rates_from(Jth, M, motion.theta_dot[sl])
            position[sl, len(plat):] = pos
            for k in range(len(verts)):
                j = len(plat) + k
                speed[sl, j] = np.linalg.norm(vel[:, k], axis=1)
                ratio[sl, j], mass[sl, j] = _worst(A[:, k], vel[:, k], what.regions)
                if drive:
                    ratio[sl, j] = _with_drive(ratio[sl, j], Jth[:, k], M, A[:, k],
                                               motion.theta_dot[sl], tau[sl], cap,
                                               what.regions, motion.rate)
    speed = np.nan_to_num(speed, nan=np.inf)
    return PflProfile(labels, what.regions, position, speed, mass,
                      np.nan_to_num(ratio, nan=np.inf))


def pfl_check(rep: ValidationReport, robot: Robot, motion: Motion, what: Judged
              ) -> ValidationReport:
    """``rep`` with the PFL check on the samples of ``motion`` (a report whose forward
    kinematics went through): its findings added, ``pfl``, ``pfl_links``,
    ``max_pfl_ratio`` and ``max_pfl_where`` set.  Nothing judged: ``rep`` itself."""
    if not what or rep.position is None or rep.quaternion is None or rep.psi is None:
        return rep
    prof = pfl_profile(rep, robot, motion, what)
    out: list[Finding] = []
    for k, region in enumerate(what.regions):
        f = finding(f"pfl {region.name} (contact energy / ISO/TS 15066 limit)", "limit", "",
                    1.0, prof.ratio[:, :, k] - 1.0, prof.ratio[:, :, k], motion.t,
                    list(prof.points))
        if f:
            out.append(f)
    return replace(rep, pfl=tuple(names_of(what.regions)), pfl_links=what.links,
                   max_pfl_ratio=float(prof.ratio.max()), max_pfl_where=prof.worst()[1],
                   findings=list(rep.findings) + out, ok=rep.ok and not out)


__all__ = ["Judged", "PflProfile", "judged", "judged_regions", "pfl_check", "pfl_profile"]
