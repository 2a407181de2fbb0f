"""The safety report's files (issue 70): one HTML page with its plots embedded, for the
person who signs off on a cell, and the JSON file it was drawn from
(:func:`sixplus3.interaction.report.safety_report.safety_report`), both written atomically.
Every number on the page is read from that mapping: the page and the JSON cannot
disagree."""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.fileio import atomic_write, figure_png, strict_json

#: Lines drawn with a label (the largest); the rest grey.
LABELLED = 4


def _arr(values: list[Any]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def _img(fig: Any, alt: str) -> str:
    data = base64.b64encode(figure_png(fig, dpi=90)).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _lines(ax: Any, t: np.ndarray, series: dict[str, np.ndarray]) -> None:
    """The largest LABELLED series labelled, the tool centre point always; others grey."""
    peak = {k: np.nanmax(v) if np.isfinite(v).any() else 0.0 for k, v in series.items()}
    top = sorted(peak, key=lambda k: -peak[k])[:LABELLED]
    for k, v in series.items():
        if k in top or k == "tcp":
            ax.plot(t, v, lw=1.6 if k == "tcp" else 1.2, label=k)
        else:
            ax.plot(t, v, lw=0.6, color="0.75")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")


def _plots(rep: dict[str, Any]) -> list[str]:
    import matplotlib  # deferred: matplotlib loads in ~0.3 s, only for the plots

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: as above

    t = _arr(rep["path"]["t"])
    pts = rep["path"]["points"]
    out = []
    regions = rep["coverage"]["regions"]
    for name in regions:
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        force = {p: _arr(d["regions"][name]["force [N]"]) for p, d in pts.items()}
        _lines(a1, t, force)
        a1.axhline(rep["coverage"]["region limits [N]"][name], color="red", ls="--", lw=1)
        a1.set_ylabel(f"{name}: contact force [N]")
        mass = {p: _arr(d["regions"][name]["effective mass [kg]"]) for p, d in pts.items()}
        _lines(a2, t, mass)
        a2.set_ylabel("effective mass [kg]\n(worst direction)")
        a2.set_xlabel("t [s]")
        out.append(_img(fig, f"contact force and effective mass, {name}"))
    fig, ax = plt.subplots(figsize=(9, 3))
    _lines(ax, t, {p: _arr(d["speed [m/s]"]) for p, d in pts.items()})
    ax.set_ylabel("speed [m/s]")
    ax.set_xlabel("t [s]")
    out.append(_img(fig, "speed of every point"))
    stop = rep["stop"]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    a1.plot(t, 1e3 * _arr(stop["stop time [s]"]))
    a1.set_ylabel("stop time [ms]")
    a2.plot(t, 1e3 * _arr(stop["tcp distance [m]"]), label="tool centre point")
    a2.plot(t, 1e3 * _arr(stop["largest distance [m]"]), label="the farthest point")
    a2.plot(t, 1e3 * _arr(stop["tcp distance with detection [m]"]), ls="--",
            label=f"tool centre point, after {1e3 * stop['detection assumed [s]']:.0f} ms "
                  "of detection")
    a2.set_ylabel("stop distance [mm]")
    a2.set_xlabel("stop begun at t [s]")
    a2.legend(fontsize=7)
    for a in (a1, a2):
        a.grid(alpha=0.3)
    out.append(_img(fig, "stop time and distance from each sample"))
    return out


def _table(rows: list[tuple[str, Any]], cls: str = "") -> str:
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_fmt(v))}</td></tr>"
                   for k, v in rows)
    return f'<table class="{cls}">{body}</table>'


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v) if v else "none"
    if v is None:
        return "-"
    return str(v)


