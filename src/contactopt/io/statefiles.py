"""The files of one state solve: state.json, state.npz, body.vtu, lambda.png, pressure.png, classes.png,
contact.png (pressure, ‖τ‖, slip ‖u_t‖, stick/slip) and von_mises.png (where the von Mises stress
is largest, the peak marked).

:func:`write_state` is all-or-nothing: every file is first built in a temporary sibling directory
of ``outdir``; only when all of them succeeded are they moved into ``outdir`` (each by an atomic
rename; when ``outdir`` does not exist yet, the whole directory is renamed at once). A failure
part-way leaves ``outdir`` exactly as it was and removes the temporary directory. Half of the
figures are drawn in a forked child beside the other files where forking is safe
(:class:`~contactopt.io.forked.Forked`); the files are the same either way.

Conventions of the stored contact arrays (contact-node order m = 0..p−1, see
:mod:`contactopt.contact.state`):

* ``u_c[m] = (u1, u2, u3)``: tangential part u_t = (u1, u2), normal part u_ν = u3 (the foundation
  x3 ≤ 0 has normal e3);
* ``gap[m] = ϑ_α(x'_m)``: initial distance to the foundation; non-penetration u_ν + g ≥ 0;
* ``lam[m] = λ_m = (S u_c − ℓ)_ν ≥ 0``: normal contact force on the body (paper (3.17));
* ``pressure[m] = p_m = λ_m / a_m``: contact pressure, a_m the node's lumped contact area on Ω(α)
  (:mod:`contactopt.io.pressure`; force per unit area in the model's units);
* ``tau[m] = τ_m = −(S u_c − ℓ)_t``: the paper's tangential contact force, ‖τ_m‖ ≤ F λ_m and
  u_t ≠ 0 ⇒ τ_m = F λ_m u_t/‖u_t‖ (the friction force on the body is −τ_m);
* ``classes[m]``: index into ("L", "M1", "M2", "M3+", "M3-", "M4") of Table 4.1;
* ``contact_coords[m]`` (state.npz): the node's reference coordinates (x1, x2, x3), before the design
  moves it; ``contact_pair[m]``: the index of its contact pair in ``[[contacts]]`` (state.json's
  ``contacts`` lists the pairs with their resultant, peak pressure and classes);
* ``x1[m], x2[m]`` (state.json; ``contact_points`` in state.npz): the chart coordinates
  ξ = (ξ1, ξ2) of the contact node, (x1, x2) on the paper's map; state.json's ``chart`` names them
  (on a cylinder the arc length ρθ and the axial position, :mod:`contactopt.design.chart`). The
  keys stay x1, x2 on every chart, as in files written before.

On an elastic foundation ``u_c`` is the relative displacement w = u_body − u_partner of a contact
node and its partner on the foundation's top face (the contact law acts on it), ``u_body`` and
``u_partner`` are stored beside it, and ``foundation.vtu`` (the foundation with its displacement)
and ``foundation.png`` (the partners' vertical displacement −(Π u_f)_3, the foundation's
indentation under the contact face) join the files.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..contact.state import CLASS_NAMES, FoundationState, State
from ..design.chart import chart_summary
from ..design.several import alpha_record
from . import plots, vtk
from .atomic import atomic_savez, atomic_write_json, fsync_dir, to_jsonable
from .forked import Forked
from .pressure import contact_pressure, face_classes, pair_index, pair_reports

log = logging.getLogger(__name__)

__all__ = ["STATE_FILES", "FOUNDATION_FILES", "state_files", "write_state", "read_state_npz", "state_json"]

STATE_FILES = ("state.json", "state.npz", "body.vtu", "lambda.png", "pressure.png", "classes.png", "contact.png",
               "von_mises.png")
FOUNDATION_FILES = ("foundation.vtu", "foundation.png")      # with an elastic [foundation]
FORMAT_VERSION = 1

CONVENTIONS = {
    "ordering": "contact-node order m = 0..p-1: the nodes of the contact face with no clamped normal component, "
                "by node number (the block: i fastest, then j, i >= 1); a clamped tangential component of a "
                "node is pinned: u = 0 and no contact force in that direction",
    "u_c": "(u1, u2, u3): tangential u_t = (u1, u2), normal u_nu = u3; foundation x3 <= 0 with normal e3",
    "gap": "g_m = theta_alpha(x'_m) >= 0; non-penetration u_nu + g >= 0",
    "lam": "lambda_m = (S u_c - l)_nu >= 0: normal contact force on the body (paper (3.17))",
    "pressure": "p_m = lambda_m / a_m: contact pressure, a_m the lumped contact area of node m on the "
                "design's surface (force per unit area in the model's units)",
    "tau": "tau_m = -(S u_c - l)_t, |tau_m| <= F lambda_m; friction force on the body is -tau_m",
    "classes": "index into class_names (Table 4.1)",
    "x1, x2": "chart coordinates xi = (xi1, xi2) of the contact nodes, named in 'chart' (the paper's map: x1, x2)",
    "alpha": "control points alpha_ij, (d1+1) x (d2+1), row i along xi1 (x1 on the paper's map)",
}


def state_json(model, state: State, config=None, warnings=None, objective=None, constraints=None) -> dict:
    """The content of state.json: summary, design, contact arrays as lists, conventions, the
    chart of the face (its description and the names of the coordinates x1, x2), and
    ``warnings`` (e.g. the constraints of U the design breaks), ``objective`` ({type, value,
    terms}) and ``constraints`` ({name: {type, value, limit, margin}}) when given."""
    rows = _rows(model)
    doc = {
        "format_version": FORMAT_VERSION,
        "summary": state.summary(),
        "alpha": alpha_record(model.surface, state.alpha),
        "n_nodes": int(model.mesh.n_nodes),
        "n_contact": int(model.n_contact),
        "class_names": list(CLASS_NAMES),
        "conventions": CONVENTIONS,
        "chart": chart_summary(model.mesh.chart),
        "contacts": pair_reports(model, state),
        "contact": {
            "node": rows[0].tolist(),
            "x1": rows[1][:, 0].tolist(),
            "x2": rows[1][:, 1].tolist(),
            "lam": np.asarray(state.lam, float).tolist(),
            "pressure": contact_pressure(model, state.lam, state.coords).tolist(),
            "tau": np.asarray(state.tau, float).tolist(),
            "u_c": np.asarray(state.u_c, float).tolist(),
            "gap": np.asarray(state.gap, float).tolist(),
            "classes": np.asarray(state.classes, int).tolist(),
            "class": [CLASS_NAMES[k] for k in np.asarray(state.classes, int)],
        },
    }
    if model.n_contact > model.contact_nodes.size:     # faces on several bodies: each row's body
        doc["contact"]["body"] = rows[3]
    if state.foundation is not None:          # an elastic foundation: u_c is w = u_body − u_partner
        doc["contact"]["u_body"] = np.asarray(state.foundation.u_body_c, float).tolist()
        doc["contact"]["u_partner"] = np.asarray(state.foundation.u_partner, float).tolist()
    if state.slip_ref is not None:            # a load step: the law's slip increment, the accumulated slip
        doc["contact"]["slip_increment"] = np.asarray(state.slip_increment, float).tolist()
        doc["contact"]["slip"] = np.asarray(state.slip_increment if state.slip is None else state.slip, float).tolist()
    if model.foundation is not None:
        doc["foundation"] = model.foundation.summary()
    if warnings is not None:
        doc["warnings"] = list(warnings)
    if objective is not None:
        doc["objective"] = objective
    if constraints is not None:
        doc["constraints"] = constraints
    if config is not None:
        doc["config"] = config.to_dict() if hasattr(config, "to_dict") else config
    return doc


def _rows(model):
    """(node numbers, (x1, x2) or chart coordinates, reference coordinates, body names) of the law's
    rows: the face body's contact nodes, then those of the faces on other bodies (fem.faces), each
    numbered and placed on its own body's mesh."""
    nodes = np.asarray(model.contact_nodes, np.int64)
    xy = np.asarray(model.mesh.contact_points(), float)
    x = np.asarray(model.body.reference.points[nodes], float)
    names = [model.config.assembly.bodies[0]] * nodes.size
    if model.n_contact > nodes.size:
        f = model.foundation
        off = model.config.off_faces
        nodes, xy, x = (np.concatenate([nodes, f.off_nodes]), np.vstack([xy, f.off_points[:, :2]]),
                        np.vstack([x, f.off_points]))
        names += [off[int(k)] for k in f.off_pairs]
    return nodes, xy, x, names


