"""The orientation-workspace atlas: how far the platform tilts, everywhere, in every
direction, with the three redundant cranks free versus locked at home.

For every platform-centre position of a grid, every tilt direction and every torsion,
the atlas reports the **largest tilt** [deg] of an admissible pose, found by the scheme
of :func:`sixplus3.planner.analysis.largest_tilt`: a scan in ``scan_deg`` steps from 0 to
the first inadmissible tilt, then bisection to ``resolution_deg``.  A position whose
zero-tilt pose is inadmissible gets NaN.

Orientation: R = Rot(axis(beta), alpha) @ Rz(torsion), with axis(beta) = (cos beta,
sin beta, 0).  beta is the **tilt-axis azimuth** (0 deg: a rotation about +x, the
``largest_tilt(axis="x")`` case; 90 deg: about +y), alpha >= 0 the tilt; the azimuths
cover 0..360 deg because +alpha about beta is -alpha about beta + 180 deg.

A pose is **admissible** when some candidate crank choice passes, in this order (the
first check no candidate passes is the pose's ``binding`` code):

1. ``reach``      every chain in reach (closed-form IK);
2. ``theta``      every actuated angle in the robot's actuated range;
3. ``spherical``  every spherical joint within the robot's spherical limit;
4. ``leg margin`` every leg's type I and type II singularity margin >= the robot's
                  ``limits.margin``;
5. ``clearance``  no interference between the links of different legs;
6. ``platform``   the platform's singularity margin >= ``limits.margin``;
7. ``torque``     the static holding torque (closed loop, with the robot's
                  payload and mounting) within ``limits.torque`` on all nine motors;
                  with ``accel_g`` = a > 0 (optional), the torque to accelerate the
                  platform from rest at a g in *every* direction, with no angular or
                  crank acceleration: max over |acc| = a g of |tau_0 + A acc| =
                  |tau_0| + a g |A_j| per motor j (tau_0 the holding torque, A = d tau /
                  d acc, the motors' rotor inertia included).

Candidates:

- ``locked``: the cranks at the robot's home angles (one candidate);
- ``free``: a searched choice.  The redundant joint of leg i moves only leg i's chain,
  so checks 1-4 are done leg by leg on a grid of ``psi_step_deg`` over the planner's crank
  range [45, 135] deg; the two best values per leg (by the leg's smallest margin) form
  2^3 combinations, checked with 5-7, together with the home angles.  The free result is
  therefore a lower bound on the exhaustive search's largest tilt (a finite search), and
  it is never below the locked result: the free candidates include the locked one at
  every tilt, and the scan and bisection then keep free >= locked (tests check it).

The locked scan runs first.  Every scan step it passed is free-admissible too (the
free candidates include the home cranks), so the free scan starts at the locked
scan's last admissible step instead of at 0: the same largest tilt and binding as a
free scan from 0, fewer evaluations.  The reported free ``psi`` is then the home cranks
where the free largest tilt is that step.

Work is split into chunks of positions, each a Dask task (``dask.distributed``: a
``LocalCluster`` by default, a scheduler address for a real cluster, or
``scheduler="synchronous"`` to run in this process).  Every chunk is vectorised over its
(position, direction, torsion) pairs: checks 1-6 of all its poses at one scan or
bisection step are one call of the compiled kernel :mod:`design._atlas_kernel` (each
check only where the ones before it passed), and check 7 one call of the compiled
symbolic statics (:func:`dynamics.symbolic.holding_function`, checked against Pinocchio).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from sixplus3.design.atlas_checks import PoseChecker
from sixplus3.design.atlas_data import (
    BINDING,
    AtlasSettings,
    build_dataset,
    position_grid,
)
from sixplus3.design.cluster import check_scheduler, check_workers, map_tasks
from sixplus3.errors import InputError
from sixplus3.kinematics.rotations import matrix_from_rotvec
from sixplus3.robot_description.robot import Robot, require_robot

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr


# --------------------------------------------------------------------- one batch of poses
def rotations(azimuth_deg: ArrayLike, tilt_deg: ArrayLike,
              torsion_deg: ArrayLike) -> np.ndarray:
    """(n, 3, 3) R = Rot(axis(azimuth), tilt) @ Rz(torsion), arrays broadcast to (n,)."""
    b, a, t = np.broadcast_arrays(np.radians(azimuth_deg), np.radians(tilt_deg),
                                  np.radians(torsion_deg))
    tilt = matrix_from_rotvec(np.c_[np.cos(b.ravel()), np.sin(b.ravel()),
                                    np.zeros(b.size)] * a.ravel()[:, None])
    return tilt @ matrix_from_rotvec(np.c_[np.zeros((t.size, 2)), t.ravel()])


def largest_tilts(robot: Robot, positions: np.ndarray, azimuths_deg: ArrayLike,
                  torsions_deg: ArrayLike = (0.0,), settings: AtlasSettings | None = None,
                  checker: PoseChecker | None = None) -> dict[str, np.ndarray]:
    """The atlas kernel: largest admissible tilt [deg] at ``positions`` (m, 3) [m] for
    every azimuth and torsion [deg], cranks free and locked.

    Returns arrays shaped (2, T, A, m) (cranks, torsion, azimuth, position):
    ``max_tilt`` [deg] (NaN: the zero-tilt pose is inadmissible), ``binding`` (code into
    :data:`BINDING`: what fails just beyond), and ``psi`` (2, T, A, m, 3) [deg] the crank
    angles of an admissible pose at ``max_tilt`` (free: the best-margin candidate of the
    evaluation there, or the home cranks where the locked scan had already passed it).
    """
    st = (settings or AtlasSettings()).check()
    chk = checker or PoseChecker(robot, st.psi_step_deg, st.accel_g)
    pos = np.asarray(positions, dtype=float).reshape(-1, 3)
    az = np.asarray(azimuths_deg, dtype=float)
    tor = np.asarray(torsions_deg, dtype=float)
    m, A, T = len(pos), len(az), len(tor)
    # pairs, torsion-major: (T, A, m)
    P = np.broadcast_to(pos[None, None], (T, A, m, 3)).reshape(-1, 3)
    B = np.broadcast_to(az[None, :, None], (T, A, m)).ravel()
    Z = np.broadcast_to(tor[:, None, None], (T, A, m)).ravel()
    n = len(P)
    out_tilt = np.full((2, n), np.nan)
    out_bind = np.zeros((2, n), dtype=np.int8)
    out_psi = np.full((2, n, 3), np.nan)
    home = np.broadcast_to(chk.home, (n, 3))
    scanned = np.full(n, np.nan)  # the locked scan's last admissible tilt
    for c, free in ((1, False), (0, True)):  # locked first: the free scan starts from it
        lo = np.full(n, np.nan)
        best_psi = np.full((n, 3), np.nan)
        bind = np.zeros(n, dtype=np.int8)
        if free:
            # every scan step the locked scan passed is free-admissible (free candidates
            # include the home cranks): start there, with the home cranks as the choice
            known = np.isfinite(scanned)
            lo[known], best_psi[known] = scanned[known], home[known]
        else:
            known = np.zeros(n, dtype=bool)
        # zero tilt where not known: the same pose for every azimuth of a (torsion,
        # position)
        need0 = ~known.reshape(T, A, m).all(axis=1)  # (T, m)
        ok0, psi0 = np.zeros((T, m), dtype=bool), np.full((T, m, 3), np.nan)
        b0 = np.zeros((T, m), dtype=np.int8)
        t0, m0 = np.nonzero(need0)
        if len(t0):
            ok0[t0, m0], psi0[t0, m0], b0[t0, m0] = chk.admissible(
                pos[m0], rotations(0.0, 0.0, tor[t0]), free)

        def pairs(x: np.ndarray) -> np.ndarray:  # (T, m, ...) -> (n, ...)
            return np.broadcast_to(x[:, None], (T, A, *x.shape[1:])).reshape(n, *x.shape[2:])

        ok0p = pairs(ok0)
        lo = np.where(~known & ok0p, 0.0, lo)
        best_psi = np.where((~known & ok0p)[:, None], pairs(psi0), best_psi)
        bind = np.where(~known & ~ok0p, pairs(b0), bind).astype(np.int8)
        hi = np.full(n, np.nan)
        active = np.isfinite(lo)
        # scan upwards until the first inadmissible tilt
        t = np.where(active, lo, 0.0)
        while active.any():
            idx = np.flatnonzero(active)
            at_max = t[idx] >= st.max_tilt_deg
            if at_max.any():
                bind[idx[at_max]] = BINDING.index("max tilt")
                active[idx[at_max]] = False
                idx = idx[~at_max]
                if not len(idx):
                    break
            tn = np.minimum(t[idx] + st.scan_deg, st.max_tilt_deg)
            ok, psi, b = chk.admissible(P[idx], rotations(B[idx], tn, Z[idx]), free)
            t[idx] = tn
            lo[idx[ok]], best_psi[idx[ok]] = tn[ok], psi[ok]
            hi[idx[~ok]], bind[idx[~ok]] = tn[~ok], b[~ok]
            active[idx[~ok]] = False
        if not free:
            scanned = lo.copy()
        # bisection inside the first failing scan interval
        while True:
            idx = np.flatnonzero(np.isfinite(hi) & (hi - lo > st.resolution_deg))
            if not len(idx):
                break
            mid = 0.5 * (lo[idx] + hi[idx])
            ok, psi, b = chk.admissible(P[idx], rotations(B[idx], mid, Z[idx]), free)
            lo[idx[ok]], best_psi[idx[ok]] = mid[ok], psi[ok]
            hi[idx[~ok]], bind[idx[~ok]] = mid[~ok], b[~ok]
        out_tilt[c], out_bind[c], out_psi[c] = lo, bind, best_psi
    return {"evaluations": np.array([chk.evaluations]),
            "max_tilt": out_tilt.reshape(2, T, A, m),
            "binding": out_bind.reshape(2, T, A, m),
            "psi": np.degrees(out_psi).reshape(2, T, A, m, 3)}


# --------------------------------------------------------------------- Dask driver
def _chunk_task(shared: tuple[Robot, AtlasSettings], positions: np.ndarray,
                ) -> dict[str, np.ndarray]:
    """One Dask task: the kernel over a chunk of positions.

    The batched IK kernel is a numba ``prange`` loop; with one task per core its threads
    would oversubscribe the cores (measured: 3-9x slower with 2 workers on 2 cores), so a
    task runs it on one thread.
    """
    # deferred: numba loads only when this runs
    import numba

    robot, settings = shared
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return largest_tilts(robot, positions, settings.azimuths_deg, settings.torsions_deg,
                             settings)
    finally:
        numba.set_num_threads(before)


#: Most results an atlas may hold (positions x azimuths x torsions x {free, locked}):
#: 33 bytes each (the tilt, its binding limit, three crank angles), held twice while the
#: chunks are joined into the dataset: ~1.3 GB at the cap.  The default atlas holds
#: 3.5e6; --step 0.01 would hold 2.8e7 (refused: run it on a Dask cluster in parts).
MAX_VALUES = 20_000_000


def check_run(workers: int, chunk: int) -> None:
    """Refuse a worker count or chunk size out of range (before anything runs)."""
    check_workers(workers)
    if not (isinstance(chunk, int) and 1 <= chunk <= 100000):
        raise InputError(f"chunk must be an integer in [1, 100000], got {chunk!r}",
                         value=chunk, valid="[1, 100000]")


def compute_atlas(robot: Robot, settings: AtlasSettings | None = None,
                  scheduler: str | None = None, workers: int = 2, chunk: int = 64,
                  grid: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                  progress: Callable[[int, int], None] | bool = False) -> xr.Dataset:
    """The atlas of ``robot`` as an xarray Dataset.

    ``scheduler``: None starts a ``dask.distributed.LocalCluster`` of ``workers``
    single-threaded worker processes; ``"synchronous"`` runs the chunks in this process
    (tests, debugging); anything else is a scheduler address (``tcp://host:8786``).
    ``chunk``: positions per Dask task.  ``grid``: (xs, ys, zs) [m] instead of
    :func:`position_grid`.  ``progress``: True for a tqdm bar, or a callback(done, total).
    """

    robot = require_robot(robot)
    st = (settings or AtlasSettings()).check()
    check_run(workers, chunk)
    check_scheduler(scheduler)
    xs, ys, zs = grid if grid is not None else position_grid(robot, st.step)
    values = 2 * len(xs) * len(ys) * len(zs) * len(st.azimuths_deg) * len(st.torsions_deg)
    if values > MAX_VALUES:
        raise InputError(f"the atlas would hold {values:.3g} results (positions x azimuths "
                         f"x torsions x 2), over the cap of {MAX_VALUES:.3g}: use a coarser "
                         "--step or --azimuth-step, or fewer torsions", value=values,
                         valid=f"<= {MAX_VALUES}")
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    pts = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    chunks = [pts[i:i + chunk] for i in range(0, len(pts), chunk)]
    t0 = time.perf_counter()
    results = map_tasks(_chunk_task, chunks, (robot, st), scheduler, workers, progress,
                        desc="atlas")
    wall = time.perf_counter() - t0
    evaluations = int(sum(int(r["evaluations"][0]) for r in results))
    cat = {k: np.concatenate([r[k] for r in results], axis=3) for k in results[0]
           if k != "evaluations"}
    shape = (2, len(st.torsions_deg), len(st.azimuths_deg), len(xs), len(ys), len(zs))
    ds = build_dataset(robot, st, xs, ys, zs, cat, shape, wall, len(pts),
                  workers if scheduler is None else None)
    ds.attrs["pose_evaluations"] = evaluations
    return ds


def home_polar(robot: Robot, settings: AtlasSettings | None = None,
               azimuth_step_deg: float = 5.0) -> dict[str, np.ndarray]:
    """Largest tilt per direction at the robot's home position (both crank modes):
    {"azimuth": (A,), "free": (A,), "locked": (A,)} [deg]."""
    st = settings or AtlasSettings()
    az = np.arange(0.0, 360.0 - 1e-9, azimuth_step_deg)
    r = largest_tilts(robot, np.asarray(robot.home_position)[None], az, (0.0,), st)
    return {"azimuth": az, "free": r["max_tilt"][0, 0, :, 0],
            "locked": r["max_tilt"][1, 0, :, 0]}


__all__ = ["check_run", "compute_atlas", "home_polar", "largest_tilts", "rotations"]