def page(rep: dict[str, Any]) -> str:
    """The report's HTML page (self-contained: plots embedded, no script fetched)."""
    v = rep["validation"]
    verdict = {0: "passes the gate", 1: "VIOLATES A LIMIT", 2: "NOT A VALID MOTION"}[
        int(v["exit_code"])]
    parts = [f"<h1>Safety report: {html.escape(Path(rep['file']).name)}</h1>",
             f'<p class="verdict" id="verdict">The file {verdict} (exit code '
             f'{v["exit_code"]}).</p>']
    if "refused" in rep:
        parts.append(f"<p>{html.escape(rep['refused'])}</p>")
        return _wrap(rep, parts)
    cov = rep["coverage"]
    if "largest" in rep:
        lg = rep["largest"]
        parts.append("<h2>The largest contact</h2>" + _table(
            [("ratio (contact energy / ISO/TS 15066 limit)", lg["ratio"]),
             ("where", lg["where"]), ("at t [s]", lg["t [s]"]), ("region", lg["region"]),
             ("two-body force [N]", lg["force [N]"]), ("limit [N]", lg["limit [N]"]),
             ("speed there [m/s]", lg["speed [m/s]"])], "largest"))
    else:
        parts.append("<h2>No body region judged</h2><p>This file was not planned for "
                     "power and force limiting: no contact with a person is judged. The "
                     "speeds are shown below.</p>")
    parts.append("<h2>Coverage</h2>" + _table(
        [("body regions judged", cov["regions"]),
         ("body regions not judged", cov["regions not covered"]),
         ("leg links judged", cov["leg links"]),
         ("leg links not judged", cov["leg links not covered"]),
         ("points judged", cov["points"]),
         ("never covered", cov["never covered"]),
         ("the site requires", f"regions {_fmt(cov['site requires']['regions'])}; leg "
                               f"links {_fmt(cov['site requires']['leg links'])}")]))
    parts.append("<h2>Along the path</h2>" + "".join(_plots(rep)))
    st = rep["stop"]
    parts.append("<h2>Stopping</h2>" + _table(
        [("the file's stop table", st["file's table"]),
         ("torque share of a stop", st["torque share"]),
         ("longest stop [s]", st["max stop time [s]"]),
         ("longest tool centre point distance [m]", st["max tcp distance [m]"]),
         ("longest distance of any point judged [m]", st["max distance [m]"]),
         ("detection before the stop (the guard's worst measured) [s]",
          st["detection assumed [s]"]),
         ("longest tool centre point distance with it [m]",
          st["max tcp distance with detection [m]"]),
         ("longest distance of any point judged with it [m]",
          st["max distance with detection [m]"])]))
    g = rep["guard"]
    parts.append("<h2>The contact guard</h2>" + _table(list(g["settings"].items())))
    head = list(g["measured"][0])
    rows = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(m[k]))}</td>" for k in head)
                   + "</tr>" for m in g["measured"])
    parts.append("<p>Measured (not computed from this file):</p><table><tr>"
                 + "".join(f"<th>{html.escape(k)}</th>" for k in head) + "</tr>" + rows
                 + "</table>")
    parts.append("<h2>Assumptions</h2><ul>" + "".join(
        f"<li>{html.escape(a)}</li>" for a in rep["assumptions"]) + "</ul>")
    parts.append("<h2>The gate's record</h2><p>As <code>sixplus3 validate --json</code> "
                 "prints it.</p>" + _table([(k, v[k]) for k in v], "validation"))
    return _wrap(rep, parts)


def _wrap(rep: dict[str, Any], parts: list[str]) -> str:
    style = ("body{font-family:sans-serif;max-width:980px;margin:2em auto;color:#222}"
             "table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;"
             "padding:3px 8px;text-align:left;font-size:13px;vertical-align:top}"
             "img{max-width:100%;display:block;margin:1em 0}.verdict{font-weight:bold}")
    title = html.escape(f"sixplus3 safety report: {Path(rep['file']).name}")
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{title}</title>"
            f"<style>{style}</style></head><body>{''.join(parts)}</body></html>\n")


def write_report(rep: dict[str, Any], out_dir: str | Path, stem: str
                 ) -> tuple[Path, Path]:
    """Write ``<stem>_safety.html`` and ``<stem>_safety.json`` in ``out_dir`` (made if
    missing), each atomically: (the page, the JSON file)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js, pg = out / f"{stem}_safety.json", out / f"{stem}_safety.html"
    atomic_write(js, strict_json(rep, indent=1).encode())
    atomic_write(pg, page(rep).encode())
    return pg, js


__all__ = ["page", "write_report"]
