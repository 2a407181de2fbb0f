"""The robot's closed-form inverse kinematics written with CasADi symbols (the first
ingredient of :mod:`sixplus3.dynamics.symbolic`): the same conventions and branches as
:mod:`sixplus3.kinematics.leg` (docs/conventions.md), every tree joint's value, the
actuated angles, and per leg its reach, margins and links, as expressions of the minimal
coordinates x = (platform position [m], rotation vector [rad], crank angles [rad])."""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

from sixplus3.robot_description.assembly import AssemblyMode
from sixplus3.robot_description.robot_geometry import NUM_LEGS, RobotGeometry


def rotvec_matrix(r: Any) -> Any:
    """R = exp([r]x) (Rodrigues), smooth at r = 0 (series branch below |r|^2 = 1e-8)."""
    a = ca.dot(r, r)
    th = ca.sqrt(a + 1e-30)
    A = ca.if_else(a < 1e-8, 1 - a / 6 + a * a / 120, ca.sin(th) / th)
    B = ca.if_else(a < 1e-8, 0.5 - a / 24 + a * a / 720, (1 - ca.cos(th)) / (th * th + 1e-300))
    K = ca.skew(r)
    return ca.SX.eye(3) + A * K + B * (K @ K)


def _solve_rus(rx: Any, ry: Any, rz: Any, crank: float, link: float, sign: int) -> Any:
    """cos/sin of the crank angle (kinematics._leg_kernel._solve_rus, symbolically).

    Returns (c, s, q2) with q2 = r^2 - k^2 >= 0 the reachability measure.
    """
    r2 = ry * ry + rz * rz
    k = (rx * rx + r2 + crank * crank - link * link) / (2 * crank)
    q2 = r2 - k * k
    q = sign * ca.sqrt(ca.fmax(q2, 0) + 1e-30)
    return (ry * k - rz * q) / r2, (rz * k + ry * q) / r2, q2


def _angle(c: Any, s: Any) -> Any:
    """Actuated angle in (-90, 270] deg, continuous through 0..270 (cut: pointing down)."""
    return math.pi / 2 + ca.atan2(-c, s)


def _leg_symbolic(p_leg: Any, geom: RobotGeometry, mode: AssemblyMode) -> dict[str, Any]:
    """Closed-form IK of one leg with CasADi symbols; returns a dict of expressions."""
    lg = geom.leg
    s1_, s3_, s2_, s4_ = mode.signs
    x, y, z = p_leg[0], p_leg[1], p_leg[2]
    c1, s1, q_ru = _solve_rus(x, y, z, lg.l1, lg.dp, s1_)
    d = ca.vertcat(0, lg.l1 * c1, lg.l1 * s1)
    v = (p_leg - d) / lg.dp
    rho = ca.sqrt(v[1] ** 2 + v[2] ** 2 + 1e-30)
    cs3 = s3_ * rho
    cp = -s3_ * v[1] / rho
    sp = -s3_ * v[2] / rho
    ss3 = v[0]
    Q = ca.vertcat(ca.horzcat(ss3, cs3, 0), ca.horzcat(-cp * cs3, cp * ss3, -sp),
                   ca.horzcat(-sp * cs3, sp * ss3, cp))
    e = d + Q @ ca.DM(lg.e_b)
    f = d + Q @ ca.DM(lg.f_b)
    c2, s2, q_b = _solve_rus(e[0] - lg.l6, e[1], e[2], lg.l2, lg.l4, s2_)
    c3, s3, q_c = _solve_rus(f[0] + lg.l7, f[1], f[2], lg.l3, lg.l5, s4_)
    g = ca.vertcat(lg.l6, lg.l2 * c2, lg.l2 * s2)
    h = ca.vertcat(-lg.l7, lg.l3 * c3, lg.l3 * s3)
    th = ca.vertcat(_angle(c1, s1), _angle(c2, s2), _angle(c3, s3))
    ts2 = ca.atan2(sp * c1 - cp * s1, cp * c1 + sp * s1)
    ts3 = ca.atan2(ss3, cs3)

    def u_angles(c: Any, s: Any, w: Any) -> Any:
        uy = c * w[1] + s * w[2]
        uz = -s * w[1] + c * w[2]
        return ca.atan2(uz, uy), ca.atan2(-w[0], ca.sqrt(uy * uy + uz * uz + 1e-30))

    ga, gb = u_angles(c2, s2, (e - g) / lg.l4)
    ha, hb = u_angles(c3, s3, (f - h) / lg.l5)
    # Jacobian ingredients (kinematics._leg_kernel.jacobian_point, symbolically)
    pd = p_leg - d
    eg = e - g
    fh = f - h
    u1 = ca.vertcat(0, -d[2], d[1])
    u2 = ca.vertcat(0, -g[2], g[1])
    u3 = ca.vertcat(0, -h[2], h[1])
    k11 = ca.dot(pd, u1)
    k22 = ca.dot(eg, u2)
    k33 = ca.dot(fh, u3)
    w = Q[:, 2]
    xf = ca.DM([1.0, 0.0, 0.0])
    a0 = ca.cross(xf, p_leg)
    a1 = ca.cross(xf, pd)
    a2 = ca.cross(w, pd)
    r0, r1, r2 = ca.cross(a1, a2), ca.cross(a2, a0), ca.cross(a0, a1)
    ne = ca.cross(e - d, eg)
    nf = ca.cross(f - d, fh)
    j1 = ne[0] * (r0 + r1) + ca.dot(ne, w) * r2
    j2 = nf[0] * (r0 + r1) + ca.dot(nf, w) * r2

    def unit(vv: Any) -> Any:
        return vv / ca.sqrt(ca.dot(vv, vv) + 1e-30)

    det_hat = ca.dot(unit(pd), ca.cross(unit(j1), unit(j2)))
    return {
        "theta": th, "ts2": ts2, "ts3": ts3, "ga": ga, "gb": gb, "ha": ha, "hb": hb,
        "reach": ca.vertcat(q_ru, q_b, q_c),
        "type1": ca.vertcat(k11 / (lg.dp * lg.l1), k22 / (lg.l4 * lg.l2),
                            k33 / (lg.l5 * lg.l3)),
        "type2_det": det_hat, "Q": Q, "d": d, "e": e, "f": f, "g": g, "h": h,
    }