def _state_arrays(model, state: State) -> dict:
    scalars = state.scalars()
    rows = _rows(model)
    return {
        "format_version": np.int64(FORMAT_VERSION),
        "alpha": np.asarray(state.alpha, float),
        "coords": np.asarray(state.coords, float),
        "u": np.asarray(state.u, float),
        "u_c": np.asarray(state.u_c, float),
        "lam": np.asarray(state.lam, float),
        "pressure": contact_pressure(model, state.lam, state.coords),
        "tau": np.asarray(state.tau, float),
        "gap": np.asarray(state.gap, float),
        "classes": np.asarray(state.classes, np.int64),
        "class_names": np.array(CLASS_NAMES),
        "contact_nodes": rows[0],
        "contact_points": rows[1],
        "contact_coords": rows[2],
        "contact_pair": pair_index(model),
        "friction": np.asarray(state.friction, np.float64),     # 0-d, or (p,) per contact node
        "method": np.array(str(state.method)),
        "iterations": np.int64(state.iterations),
        "residual": np.float64(state.residual),
        "complementarity": np.float64(state.complementarity),
        "converged": np.bool_(state.converged),
        "timings_json": np.array(json.dumps(to_jsonable(state.timings))),
        "info_json": np.array(json.dumps(to_jsonable(scalars))),
        **({"u_body_c": np.asarray(state.foundation.u_body_c, float),
            "u_partner": np.asarray(state.foundation.u_partner, float),
            "foundation_u": np.asarray(state.foundation.displacement, float)} if state.foundation is not None else {}),
        **({"slip_increment": np.asarray(state.slip_increment, float),
            "slip": np.asarray(state.slip_increment if state.slip is None else state.slip, float)}
           if state.slip_ref is not None else {}),
    }


