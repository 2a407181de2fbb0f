"""The legs in power and force limiting (issue 70): the reachable links' names, their
vertices' velocities and inverse masses by two derivations (Pinocchio's frame Jacobians
through the closures, the gate's; the closed-form IK in CasADi, the planner's rows'),
and the argument that a link's vertices bound its contact energy, checked on the links'
interiors rather than assumed."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.effective_mass import link_inverse_mass, pfl_ratio
from sixplus3.dynamics.leg_points import vertex_rates
from sixplus3.errors import GeometryError, InputError
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.pfl import pfl_matrices, pfl_points
from sixplus3.planner.tcp_rows import pfl_ratios_at
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import regions
from sixplus3.robot_description.leg_links import LINKS, link_names, vertices_of
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
ALL = link_names(["legs"])


def _states(n: int, seed: int):
    """n reachable states x (platform position, rotation vector, cranks) with rates xd,
    and their tree configurations and actuated rates (central differences of the
    numeric IK: a third derivation of the rates)."""
    rng = np.random.default_rng(seed)
    xs, xds = [], []
    while len(xs) < n:
        x = np.r_[np.add(ROBOT.home_position, rng.uniform(-0.04, 0.04, 3)),
                  rng.uniform(-0.25, 0.25, 3), np.add(ROBOT.home_psi, rng.uniform(-0.4, 0.4, 3))]
        if _cfg(x[None]).ok[0]:
            xs.append(x)
            xds.append(rng.normal(size=9) * np.r_[0.5, 0.5, 0.5, 2, 2, 2, 3, 3, 3])
    x, xd = np.array(xs), np.array(xds)
    h = 1e-6
    thd = (_cfg(x + h * xd).theta - _cfg(x - h * xd).theta) / (2 * h)
    return x, xd, _cfg(x), thd


def _cfg(x):
    return robot_ik(x[:, 0:3], rot.matrix_from_rotvec(x[:, 3:6]), x[:, 6:9], ROBOT,
                    platform_margins=False)


def test_link_names_and_their_vertices() -> None:
    assert len(ALL) == 18 and ALL[0] == "leg0_proximal"
    assert link_names(["crankB"]) == ("leg0_crankB", "leg1_crankB", "leg2_crankB")
    assert link_names(["leg2_body", "leg2_body"]) == ("leg2_body",)
    assert link_names(None) == () and link_names([]) == ()
    assert vertices_of(("leg1_distalB",)) == ((1, "E"), (1, "G"))
    assert len(vertices_of(ALL)) == 18  # D, E, F, G, H, P on each leg
    for bad in (["leg3_body"], ["elbow"], [3], "legs", ["leg0_"]):
        with pytest.raises(InputError, match="pfl_links"):
            link_names(bad)


def test_a_site_requires_leg_links_no_task_can_drop(tmp_path) -> None:
    site = tmp_path / "site.yaml"
    site.write_text("pfl: [hand]\npfl_links: [body]\n")
    hw = hardware.load_hardware(site)
    assert hw.pfl_links == ("leg0_body", "leg1_body", "leg2_body")
    hardware.use(hw)
    assert hardware.judged_links([]) == hw.pfl_links  # a task's [] cannot drop them
    assert hardware.judged_links(None) == ALL  # no key: every reachable link
    hardware.use(None)
    assert hardware.judged_links([]) == ()
    site.write_text("pfl_links: [knee]\n")
    with pytest.raises(GeometryError, match="hardware.pfl_links"):
        hardware.load_hardware(site)


def test_the_vertices_velocity_by_pinocchio_casadi_and_the_ik() -> None:
    """Each vertex's velocity three ways: Pinocchio's frame Jacobians through the
    closures at the actuated rates (the gate), the closed-form IK's CasADi derivative
    along xd (the NLP's rows, v^T I v = |v|^2), and a finite difference of the
    vertex's position along the motion."""
    x, xd, cfg, thd = _states(4, 3)
    dyn = ClosedLoopDynamics(ROBOT)
    verts = vertices_of(ALL)
    pos, vel, _ = vertex_rates(dyn, cfg.q, thd, verts)
    groups = pfl_points(ROBOT, ALL)[1:]
    assert [g.label for g in groups] == ["leg0", "leg1", "leg2"]
    labels = [f"leg{i}_{v}" for i, v in verts]
    assert [lab for g in groups for lab in g.labels] == labels
    for g in groups:
        eye = np.broadcast_to(np.eye(3), (len(x), g.size, 3, 3))
        speed = np.sqrt(pfl_ratios_at(g.function(ROBOT), x, xd, eye))  # (n, k)
        for j, lab in enumerate(g.labels):
            k = labels.index(lab)
            np.testing.assert_allclose(speed[:, j], np.linalg.norm(vel[:, k], axis=1),
                                       rtol=1e-6, atol=1e-9)
    h = 1e-6
    p1 = vertex_rates(dyn, _cfg(x + h * xd).q, thd, verts)[0]
    p0 = vertex_rates(dyn, _cfg(x - h * xd).q, thd, verts)[0]
    np.testing.assert_allclose((p1 - p0) / (2 * h), vel, rtol=1e-5, atol=1e-7)


def test_the_vertices_inverse_mass_is_the_links() -> None:
    """A vertex's inverse mass (frame Jacobians, batched) against
    :func:`link_inverse_mass` (the joint's Jacobian shifted to the point, the closures'
    G; cross-checked against MuJoCo in tests/test_safety.py) on each link that meets
    there: a joint centre's mass does not depend on the link a contact lands on."""
    _, _, cfg, thd = _states(2, 4)
    dyn = ClosedLoopDynamics(ROBOT)
    verts = vertices_of(ALL)
    pos, _, A = vertex_rates(dyn, cfg.q, thd, verts)
    joint = {"proximal": "A", "body": "Ds3", "crankB": "B", "distalB": "Gb", "crankC": "C",
             "distalC": "Hb"}
    for t in range(len(cfg.q)):
        for k, (i, v) in enumerate(verts):
            for link, ends in LINKS.items():
                if v in ends:
                    want = link_inverse_mass(dyn, cfg.q[t], f"leg{i}_{joint[link]}",
                                             pos[t, k])
                    np.testing.assert_allclose(A[t, k], want, rtol=1e-7,
                                               atol=1e-9 * np.abs(want).max())


def test_a_links_vertices_bound_its_contact_energy() -> None:
    """The rows and the gate judge a link at its vertices (dynamics/leg_points.py).  Its
    speed is largest there (a rigid body's velocity is affine in the point); that its
    contact energy is too, where the inverse mass also varies along the link, is checked
    here on points spread over every link's interior, for a free and a clamped hand."""
    x, xd, cfg, thd = _states(6, 5)
    dyn = ClosedLoopDynamics(ROBOT)
    m, d = dyn.model, dyn.data
    regs = list(regions(["hand", "hand-clamped", "lower_arm"]))
    joint = {"proximal": "A", "body": "Ds3", "crankB": "B", "distalB": "Gb", "crankC": "C",
             "distalC": "Hb"}
    rng = np.random.default_rng(6)
    worst_inside = 0.0
    for t in range(len(x)):
        v_tree = dyn.consistent_states_batch(cfg.q[t:t + 1], thd[t:t + 1],
                                             np.zeros((1, 9)))[0][0]
        for i in range(3):
            for link, ends in LINKS.items():
                verts = tuple((i, e) for e in ends)
                pos, vel, A = vertex_rates(dyn, cfg.q[t:t + 1], thd[t:t + 1], verts)
                at_vertices = max(_ratio(A[0, k], vel[0, k], regs) for k in range(len(ends)))
                corners = [pos[0, k] for k in range(len(ends))]
                if link in ("proximal", "crankB", "crankC"):  # the fixed end on the axis
                    base = {"proximal": 0.0, "crankB": ROBOT.geometry.leg.l6,
                            "crankC": -ROBOT.geometry.leg.l7}[link]
                    org = ROBOT.geometry.leg_origin(i) + base * \
                        ROBOT.geometry.leg_rotation(i)[:, 0]
                    corners.append(np.asarray(org, dtype=float))
                jid = m.getJointId(f"leg{i}_{joint[link]}")
                pin.forwardKinematics(m, d, cfg.q[t], v_tree)
                vo = pin.getVelocity(m, d, jid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
                o = d.oMi[jid].translation.copy()
                for w in rng.dirichlet(np.ones(len(corners)), size=12):
                    point = np.einsum("k,ki->i", w, np.array(corners))
                    Ap = link_inverse_mass(dyn, cfg.q[t], f"leg{i}_{joint[link]}", point)
                    vp = vo.linear + np.cross(vo.angular, point - o)
                    inside = _ratio(Ap, vp, regs)
                    worst_inside = max(worst_inside, inside / max(at_vertices, 1e-300))
                    assert inside <= at_vertices * (1 + 1e-6), (t, i, link, inside,
                                                                 at_vertices)
    assert worst_inside > 0.3  # the interiors were near enough to matter


def _ratio(A: np.ndarray, v: np.ndarray, regs) -> float:
    """The worst region's worst-direction contact energy over its limit (a clamped
    region by the limit of a large mass: the gate's pseudo-inverse, independently)."""
    out = 0.0
    for r in regs:
        mass = r.mass if np.isfinite(r.mass) else 1e9
        out = max(out, float(pfl_ratio(A[None], v[None], [r.__class__(
            r.name, mass, r.stiffness, r.force, r.pressure, r.transient_factor)])[0][0]))
    return out


def test_the_rows_matrix_at_a_vertex_is_the_gates_ratio() -> None:
    """The NLP's C at a leg vertex (planner/pfl.py, eigenvalues; a crank's tip of rank 1)
    against the gate's pseudo-inverse energy (control/gate/pfl.py): v^T C v equals the
    worst region's ratio for a motion the vertex can make."""
    from sixplus3.control.gate.pfl import _worst

    x, xd, cfg, thd = _states(3, 7)
    regs = regions(["hand-clamped"])
    _, vel, A = vertex_rates(ClosedLoopDynamics(ROBOT), cfg.q, thd, vertices_of(ALL))
    k = 0
    for g in pfl_points(ROBOT, ALL)[1:]:
        C = pfl_matrices(ROBOT, x, regs, g)  # (n, size, 3, 3)
        assert C.shape == (len(x), g.size, 3, 3)
        for j in range(g.size):
            got = np.einsum("ni,nij,nj->n", vel[:, k], C[:, j], vel[:, k])
            want = _worst(A[:, k], vel[:, k], regs)[0][:, 0]
            np.testing.assert_allclose(got, want, rtol=1e-6)
            k += 1
    assert k == 18


def test_plan_refuses_an_unknown_leg_link_before_solving(tmp_path) -> None:
    from click.testing import CliRunner

    from sixplus3.cli import main

    r = CliRunner().invoke(main, ["plan", "translate", "--pfl", "hand", "--pfl-links",
                                  "body,knee", "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and "unknown leg link 'knee'" in r.output, r.output
    assert "legs" in r.output and "Traceback" not in r.output
    assert not (tmp_path / "out").exists()


def test_the_vertices_in_mujoco_are_pinocchios() -> None:
    """The simulated person meets a vertex on MuJoCo's body (control/drive/person.py:
    ``contact_site``): its position and MuJoCo's velocity there (``mj_jac`` at the
    point, the tree velocities that realise the rates) equal the gate's Pinocchio ones."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.mujoco_model import MujocoRobot
    from sixplus3.control.drive.person import contact_from_dict, contact_site, site_point

    _, _, cfg, thd = _states(2, 9)
    verts = vertices_of(ALL)
    pos, vel, _ = vertex_rates(ClosedLoopDynamics(ROBOT), cfg.q, thd, verts)
    sim = MujocoRobot(ROBOT, 1e-4)
    mj, m, d = sim.mj, sim.model, sim.data
    for t in range(len(cfg.q)):
        sim.set_state(np.asarray(cfg.q[t]), thd[t])
        for k, (i, v) in enumerate(verts):
            c = contact_from_dict({"region": "hand", "kind": "free", "at": 0.1,
                                   "point": f"leg{i}_{v}"})
            name, offset = contact_site(ROBOT, c)
            body = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, name)
            p = site_point(d, body, offset)
            jac = np.zeros((3, m.nv))
            mj.mj_jac(m, d, jac, None, p, body)
            np.testing.assert_allclose(p, pos[t, k], atol=1e-12)
            np.testing.assert_allclose(jac @ d.qvel, vel[t, k], atol=1e-9)
