"""The identification report: the identified robot file, the parameter table, plots of
measured against predicted torques, and the cross-validation on a log the estimate did
not see."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sixplus3.control.file.drive_log import DriveLog
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.regressor import parameters
from sixplus3.fileio import atomic_write, finite_or_none, save_figure, strict_json
from sixplus3.identification.base import base_parameters
from sixplus3.identification.identify import (
    V_MIN,
    Identification,
    check,
    dataset,
    not_measured,
)
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names


def robot_yaml(robot: Robot, header: str = "") -> str:
    """The robot as a robot file (YAML, :meth:`Robot.as_dict`'s structure)."""

    lines = "".join(f"# {ln}\n" for ln in header.splitlines())
    return lines + yaml.safe_dump(robot.as_dict(), sort_keys=False, default_flow_style=None)


def write_robot(path: str | Path, idf: Identification, logs: list[str]) -> Path:
    """The identified robot file, atomically, with a comment naming its logs."""
    head = (f"sixplus3 identified robot: from {', '.join(logs)}; {idf.base.rank} base "
            f"parameters, condition {idf.condition:.4g}; physically consistent "
            f"(smallest pseudo-inertia eigenvalue {idf.min_eigenvalue:.3g}); "
            f"hash {idf.robot.hash[:16]}")
    atomic_write(path, robot_yaml(idf.robot, head).encode())
    return Path(path)


def write_report(out_dir: str | Path, idf: Identification, logs: list[DriveLog],
                 nominal: Robot, validation: DriveLog | None = None) -> dict[str, Any]:
    """Write the report into ``out_dir``: ``summary.json``, ``parameters.csv`` (the base
    parameters: combination, nominal, WLS with its standard deviation, consistent),
    ``torques_<log>.png`` (measured and predicted torque per joint) and, with a
    ``validation`` log, the cross-validation of the nominal and the identified robot.
    Returns the summary."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = idf.summary()
    rows = idf.table()
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write(out / "parameters.csv", buf.getvalue().encode())
    files = ["parameters.csv"]
    for log in logs[:4]:
        name = f"torques_{Path(log.name).stem[:60]}.png"
        _plot_torques(out / name, log, idf.robot, nominal)
        files.append(name)
    if validation is not None:
        cv = {}
        for label, rob in (("nominal", nominal), ("identified", idf.robot)):
            c = check(validation, rob)
            cv[label] = {"rms_n_m": c.rms.tolist(), "rms_all_n_m": c.rms_all,
                         "peak_n_m": c.peak.tolist(), "rows": c.rows,
                         "not_measured": not_measured(c.rms)}
        summary["cross_validation"] = {"log": validation.name, **cv}
        name = f"torques_{Path(validation.name).stem[:60]}_validation.png"
        _plot_torques(out / name, validation, idf.robot, nominal)
        files.append(name)
    if idf.estimate.cov is not None:  # the base parameters' confidence, for `sixplus3 wrench`
        save_parameters(out / "parameters.npz", idf)
        files.append("parameters.npz")
    summary["files"] = files + ["summary.json"]
    summary = finite_or_none(summary)  # strict JSON: null (with not_measured's reason)
    atomic_write(out / "summary.json", (strict_json(summary, indent=1) + "\n").encode())
    return summary


def save_parameters(path: Path, idf: Identification) -> None:
    """The base parameters' definition, estimate and covariance (``np.load``-able):
    ``index`` (the base columns), ``beta``, ``cov``, ``robot_hash``."""
    assert idf.estimate.cov is not None
    buf = io.BytesIO()
    np.savez(buf, index=idf.base.index, beta=idf.beta_consistent, cov=idf.estimate.cov,
             robot_hash=np.array(idf.robot.hash))
    atomic_write(path, buf.getvalue())


def _plot_torques(path: Path, log: DriveLog, robot: Robot, nominal: Robot) -> None:
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt


    base = base_parameters(robot)
    ds = dataset([log], robot, base, v_min=-1.0)  # every row, in order (n, 9)
    f = ds.filtered[0]
    n = len(f.t)
    pred = (ds.Wb @ base.beta(parameters(ClosedLoopDynamics(robot)))).reshape(n, 9)
    pred0 = (ds.Wb @ base.beta(parameters(ClosedLoopDynamics(nominal)))).reshape(n, 9)
    fig, axes = plt.subplots(3, 3, figsize=(13, 8), sharex=True)
    for j, name in enumerate(actuated_joint_names()):
        ax = axes[j // 3, j % 3]
        ax.plot(f.t, f.tau[:, j], color="k", lw=1.2, label="measured (filtered)")
        ax.plot(f.t, pred0[:, j], color="tab:red", lw=0.8, ls="--", label="nominal model")
        ax.plot(f.t, pred[:, j], color="tab:blue", lw=0.8, label="identified model")
        moving = np.abs(f.theta_dot[:, j]) > V_MIN
        rms = math.sqrt(float(np.mean((f.tau[moving, j] - pred[moving, j]) ** 2))) \
            if moving.any() else math.nan
        ax.fill_between(f.t, 0, 1, where=~moving, color="0.85", alpha=0.6, lw=0,
                        transform=ax.get_xaxis_transform(),
                        label=f"|rate| < {V_MIN:g} rad/s (dry friction: not fitted)")
        ax.set_title(f"{name}: RMS error {rms:.4f} N m while moving" if math.isfinite(rms)
                     else f"{name}: no RMS (never faster than {V_MIN:g} rad/s)", fontsize=9)
        ax.grid(alpha=0.3)
        if j // 3 == 2:
            ax.set_xlabel("t [s]")
        if j % 3 == 0:
            ax.set_ylabel("torque at the joint [N m]")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"{log.name}: measured and predicted torques ({robot.name}; filter "
                 f"{f.cutoff_hz:.0f} Hz)", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


__all__ = ["robot_yaml", "write_report", "write_robot"]