def _check_finite(state: State) -> None:
    for name in ("alpha", "coords", "u", "u_c", "lam", "tau", "gap"):
        arr = np.asarray(getattr(state, name), float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"state.{name} has non-finite values; refusing to write the state")


def state_files(model) -> tuple:
    """The files :func:`write_state` writes for ``model``'s states (the foundation's where a
    counterpart has a mesh: not where every counterpart of several pairs is rigid)."""
    return STATE_FILES + (FOUNDATION_FILES if _counterpart_bodies(model) else ())


def _counterpart_bodies(model) -> bool:
    """Whether ``model`` has an elastic counterpart (a [foundation], or a counterpart body of its pairs)."""
    return model.foundation is not None and any(f.n_nodes for f in model.foundation.parts)


def _move_into(tmpdir: Path, outdir: Path, names=STATE_FILES) -> None:
    """Move the finished files of ``tmpdir`` into ``outdir``; rename the whole directory if it is new."""
    if not outdir.exists():
        os.chmod(tmpdir, 0o755)               # mkdtemp makes 0o700
        try:
            os.rename(tmpdir, outdir)         # the whole directory appears at once
            fsync_dir(outdir.parent)
            return
        except OSError:
            if not outdir.is_dir():           # not a race with another writer creating it
                raise
    if not outdir.is_dir():
        raise NotADirectoryError(f"{outdir} exists and is not a directory")
    for name in names:
        os.replace(tmpdir / name, outdir / name)
    fsync_dir(outdir)


def write_state(outdir, model, state: State, *, config=None, warnings=None, objective=None,
                constraints=None) -> dict:
    """Write the files of :data:`STATE_FILES` into ``outdir``, all or nothing.

    ``config`` (a :class:`~contactopt.config.Config` or a plain dict), when given, is stored
    resolved in state.json under ``"config"``; ``warnings`` (a list of strings) under
    ``"warnings"``; ``objective`` ({type, value, terms}: the objective at the state's design,
    :meth:`contactopt.problem.ShapeProblem.objective_report`) under ``"objective"``, ``constraints``
    (:meth:`~contactopt.problem.ShapeProblem.constraint_report`) under ``"constraints"``. Existing
    files of the same names are replaced;
    other files in ``outdir`` are left alone. Returns ``{file name: Path}`` of the written files.
    Raises ``ValueError`` for a state with non-finite arrays (nothing is written).
    """
    outdir = Path(outdir)
    _check_finite(state)
    parent = outdir.parent
    parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.", suffix=".tmp", dir=parent))
    try:
        pressure = contact_pressure(model, state.lam, state.coords)
        # half of the figures drawn in a forked child beside the other files (io/forked.py)
        forked = [lambda: plots.plot_contact_field(tmpdir / "lambda.png", model, state.lam,
                                                   "Normal contact force $\\lambda$", cmap="viridis",
                                                   label="$\\lambda$"),
                  lambda: plots.plot_contact_field(tmpdir / "pressure.png", model, pressure,
                                                   "Contact pressure $p = \\lambda / a$", cmap="viridis", label="$p$"),
                  lambda: plots.plot_peak_stress(tmpdir / "von_mises.png", model, np.asarray(state.coords, float),
                                                 np.asarray(state.u, float))]
        with Forked(forked, directory=tmpdir) as figures:
            atomic_write_json(tmpdir / "state.json", state_json(model, state, config, warnings, objective,
                                                                      constraints))
            atomic_savez(tmpdir / "state.npz", **_state_arrays(model, state))
            vtk.write_body_vtu(tmpdir / "body.vtu", model, state)
            classes = face_classes(model, state)
            plots.plot_node_classes(tmpdir / "classes.png", model, classes)
            plots.plot_contact_response(tmpdir / "contact.png", model, pressure, state.tau,
                                        np.asarray(state.u_c)[:, :2], classes)
            if _counterpart_bodies(model):
                vtk.write_foundation_vtu(tmpdir / "foundation.vtu", model.foundation, state)
                plots.plot_contact_field(tmpdir / "foundation.png", model,
                                         -np.asarray(state.foundation.u_partner)[:, 2],
                                         "Indentation of the foundation $-(\\Pi u_f)_3$ under the contact nodes",
                                         cmap="viridis", label="$-(\\Pi u_f)_3$")
            figures.join()
        names = state_files(model)
        built = sorted(p.name for p in tmpdir.iterdir())
        if built != sorted(names):
            raise RuntimeError(f"write_state built {built}, expected {sorted(names)}")
        _move_into(tmpdir, outdir, names)
    finally:
        if tmpdir.exists():
            shutil.rmtree(tmpdir, ignore_errors=True)
    log.info("wrote the state files %s into %s", ", ".join(names), outdir)
    return {name: outdir / name for name in names}


