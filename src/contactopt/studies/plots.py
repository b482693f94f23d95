"""Comparison figures of a sweep (PNG, matplotlib Agg, object API as :mod:`contactopt.io.plots`).

- ``ratio.png``: J/J0 against each swept parameter (one panel per key; with several keys, one
  line per combination of the other keys). Failed tasks are left out.
- ``surfaces.png``: the optimal contact surfaces ϑ_α of the runs overlaid, as two sections
  (x2 = b/2 against x1, x1 = a/2 against x2) read from each run's ``surface.csv``; on a face off
  the paper's map the sections are along its chart's ξ1 and ξ2 (summary.json ``chart``).
- ``lambda.png``: the normal contact force λ ≥ 0 of the optimal designs overlaid: the contact
  nodes of the row nearest x2 = b/2 against x1, and the sum over each column of nodes (same x1),
  read from each run's ``optimal.vtu`` (point data ``normal_force`` on ``contact_node``).
"""

from __future__ import annotations

import csv
import json
import logging
from pathlib import Path

import meshio
import numpy as np

from ..io.plots import _new_figure, _save
from .settings import format_value

log = logging.getLogger(__name__)

__all__ = ["plot_sweep", "plot_ratio", "plot_surfaces", "plot_lambda"]


def _label(row, keys) -> str:
    return ", ".join(f"{k}={format_value(row[k])}" for k in keys)


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def plot_ratio(path, keys, rows) -> Path:
    """J/J0 against each swept key."""
    ok = [r for r in rows if not r.get("error") and r.get("ratio") is not None]
    fig = _new_figure((4.2 * len(keys), 3.6))
    for n, key in enumerate(keys):
        ax = fig.add_subplot(1, len(keys), n + 1)
        others = [k for k in keys if k != key]
        groups: dict = {}
        for r in ok:
            groups.setdefault(tuple(format_value(r[k]) for k in others), []).append(r)
        values = sorted({r[key] for r in ok}, key=lambda v: (str(type(v)), v))
        numeric = _numeric(values)
        for g, members in groups.items():
            members = sorted(members, key=lambda r: values.index(r[key]))
            x = [r[key] if numeric else values.index(r[key]) for r in members]
            lab = ", ".join(f"{k}={v}" for k, v in zip(others, g)) or None
            ax.plot(x, [r["ratio"] for r in members], "o-", label=lab)
        if not numeric:
            ax.set_xticks(range(len(values)), [format_value(v) for v in values])
        ax.set_xlabel(key)
        ax.set_ylabel("$J/J_0$")
        ax.grid(True, alpha=0.3)
        if others and groups:
            ax.legend(fontsize=7)
    fig.suptitle(f"sweep: $J/J_0$ of {len(ok)} finished runs")
    return _save(fig, path)


def _read_surface(run_dir: Path):
    with open(run_dir / "surface.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    x1 = np.array([float(r["x1"]) for r in rows])
    x2 = np.array([float(r["x2"]) for r in rows])
    th = np.array([float(r["theta"]) for r in rows])
    return x1, x2, th


def _section_labels(outdir, rows) -> tuple[str, str]:
    """The labels of the two sections of surface.csv, whose columns x1, x2 hold x1, x2 on the
    paper's map and the chart's ξ1, ξ2 on a face off it (the first finished run's summary.json
    ``chart``)."""
    for r in rows:
        summary = Path(outdir) / r["run_dir"] / "summary.json"
        if r.get("error") or not summary.exists():
            continue
        chart = json.loads(summary.read_text()).get("chart", {})
        if chart and not chart.get("description", "").startswith("the paper's map"):
            return "$\\xi_1$ (at the middle of $\\xi_2$)", "$\\xi_2$ (at the middle of $\\xi_1$)"
        break
    return "$x_1$ (at $x_2 = b/2$)", "$x_2$ (at $x_1 = a/2$)"


def plot_surfaces(path, outdir, keys, rows) -> Path:
    """Sections of the optimal surfaces of every finished run, overlaid."""
    fig = _new_figure((10.0, 3.8))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for r in rows:
        run = Path(outdir) / r["run_dir"]
        if r.get("error") or not (run / "surface.csv").exists():
            continue
        x1, x2, th = _read_surface(run)
        mid2 = np.unique(x2)[np.argmin(np.abs(np.unique(x2) - 0.5 * (x2.min() + x2.max())))]
        mid1 = np.unique(x1)[np.argmin(np.abs(np.unique(x1) - 0.5 * (x1.min() + x1.max())))]
        s = x2 == mid2
        line, = ax1.plot(x1[s], th[s], label=_label(r, keys))
        s = x1 == mid1
        ax2.plot(x2[s], th[s], color=line.get_color())
    label1, label2 = _section_labels(outdir, rows)
    ax1.set_xlabel(label1)
    ax2.set_xlabel(label2)
    for ax in (ax1, ax2):
        ax.set_ylabel(r"$\vartheta_\alpha$")
        ax.grid(True, alpha=0.3)
    if ax1.lines:
        ax1.legend(fontsize=7)
    fig.suptitle("optimal contact surfaces")
    return _save(fig, path)


def _read_lambda(run_dir: Path):
    mesh = meshio.read(run_dir / "optimal.vtu")
    on = np.asarray(mesh.point_data["contact_node"]).ravel() > 0
    pts = np.asarray(mesh.points)[on]
    lam = np.asarray(mesh.point_data["normal_force"]).ravel()[on]
    return pts[:, 0], pts[:, 1], lam


def plot_lambda(path, outdir, keys, rows) -> Path:
    """Normal contact forces of the optimal designs, overlaid."""
    fig = _new_figure((10.0, 3.8))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for r in rows:
        run = Path(outdir) / r["run_dir"]
        if r.get("error") or not (run / "optimal.vtu").exists():
            continue
        x1, x2, lam = _read_lambda(run)
        rows2 = np.unique(np.round(x2, 9))
        mid = rows2[np.argmin(np.abs(rows2 - 0.5 * (rows2.min() + rows2.max())))]
        s = np.round(x2, 9) == mid
        order = np.argsort(x1[s])
        line, = ax1.plot(x1[s][order], lam[s][order], ".-", label=_label(r, keys))
        cols, inv = np.unique(np.round(x1, 9), return_inverse=True)
        ax2.plot(cols, np.bincount(inv, weights=lam), ".-", color=line.get_color())
    ax1.set_xlabel("$x_1$ (contact nodes nearest $x_2 = b/2$)")
    ax1.set_ylabel(r"$\lambda$")
    ax2.set_xlabel("$x_1$")
    ax2.set_ylabel(r"$\sum_{x_2} \lambda$ (per column of nodes)")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    if ax1.lines:
        ax1.legend(fontsize=7)
    fig.suptitle(r"normal contact force $\lambda$ at the optimal designs")
    return _save(fig, path)


def plot_sweep(outdir, keys, rows) -> list[Path]:
    """All comparison figures of a sweep into its directory; returns their paths."""
    outdir = Path(outdir)
    return [plot_ratio(outdir / "ratio.png", keys, rows),
            plot_surfaces(outdir / "surfaces.png", outdir, keys, rows),
            plot_lambda(outdir / "lambda.png", outdir, keys, rows)]
