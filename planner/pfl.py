"""Power and force limiting in the plan (docs/safety.md): the tool centre point's speed
bound that keeps every contact with the named body regions within ISO/TS 15066.

The planner bounds the tool centre point's speed at every node and midpoint (its
platform rows, :mod:`sixplus3.planner.tcp_rows`).  For power and force limiting that
bound is the largest speed in any direction that keeps the worst direction's contact
energy within the region's limit (:func:`sixplus3.dynamics.effective_mass.worst_speed`),
taken at the task's poses (the waypoints and points between them, cranks at the
waypoints' or home's) and lowered by :data:`PFL_SAFETY` for the poses in between.  The
gate then recomputes the exact, direction-aware condition on every sample of the
smoothed file (control/gate/pfl.py); a plan that breaks it is re-planned with the bound
lowered by the ratio found (control/pipeline.py), so a file that is written holds it.

The legs (issue 70): every reachable leg link's vertices
(:mod:`sixplus3.dynamics.leg_points`) get rows of the same form, v^T C v with the
vertex's velocity from the closed-form IK in CasADi
(:func:`sixplus3.planner.tcp_rows.leg_pfl_function`) and C from the vertex's inverse
mass (Pinocchio's, the gate's).  A crank's tip moves along one line only, so its inverse
mass has rank 1: C takes 0 along the directions it cannot move in.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.drive_contact import (
    DriveCase,
    contact_peaks,
    drive_cap,
    reference_stop,
)
from sixplus3.dynamics.effective_mass import (
    RCOND,
    point_inverse_mass,
    point_jacobian,
    worst_speed,
)
from sixplus3.dynamics.leg_points import rates_from, vertex_jacobians
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.task import Task
from sixplus3.planner.tcp_rows import leg_pfl_function, pfl_function, pfl_ratios_at
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import BodyRegion, regions
from sixplus3.robot_description.leg_links import vertex_label, vertices_of
from sixplus3.robot_description.robot import Robot

#: The bound at the task's poses, lowered for the poses the plan passes in between.
PFL_SAFETY = 0.95
#: Points per segment between waypoints at which the bound is evaluated.
POINTS = 8
#: The drive's rate the rows assume with a declared position loop [Hz] (the default
#: file's; the gate judges the file at its own rate, and the pipeline re-plans).
NLP_RATE = 1000.0


def task_regions(task: Task) -> tuple[BodyRegion, ...]:
    """The task's regions and the site's (the site's cannot be dropped)."""
    return regions(list(task.pfl) + list(hardware.active().pfl))


def task_links(task: Task) -> tuple[str, ...]:
    """The leg links judged with the task's regions (:func:`hardware.judged_links`):
    none without a region."""
    return hardware.judged_links(task.pfl_links) if task_regions(task) else ()


@dataclass(frozen=True)
class PflPoint:
    """Where power and force limiting holds: a platform point (``platform``, platform
    frame [m]), or the vertices of one leg (``leg`` and ``vertices``, D/E/F/G/H/P: one
    CasADi function for the leg's vertices, its IK computed once)."""

    label: str
    platform: tuple[float, float, float] | None = None
    leg: int | None = None
    vertices: tuple[str, ...] = ()

    @property
    def size(self) -> int:
        """The points (rows per NLP point): 1 at the platform, the leg's vertices."""
        return 1 if self.leg is None else len(self.vertices)

    @property
    def labels(self) -> tuple[str, ...]:
        return (self.label,) if self.leg is None else tuple(
            vertex_label((self.leg, v)) for v in self.vertices)

    def function(self, robot: Robot) -> ca.Function:
        """The rows' function (x, xd, c) -> v^T C v at each of the points."""
        if self.leg is not None:
            return leg_pfl_function(robot.geometry, robot.mode, self.leg, self.vertices)
        return pfl_function(self.platform)


def pfl_points(robot: Robot, links: tuple[str, ...] = ()) -> tuple[PflPoint, ...]:
    """Where power and force limiting holds: the tool centre point, the platform centre
    too when a tool moves it off the centre (a person can meet the platform's body as
    well as the tool), and each leg's vertices of the leg links ``links``."""
    tool = tuple(float(c) for c in robot.tool.xyz)
    centre = (0.0, 0.0, 0.0)
    plat = [PflPoint("tcp", tool)] + ([] if tool == centre else  # type: ignore[arg-type]
                                      [PflPoint("centre", centre)])
    verts = vertices_of(links)
    legs = [PflPoint(f"leg{i}", leg=i, vertices=tuple(v for j, v in verts if j == i))
            for i in sorted({i for i, _ in verts})]
    return tuple(plat) + tuple(legs)


def pfl_ratio_max(robot: Robot, x: np.ndarray, xd: np.ndarray,
                  regs: tuple[BodyRegion, ...], links: tuple[str, ...] = ()) -> float:
    """The largest v^T C v over the states (n, 9 each) and every point of
    :func:`pfl_points` (the NLP rows' form, evaluated)."""
    return float(pfl_ratios(robot, x, xd, regs, links).max())


def pfl_ratios(robot: Robot, x: np.ndarray, xd: np.ndarray,
               regs: tuple[BodyRegion, ...], links: tuple[str, ...] = ()) -> np.ndarray:
    """(n,) the largest v^T C v at each state over every point of :func:`pfl_points`."""
    each = [np.reshape(pfl_ratios_at(p.function(robot), x, xd,
                                     pfl_matrices(robot, x, regs, p)), (len(x), -1))
            for p in pfl_points(robot, links)]
    return np.concatenate(each, axis=1).max(axis=1)


def pfl_parameters(robot: Robot, x: np.ndarray, regs: tuple[BodyRegion, ...],
                   point: PflPoint) -> np.ndarray:
    """(n, 9 k) the NLP's parameters of ``point``'s rows at the states x: each of its k
    matrices (:func:`pfl_matrices`) column-major, one after the other."""
    C = pfl_matrices(robot, x, regs, point)
    return np.swapaxes(C, -1, -2).reshape(len(C), -1)


def pfl_matrices(robot: Robot, x: np.ndarray, regs: tuple[BodyRegion, ...],
                 point: PflPoint | None = None) -> np.ndarray:
    """(n, 3, 3) C_k of the NLP's power and force limiting rows at the states x (n, 9:
    position, rotation vector, crank angles): v^T C_k v is the worst contact energy of
    ``point`` (:class:`PflPoint`; default the tool centre point) over every direction
    and every region of ``regs``, as a share of that region's limit.  A leg's
    :class:`PflPoint`: (n, k, 3, 3), one per vertex.

    With A = U diag(lambda) U^T (:func:`point_inverse_mass`), a region's condition is
    v^T (A + I/m_H)^-1 v / (2 E) <= 1 (E = F^2 / 2k), whose matrix has A's eigenvectors
    and the eigenvalues 1 / ((lambda_i + 1/m_H) 2 E).  C_k takes, along each
    eigenvector, the largest over the regions: v^T C_k v <= 1 then holds every region's
    condition, and equals the worst of them along each of A's principal directions.
    A state whose inverse kinematics fails takes the largest C of the others (the
    gate judges the smoothed file anyway)."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    R = rot.matrix_from_rotvec(x[:, 3:6])
    cfg = robot_ik(x[:, 0:3], R, x[:, 6:9], robot, platform_margins=False)
    ok = np.asarray(cfg.ok, dtype=bool)
    if not ok.any():
        raise ValueError("no state of the power and force limiting rows has a pose")
    dyn = ClosedLoopDynamics(robot)
    sub = cfg.take(ok)
    if point is not None and point.leg is not None:
        verts = tuple((point.leg, v) for v in point.vertices)
        Jp, M = vertex_jacobians(dyn, sub.q, verts)[1:]  # (m, k, 3, 9), (m, 9, 9)
    else:
        Jp, M = point_jacobian(dyn, sub, robot.tool.xyz if point is None
                               else point.platform)
        Jp = Jp[:, None]
    A = rates_from(Jp, M, np.zeros((len(M), 9)))[1]  # (m, k, 3, 3)
    lam, U = np.linalg.eigh(A)
    lam[lam <= RCOND * lam[..., -1:]] = np.inf  # a direction the point cannot move in
    inv_m = np.array([0.0 if not np.isfinite(r.mass) else 1.0 / r.mass for r in regs])
    two_e = np.array([2.0 * r.energy for r in regs])
    c_r = 1.0 / ((lam[..., None, :] + inv_m[:, None]) * two_e[:, None])  # (m, k, R, 3)
    _with_loop(c_r, U, Jp, M, regs)
    c = c_r.max(axis=-2)
    if point is None or point.leg is None:
        A, U, c = A[:, 0], U[:, 0], c[:, 0]
    C = np.zeros((len(x), *A.shape[1:]))
    C[ok] = np.einsum("...ij,...j,...kj->...ik", U, c, U)
    if not ok.all():
        size = np.trace(C[ok], axis1=-2, axis2=-1).reshape(int(ok.sum()), -1).sum(axis=1)
        C[~ok] = C[ok][int(np.argmax(size))]
    return C


def _with_loop(c: np.ndarray, U: np.ndarray, Jp: np.ndarray, M: np.ndarray,
               regs: tuple[BodyRegion, ...]) -> None:
    """Scale ``c`` (m, k, R, 3: along each eigenvector of A, per region) in place for
    the site's declared position loop (module doc): along each principal direction u, a
    region's c times (F / F_max)^2, F the contact's peak with the loop in it
    (:func:`sixplus3.dynamics.drive_contact.contact_peaks`; a clamp's reference stands
    after the guard's detection) at the speed where the two-body model reaches the
    limit, the planned torques taken as zero and the actuated rates the least that move
    the point so.  No loop declared: nothing."""
    hw = hardware.active()
    if hw.position_loop is None:
        return
    m, k = Jp.shape[:2]
    cap = drive_cap()
    Minv = np.repeat(np.linalg.inv(M), k * 3, axis=0)
    ju = np.einsum("mkji,mkjd->mkdi", Jp, U).reshape(-1, 9)  # J^T u per direction
    pinv = np.repeat(np.linalg.pinv(Jp, rcond=RCOND), 3, axis=1).reshape(-1, 9, 3)
    for r, region in enumerate(regs):
        cr = c[:, :, r, :].reshape(-1)
        with np.errstate(divide="ignore"):
            speed = np.where(cr > 0, 1.0 / np.sqrt(np.where(cr > 0, cr, 1.0)), 0.0)
        thd = np.einsum("nij,nj->ni", pinv, U.transpose(0, 1, 3, 2).reshape(-1, 3)
                        * speed[:, None])
        case = DriveCase(Minv, ju, speed, np.zeros((len(cr), 9)), cap,
                         np.full(len(cr), region.mass), np.full(len(cr), region.stiffness),
                         thd)
        f = contact_peaks(case, hw.position_loop, NLP_RATE,
                          stop=reference_stop(region, NLP_RATE)) / region.transient_force
        c[:, :, r, :] = np.where(cr > 0, cr * f * f, cr).reshape(m, k, 3)


def pfl_speed(task: Task, robot: Robot) -> float | None:
    """The tool centre point's speed bound [m/s] for the task's regions (module doc);
    None without regions.  ``robot``: the robot with the task's setup (its tool)."""
    regs = task_regions(task)
    if not regs:
        return None
    wps = task.resolved(robot).waypoints
    pos, rots, psi = [], [], []
    home_psi = np.asarray(robot.home_psi, dtype=float)
    for a, b in zip(wps[:-1], wps[1:], strict=True):
        ra = rot.rotvec_from_matrix(np.asarray(a.rotation))
        rb = rot.rotvec_from_matrix(np.asarray(b.rotation))
        pa = home_psi if a.psi is None else np.asarray(a.psi)
        pb = home_psi if b.psi is None else np.asarray(b.psi)
        for s in np.linspace(0.0, 1.0, POINTS + 1):
            pos.append((1 - s) * np.asarray(a.position) + s * np.asarray(b.position))
            rots.append(np.reshape((1 - s) * ra + s * rb, 3))
            psi.append((1 - s) * pa + s * pb)
    R = rot.matrix_from_rotvec(np.array(rots))
    cfg = robot_ik(np.array(pos), R, np.array(psi), robot, platform_margins=False)
    if not cfg.ok.any():
        return None
    cfg = cfg.take(cfg.ok)
    A = point_inverse_mass(ClosedLoopDynamics(robot), cfg)
    return PFL_SAFETY * float(min(worst_speed(A, r).min() for r in regs))


__all__ = ["PFL_SAFETY", "PflPoint", "pfl_matrices", "pfl_parameters", "pfl_points",
           "pfl_ratio_max", "pfl_ratios", "pfl_speed", "task_links", "task_regions"]