_NPZ_KEYS = ("alpha", "coords", "u", "u_c", "lam", "tau", "gap", "classes", "friction", "method",
             "iterations", "residual", "complementarity", "converged", "timings_json", "info_json")


def _friction(stored: np.ndarray):
    """F as a state holds it: a float, or (p,) per contact node."""
    return float(stored) if stored.ndim == 0 else np.asarray(stored, np.float64)


def read_state_npz(path) -> State:
    """Read a state.npz written by :func:`write_state` back into a :class:`State` (no pickles).

    Of the statistics and data (``State.info``) it holds the scalars (the ones summary() keeps), in
    their named fields (:meth:`State.fields_of_info`).
    """
    path = Path(path)
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in _NPZ_KEYS if k not in z.files]
        if missing:
            raise ValueError(f"{path}: not a contactopt state file, missing arrays {missing}")
        info = json.loads(str(z["info_json"]))
        foundation = None
        if "u_partner" in z.files:        # an elastic foundation
            info.pop("foundation", None)
            foundation = FoundationState(u_body_c=z["u_body_c"], u_partner=z["u_partner"],
                                         displacement=z["foundation_u"])
        return State(
            alpha=z["alpha"], coords=z["coords"], u=z["u"], u_c=z["u_c"], lam=z["lam"], tau=z["tau"],
            gap=z["gap"], classes=z["classes"].astype(int), friction=_friction(z["friction"]),
            method=str(z["method"]), iterations=int(z["iterations"]), residual=float(z["residual"]),
            complementarity=float(z["complementarity"]), converged=bool(z["converged"]),
            timings=json.loads(str(z["timings_json"])), foundation=foundation, **State.fields_of_info(info))


def write_steps(outdir, model, steps, *, config=None, warnings=None, reports=None, combined=None) -> list[dict]:
    """The states of a load path's steps ``steps`` [(name, state)], each into ``step-<name>/``
    (:func:`write_state`), with ``steps.json`` listing them and ``body.pvd``, the bodies as a
    time series (time = the step's position). ``reports`` [(objective, constraints)] per step go
    into each state.json (the responses at the step's end), ``combined`` (objective, constraints)
    over the steps into steps.json. Returns the listing."""
    outdir = Path(outdir)
    listing = []
    for k, (name, state) in enumerate(steps):
        d = f"step-{name}"
        objective, constraints = reports[k] if reports is not None else (None, None)
        write_state(outdir / d, model, state, config=config, warnings=warnings, objective=objective,
                    constraints=constraints or None)
        listing.append({"name": name, "index": k + 1, "directory": d, "summary": state.summary()})
        if objective is not None:
            listing[-1]["objective"] = objective["value"]
    doc = {"steps": listing, "warnings": warnings}
    if combined is not None:
        doc["objective"] = combined[0]
        if combined[1]:
            doc["constraints"] = combined[1]
    atomic_write_json(outdir / "steps.json", doc)
    vtk.write_pvd(outdir / "body.pvd", [(k + 1, f"step-{name}/body.vtu") for k, (name, _) in enumerate(steps)])
    return listing