def ik_expressions(geom: RobotGeometry, mode: AssemblyMode, x: ca.SX) -> dict[str, Any]:
    """The whole robot's closed-form inverse kinematics in minimal coordinates ``x``,
    symbolically: the platform rotation ``R``, every revolute joint's value by name
    (``joint_val``: the legs' nine joints each, and the cranks ``platform_crank{i}`` =
    psi_i), the actuated angles ``theta`` (9,), and per leg its reach measures, type I
    margins, type II determinant, body frame ``leg_Q`` and links (A-D, D-P, B-G, G-E,
    C-H, H-F)."""
    p, r, psi = x[0:3], x[3:6], x[6:9]
    R = rotvec_matrix(r)
    joint_val: dict[str, ca.SX] = {}
    thetas, reach, type1, type2, leg_Q, links = [], [], [], [], [], []
    for i in range(NUM_LEGS):
        b = geom.crank_axis_angle(i) + psi[i]
        local = ca.DM(geom.crank_axis_position(i)) + geom.platform_crank * ca.vertcat(
            ca.cos(b), ca.sin(b), 0)
        Pi = p + R @ local
        Rl = ca.DM(geom.leg_rotation(i))
        p_leg = Rl.T @ (Pi - ca.DM(geom.leg_origin(i)))
        leg = _leg_symbolic(p_leg, geom, mode)
        thetas.append(leg["theta"])
        reach.append(leg["reach"])
        type1.append(leg["type1"])
        type2.append(leg["type2_det"])
        leg_Q.append(Rl @ leg["Q"])
        # the links AD, DP, BG, GE, CH, HF (kinematics.collision.capsules)
        org = ca.DM(geom.leg_origin(i))
        A = org
        B = org + ca.DM(geom.leg.l6 * geom.leg_rotation(i)[:, 0])
        C = org - ca.DM(geom.leg.l7 * geom.leg_rotation(i)[:, 0])
        D, P = org + Rl @ leg["d"], Pi
        G, E = org + Rl @ leg["g"], org + Rl @ leg["e"]
        H, F = org + Rl @ leg["h"], org + Rl @ leg["f"]
        links += [(A, D), (D, P), (B, G), (G, E), (C, H), (H, F)]
        for name, val in (("A", leg["theta"][0]), ("Ds2", leg["ts2"]), ("Ds3", leg["ts3"]),
                          ("B", leg["theta"][1]), ("Ga", leg["ga"]), ("Gb", leg["gb"]),
                          ("C", leg["theta"][2]), ("Ha", leg["ha"]), ("Hb", leg["hb"])):
            joint_val[f"leg{i}_{name}"] = val
        joint_val[f"platform_crank{i}"] = psi[i]
    return {"R": R, "joint_val": joint_val, "theta": ca.vertcat(*thetas), "reach": reach,
            "type1": type1, "type2": type2, "leg_Q": leg_Q, "links": links}
