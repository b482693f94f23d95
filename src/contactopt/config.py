"""Configuration model: a TOML file (or a built-in example name) validated up front.

Every problem is collected and reported at once in a :class:`ConfigError`, each naming the key
and the allowed values. The resolved configuration is a plain nested dict (``Config.data``) with
every default filled in, so it can be written back to TOML for a run directory.
"""

from __future__ import annotations

import copy
import logging
import math
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from .errors import ConfigError

log = logging.getLogger(__name__)

EXAMPLES = ("example1", "example2", "example3")

_NUM = (int, float)


def _pos(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def _nonneg(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x) and x >= 0


def _finite(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x)


def _posint(x):
    return isinstance(x, int) and not isinstance(x, bool) and x >= 1


def _vec3(x):
    return isinstance(x, (list, tuple)) and len(x) == 3 and all(_finite(v) for v in x)


def _axis(x):
    return x == [] or (isinstance(x, list) and len(x) >= 2 and all(_finite(v) for v in x))


def _oneof(*options):
    def check(x):
        return x in options
    check.__doc__ = "one of " + ", ".join(repr(o) for o in options)
    return check


def _part_spec(x):
    """A part: a group name, or a predicate table {x1|x2|x3 = v, box = [[lo, hi]] × 3}."""
    if isinstance(x, str):
        return x != ""
    if not isinstance(x, dict) or not x or set(x) - {"x1", "x2", "x3", "box"}:
        return False
    for k, v in x.items():
        if k == "box":
            if not (isinstance(v, list) and len(v) == 3 and all(
                    isinstance(iv, list) and len(iv) == 2 and all(_finite(t) for t in iv) and iv[0] <= iv[1]
                    for iv in v)):
                return False
        elif not _finite(v):
            return False
    return True


OBJECTIVE_TYPES = ("target_normal_force", "compliance", "pressure_uniformity", "max_pressure",
                   "frictional_dissipation", "peak_stress")
_PART_SHORT = "a part (a group name or a predicate table)"
_PART = "a part: a group name such as \"bottom\", or a predicate table such as { x1 = 0.0 } or { box = [[x1lo, x1hi], [x2lo, x2hi], [x3lo, x3hi]] }"


def _clamp_spec(x):
    items = x if isinstance(x, list) else [x]
    if not items:
        return False
    for it in items:
        if isinstance(it, dict) and "on" in it:
            comps = it.get("components", [1, 2, 3])
            if set(it) - {"on", "components"} or not _part_spec(it["on"]):
                return False
            if not (isinstance(comps, list) and comps and all(c in (1, 2, 3, "x1", "x2", "x3") for c in comps)):
                return False
        elif not _part_spec(it):
            return False
    return True


def _load_list(value_check):
    def check(x):
        return isinstance(x, list) and all(
            isinstance(it, dict) and set(it) == {"on", "value"} and _part_spec(it["on"]) and value_check(it["value"])
            for it in x)
    return check


# section -> key -> (default, check, description of the allowed values)
SCHEMA = {
    "body": {
        "mesh": ("", lambda x: isinstance(x, str),
                 "a path to a mesh file (Gmsh .msh, .vtu, .inp, … read by meshio), relative to this file; "
                 "empty: the block of [geometry] and [mesh]"),
        "clamped": ("clamped", _clamp_spec,
                    _PART + "; or { on = <part>, components = [1, 3] } to fix some components; or a list of these. "
                    "On the contact face a clamped u1 or u2 (a symmetry plane) keeps the node a contact node "
                    "with friction in its free direction; a clamped u3 takes it out of the contact set"),
        "contact": ("contact", _part_spec, _PART + " (the designed contact face, on x3 = 0 in the mesh)"),
        "fixed_shape": ("auto", lambda x: x == "auto" or (isinstance(x, list) and all(_part_spec(v) for v in x)),
                        "'auto' (the named parts that share no node with the contact face) or a list of parts "
                        "whose shape the morph keeps"),
        "tolerance": (1e-3, lambda x: _pos(x) and x < 0.5,
                      "a number in (0, 0.5) (geometric tolerance of plane and predicate checks, relative to the "
                      "median boundary edge length)"),
        "min_jacobian_ratio": (0.1, lambda x: _finite(x) and 0 < x < 1,
                               "a number in (0, 1) (smallest det J(α)/det J_ref accepted at a quadrature point)"),
        "initial_gap": ("zero", lambda x: x in ("zero", "mesh"),
                        "'zero' (the contact face lies on the foundation plane x3 = 0: the gap is ϑ_α) or 'mesh' "
                        "(the contact face may lie above it, e.g. an exported optimal body: the gap is its "
                        "height x3 in the mesh plus ϑ_α)"),
    },
    "geometry": {
        "a": (2.0, _pos, "a number > 0 (length in x1)"),
        "b": (1.0, _pos, "a number > 0 (length in x2)"),
        "c": (1.0, _pos, "a number > 0 (height of the top face)"),
    },
    "mesh": {
        "nx": (32, _posint, "an integer ≥ 1"),
        "ny": (15, _posint, "an integer ≥ 1"),
        "nz": (9, _posint, "an integer ≥ 1"),
        "x1": ([], _axis, "a list of node coordinates in x1, strictly increasing from 0 to geometry.a (which "
               "the last one sets when [geometry] does not give a), instead of nx: a graded block; empty: nx "
               "equal elements"),
        "x2": ([], _axis, "a list of node coordinates in x2, strictly increasing from 0 to geometry.b, instead "
               "of ny (see x1)"),
        "x3": ([], _axis, "a list of node coordinates in x3, strictly increasing from 0 (the contact face) to "
               "geometry.c, instead of nz (see x1)"),
    },
    "material": {
        "E": (21.19, _pos, "a number > 0 (Young's modulus)"),
        "nu": (0.277, lambda x: _finite(x) and -1.0 < x < 0.5, "a number in (−1, 0.5) (Poisson's ratio)"),
        "formulation": ("auto", lambda x: x in ("auto", "standard", "bbar"),
                        "'auto', 'standard' or 'bbar': the element formulation. 'bbar' (hexahedra only): the "
                        "dilatation replaced by its element mean (Hughes' B-bar), free of volumetric locking as "
                        "ν → 0.5; 'auto': 'bbar' on hexahedra from ν ≥ 0.45, else 'standard'. Tetrahedra take "
                        "'standard' (or 'auto'); for nearly incompressible materials on tetrahedra use tetra10 "
                        "(docs/materials.md)"),
    },
    "friction": {
        "coefficient": (0.3, _nonneg, "a number ≥ 0 (Coulomb coefficient F)"),
    },
    "loads": {
        "top_traction": ([0.0, 0.0, -8e-2], _vec3,
                         "a list of 3 numbers (the block's traction on its part 'top', x3 = c)"),
        "right_traction": ([5e-2, 0.0, 0.0], _vec3,
                           "a list of 3 numbers (the block's traction on its part 'right', x1 = a)"),
        "body_force": ([0.0, 0.0, 0.0], _vec3, "a list of 3 numbers (force per unit volume)"),
        "traction": ([], _load_list(_vec3),
                     "a list of tables { on = <part>, value = [t1, t2, t3] } (force per unit area, fixed direction)"),
        "pressure": ([], _load_list(_finite),
                     "a list of tables { on = <part>, value = p } (normal pressure, p > 0 pushes into the body; "
                     "follows the face as it moves)"),
    },
    "design": {
        "degree": ([7, 3], lambda x: isinstance(x, list) and len(x) == 2 and all(_posint(v) for v in x),
                   "a list of 2 integers ≥ 1 (Bézier degrees d1, d2)"),
        "C0": (0.75, _pos, "a number > 0 (upper bound of the control points)"),
        "lower": (0.0, _finite, "a number ≤ C0 (lower bound of the control points; 0 is the paper's U, a negative "
                  "bound admits crowned faces such as a paraboloid, whose Bézier net dips below 0)"),
        "nonnegative_gap": (True, lambda x: isinstance(x, bool),
                            "true or false (keep the contact face on or above the foundation plane: "
                            "ϑ_α ≥ 0 at every node of the face, with initial_gap = 'mesh' its height in the "
                            "mesh + ϑ_α ≥ 0; linear constraints of U, needed only where design.lower < 0)"),
        "C1": (0.5, _pos, "a number > 0 (slope bound)"),
        "C2": (0.01, _nonneg, "a number ≥ 0 (mean control point: the volume constraint)"),
        "slope_divisor": ("degree", _oneof("degree", "count"), "'degree' or 'count'"),
        "initial": (0.01, lambda x: _finite(x) or isinstance(x, list),
                    "a number (all control points) or a (d1+1)×(d2+1) nested list"),
        "domain": ([], lambda x: x == [] or (isinstance(x, list) and len(x) == 2 and all(
            isinstance(iv, list) and len(iv) == 2 and all(_finite(t) for t in iv) and iv[0] < iv[1] for iv in x)),
                   "[[x1lo, x1hi], [x2lo, x2hi]] (the rectangle carrying the control net; "
                   "empty: the bounding rectangle of the contact face)"),
        "symmetry": ([], lambda x: isinstance(x, list) and len(set(x)) == len(x) and all(v in ("x1", "x2") for v in x),
                     "a list of 'x1' and/or 'x2' (mirror the control net about the mid-line of the design "
                     "rectangle normal to that axis: 'x2' keeps α[i, j] = α[i, d2 − j]; the optimizer works "
                     "on the reduced variables)"),
        "fixed": ([], lambda x: isinstance(x, list) and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in p)
            for p in x),
                  "a list of [i, j] control points kept at their initial value"),
        "direction": ("both", _oneof("both", "grow", "shrink"),
                      "'both', 'grow' (α ≥ initial; the mean value becomes an upper bound Σα ≤ "
                      "C2·(d1+1)(d2+1)) or 'shrink' (α ≤ initial; the mean value a lower bound)"),
        "linear": ([], lambda x: isinstance(x, list) and all(
            isinstance(r, dict) and "coefficients" in r and len(set(r) & {"upper", "equal"}) == 1
            and not set(r) - {"coefficients", "upper", "equal"} and all(
                _finite(r[k]) for k in ("upper", "equal") if k in r) for r in x),
                   "a list of tables { coefficients = (d1+1)×(d2+1) nested list, upper = u } (Σ c·α ≤ u) or "
                   "{ coefficients = …, equal = e } (Σ c·α = e)"),
    },
    "objective": {
        "type": ("target_normal_force",
                 _oneof(*OBJECTIVE_TYPES, "sum"),
                 "'target_normal_force', 'compliance', 'pressure_uniformity' (the spread Σ a_m (p_m − p̄)² "
                 "of the contact pressure p_m = λ_m/a_m), 'max_pressure', 'frictional_dissipation' "
                 "(Σ τ_m·u_t,m), 'peak_stress' (the largest von Mises stress of `region`) or 'sum' (of "
                 "[[objective.terms]]; implied by them)"),
        "target": ({"kind": "constant", "value": 0.0}, lambda x: isinstance(x, dict),
                   "a table with 'kind' = 'constant' | 'step' | 'values' | 'design'"),
        "scale": (1.0, _pos, "a number > 0 (multiplies the objective)"),
        "region": ("", lambda x: x == "" or _part_spec(x),
                   "empty (the whole body) or " + _PART_SHORT + " (peak_stress: the elements with every "
                   "node in the part, or with a node in it for a boundary part)"),
        "aggregate": ("max", _oneof("max", "ks", "pnorm"),
                      "'max' (nonsmooth, exact), 'ks' (max + ln Σ exp(ρ(x − max))/ρ) or 'pnorm' "
                      "((Σ x^p)^(1/p)): how peak_stress and max_pressure take the largest value"),
        "rho": (50.0, _pos, "a number > 0 (aggregate 'ks': ρ, in 1/units of the stress or pressure)"),
        "p": (8.0, _pos, "a number > 0 (aggregate 'pnorm': the exponent)"),
        "terms": ([], lambda x: isinstance(x, list) and all(isinstance(t, dict) for t in x),
                  "an array of tables [[objective.terms]], each with `type`, `weight` (≥ 0, default 1) "
                  "and that type's keys (region, aggregate, rho, p, target): the objective is Σ weight·J_term"),
        "combine": ("max", _oneof("max", "sum"),
                    "'max' (the worst of the [[load_cases]]) or 'sum' (their weighted sum); "
                    "'sum' needs load cases"),
        "weights": ([], lambda x: (isinstance(x, list) and all(_nonneg(v) for v in x)) or (
            isinstance(x, dict) and all(isinstance(k, str) and _nonneg(v) for k, v in x.items())),
                    "a list of numbers ≥ 0, one per load case in order, or a table case name = weight "
                    "(cases not named weigh 1); empty: every case weighs 1. Θ_k is multiplied by its "
                    "weight before the max or the sum"),
        "steps": ("last", lambda x: x in ("last", "max", "sum") or (
            isinstance(x, list) and x and all(isinstance(v, str) for v in x)),
                  "'last' (the objective at the end of the last [[load_steps]]), 'max' (the worst step), "
                  "'sum' (the sum over the steps) or a list of step names (the worst of those steps); "
                  "without load steps the one step is the last ('frictional_dissipation' at a step is the "
                  "friction work from the start of the path up to the step's end)"),
        "active_tol": (1e-6, lambda x: _nonneg(x) and x < 1,
                       "a number in [0, 1) (with combine = 'max', the cases within this fraction of the "
                       "largest value are reported as active)"),
    },
    "state": {
        "method": ("newton", _oneof("newton", "fixed-point"), "'newton' or 'fixed-point'"),
        "tol": (1e-12, lambda x: _pos(x) and x < 1, "a number in (0, 1) (Siconos error of the local problem; at 1e-12 every contact condition of the examples holds to 1e-9)"),
        "max_iter": (200, _posint, "an integer ≥ 1"),
        "zone": (True, lambda x: isinstance(x, bool),
                 "true or false (solve the local problem on the nodes near the foundation only)"),
        "zone_margin": (0.1, lambda x: _nonneg(x) and x <= 10,
                        "a number in [0, 10] (clearance, relative to the displacement scale, "
                        "within which a node joins the contact zone)"),
        "reuse_delassus": (True, lambda x: isinstance(x, bool),
                           "true or false (Newton builds its matrices from the Delassus block of "
                           "an earlier design, with exact residuals, instead of inverting the new one)"),
    },
    "linear_solver": {
        "path": ("auto", _oneof("auto", "condensation", "delassus", "fullspace", "petsc"),
                 "'auto', 'condensation', 'delassus', 'fullspace' or 'petsc' (how a design's contact problem and "
                 "its adjoint are solved, docs/architecture.md): 'condensation' onto all contact DOFs "
                 "(dense S); 'delassus' for large meshes, a sparse Cholesky factorization of A(α) per "
                 "design and the contact zone's Delassus products by solves with it; 'fullspace' for "
                 "meshes no factorization fits, a semismooth Newton method on all DOFs with "
                 "AMG-preconditioned GMRES (pyamg) (docs/large_meshes.md); 'petsc' the same method on "
                 "PETSc under MPI (`mpiexec -n N contactopt run`, petsc4py; docs/guide/large-meshes.md); "
                 "'auto': 'petsc' under mpiexec with more than one rank, else 'fullspace' "
                 "from `crossover` free DOFs on, else 'condensation'"),
        "library": ("auto", _oneof("auto", "pardiso", "scipy"),
                    "'auto', 'pardiso' or 'scipy' (the sparse direct solver of the condensation and "
                    "Delassus paths; 'auto': MKL PARDISO where the mkl wheel is installed, else SciPy)"),
        "crossover": (60000, _posint, "an integer ≥ 1 (free DOFs from which path 'auto' takes the "
                      "full-space path)"),
        "petsc_options": ("", lambda x: isinstance(x, str),
                          "a string of PETSc options for path 'petsc' (e.g. \"-ksp_view -log_view\", "
                          "\"-pc_gamg_threshold 0.02\"), given to PETSc's options database as on a "
                          "command line"),
        "memory_check": (True, lambda x: isinstance(x, bool),
                         "true or false (refuse up front a mesh whose estimated peak memory of an "
                         "evaluation exceeds the available memory; contactopt.fem.memory)"),
    },
    "optimizer": {
        "eps": (1e-4, lambda x: _pos(x) and x < 1, "a number in (0, 1) (BT stopping parameter ε)"),
        "max_iter": (400, _posint, "an integer ≥ 1"),
        "ftol": (5e-4, lambda x: _nonneg(x) and x < 1,
                 "a number in [0, 1) (stop when, right after a serious step, the bundle model "
                 "predicts a relative decrease of Θ below this fraction: J within about ftol of a "
                 "local optimum, docs/stopping.md; 0: off)"),
        "ftol_window": (5, _posint, "an integer ≥ 1 (serious steps before the ftol test may stop "
                        "the run)"),
        "metric": ("bfgs", _oneof("bfgs", "diagonal", "none"),
                   "'bfgs', 'diagonal' or 'none' (the variable metric of the bundle QP's proximal "
                   "term: damped BFGS from the last `metric_memory` serious steps, for a piecewise "
                   "smooth Θ; a diagonal secant estimate; or the identity, the default of "
                   "contactopt.optimize.minimize_bundle, for polyhedral functions; docs/stopping.md)"),
        "metric_memory": (20, _posint, "an integer ≥ 1 (serious steps the metric is estimated "
                          "from)"),
    },
}


def _block_spec(x):
    """A foundation block: {size = [s1, s2, s3] > 0, cells = [n1, n2, n3] ≥ 1, origin = [o1, o2],
    element = 'hexahedron' | 'tetra'} (origin and element optional)."""
    if not isinstance(x, dict) or set(x) - {"size", "cells", "origin", "element"} or not {"size", "cells"} <= set(x):
        return False
    size, cells = x["size"], x["cells"]
    origin, element = x.get("origin", [0.0, 0.0]), x.get("element", "hexahedron")
    return (isinstance(size, list) and len(size) == 3 and all(_pos(v) for v in size)
            and isinstance(cells, list) and len(cells) == 3 and all(_posint(v) for v in cells)
            and isinstance(origin, list) and len(origin) == 2 and all(_finite(v) for v in origin)
            and element in ("hexahedron", "tetra"))


def _material_spec(x):
    if not isinstance(x, dict) or set(x) - {"E", "nu"}:
        return False
    return _pos(x.get("E", 1.0)) and _finite(x.get("nu", 0.0)) and -1.0 < x.get("nu", 0.0) < 0.5


# the foundation's own loads: the forms of [loads] that need no block part
FOUNDATION_LOADS = {k: SCHEMA["loads"][k] for k in ("traction", "pressure", "body_force")}

# [foundation]: optional — absent, the foundation is the rigid half-space x3 ≤ 0 (docs/foundation.md)
FOUNDATION = {
    "mesh": ("", lambda x: isinstance(x, str),
             "a path to the foundation's mesh file (as body.mesh), relative to this file; or empty with `block`"),
    "block": ({}, lambda x: x == {} or _block_spec(x),
              "a table { size = [s1, s2, s3], cells = [n1, n2, n3], origin = [o1, o2], element = 'hexahedron' "
              "| 'tetra' }: the box [o1, o1+s1]×[o2, o2+s2]×[−s3, 0] (top face on x3 = 0, the foundation below) "
              "with parts top, bottom, left (x1 = o1), right, front (x2 = o2), back; origin defaults to "
              "[0, 0], element to hexahedra (tetra: each split into six)"),
    "top": ("top", _part_spec, _PART + " (the foundation's face on x3 = 0 under the contact face)"),
    "clamped": ("bottom", _clamp_spec, "as body.clamped, on the foundation's mesh; it must hold the "
                "foundation in place (no rigid-body motion)"),
    "material": ({}, _material_spec, "a table { E = ..., nu = ... } (Young's modulus > 0, Poisson's ratio in "
                 "(−1, 0.5)); a key not given is the body's [material] value"),
    "loads": ({}, lambda x: isinstance(x, dict) and set(x) <= set(FOUNDATION_LOADS) and all(
        FOUNDATION_LOADS[k][1](v) for k, v in x.items()),
        "a table with any of traction, pressure (lists of { on = <part of the foundation>, value = … }, as "
        "in [loads]) and body_force = [f1, f2, f3] (per unit volume): the foundation's own loads, the same "
        "in every load case"),
    "partner": ("auto", _oneof("auto", "point", "average"),
                "'point' (a contact node's partner is the point of the top face directly below it: exact "
                "node-to-node coupling on matching meshes), 'average' (the mean of the foundation's "
                "displacement over the node's tributary area: a foundation finer than the body then "
                "converges; linear body elements only) or 'auto' ('point' where every partner is a node of "
                "the top face or the body's faces are quadratic, else 'average')"),
    "tolerance": (1e-3, lambda x: _pos(x) and x < 0.5,
                  "a number in (0, 0.5) (geometric tolerance of the checks of the foundation's mesh, "
                  "relative to its median boundary edge length)"),
}

# [obstacle]: optional — absent, the rigid counterpart is the plane x3 = 0, fixed (docs/obstacles.md)
OBSTACLE = {
    "shape": ("plane", _oneof("plane", "sphere", "cylinder", "surface"),
              "'plane' (x3 = 0), 'sphere' (center, radius), 'cylinder' (point, axis, radius) or 'surface' "
              "(mesh): the rigid obstacle the contact face touches"),
    "center": ([0.0, 0.0, 0.0], _vec3, "[x1, x2, x3]: the sphere's center"),
    "radius": (0.0, _nonneg, "a number > 0: the sphere's or cylinder's radius"),
    "point": ([0.0, 0.0, 0.0], _vec3, "[x1, x2, x3]: a point on the cylinder's axis"),
    "axis": ([1.0, 0.0, 0.0], lambda x: _vec3(x) and any(v != 0 for v in x),
             "[a1, a2, a3] ≠ 0: the direction of the cylinder's axis"),
    "mesh": ("", lambda x: isinstance(x, str),
             "shape = 'surface': a closed triangulated surface (STL, or any surface meshio reads), relative "
             "to this file; the solid it bounds is the obstacle"),
    "control": ("fixed", _oneof("fixed", "displacement", "force"),
                "'fixed', 'displacement' (the obstacle moved by the rigid translation `displacement`) or "
                "'force' (pressed by the resultant `force`: it translates along the force, its translation an "
                "unknown of the state; condensation path)"),
    "displacement": ([0.0, 0.0, 0.0], _vec3,
                     "control = 'displacement': the obstacle's rigid translation [d1, d2, d3] (it enters the "
                     "gap of contact node m as −d·n_m)"),
    "force": ([0.0, 0.0, 0.0], _vec3, "control = 'force': the resultant [f1, f2, f3] the obstacle exerts on the "
              "body"),
}

TOP_LEVEL = {"name": ("custom", lambda x: isinstance(x, str) and x != "", "a non-empty string"),
             "description": ("", lambda x: isinstance(x, str), "a string")}


@dataclass
class Config:
    """A validated configuration; ``data`` is the resolved nested dict, ``source`` where it came from."""

    data: dict
    source: str = "<dict>"

    def __getitem__(self, key):
        return self.data[key]

    @property
    def name(self) -> str:
        return self.data["name"]

    def with_updates(self, updates: dict) -> "Config":
        """A new validated Config with nested keys of ``updates`` replaced."""
        merged = copy.deepcopy(self.data)
        for sec, vals in updates.items():
            if isinstance(vals, dict) and isinstance(merged.get(sec), dict):
                merged[sec].update(copy.deepcopy(vals))
            else:
                merged[sec] = copy.deepcopy(vals)
        return validate(merged, self.source)

    def to_toml(self) -> str:
        import tomli_w
        return tomli_w.dumps(self.data)


def _check_target(target, d1d2, problems, key="objective.target"):
    n0 = len(problems)
    _check_target_at(target, d1d2, problems)
    if key != "objective.target":
        problems[n0:] = [p.replace("objective.target", key, 1) for p in problems[n0:]]


def _check_target_at(target, d1d2, problems):
    kind = target.get("kind")
    allowed = {"constant": {"kind", "value"},
               "step": {"kind", "default", "regions", "per_area"},
               "values": {"kind", "values"},
               "design": {"kind", "alpha"}}
    if kind not in allowed:
        problems.append(f"objective.target.kind = {kind!r}: must be one of {sorted(allowed)}")
        return
    for k in set(target) - allowed[kind]:
        problems.append(f"objective.target.{k}: unknown key for kind {kind!r} (allowed: {sorted(allowed[kind])})")
    if kind == "constant" and not _finite(target.get("value", 0.0)):
        problems.append("objective.target.value: must be a finite number")
    if kind == "step":
        if not _finite(target.get("default", 0.0)):
            problems.append("objective.target.default: must be a finite number")
        if not isinstance(target.get("per_area", False), bool):
            problems.append("objective.target.per_area: must be true or false")
        regions = target.get("regions", [])
        if not isinstance(regions, list):
            problems.append("objective.target.regions: must be a list of tables {x1=[lo,hi], x2=[lo,hi], value}")
            regions = []
        for n, r in enumerate(regions):
            if not isinstance(r, dict) or set(r) - {"x1", "x2", "value"} or "value" not in r:
                problems.append(f"objective.target.regions[{n}]: must be a table with keys x1, x2 (optional) and value")
                continue
            for ax in ("x1", "x2"):
                iv = r.get(ax, [-math.inf, math.inf])
                if not (isinstance(iv, list) and len(iv) == 2 and all(isinstance(v, _NUM) for v in iv) and iv[0] <= iv[1]):
                    problems.append(f"objective.target.regions[{n}].{ax}: must be [lo, hi] with lo ≤ hi")
            if not _finite(r["value"]):
                problems.append(f"objective.target.regions[{n}].value: must be a finite number")
    if kind == "values":
        vals = target.get("values")
        if not (isinstance(vals, list) and all(_finite(v) for v in vals)):
            problems.append("objective.target.values: must be a list of numbers, one per contact node")
    if kind == "design":
        _check_matrix(target.get("alpha"), d1d2, "objective.target.alpha", problems)


def _check_matrix(value, d1d2, key, problems):
    if d1d2 is None:
        return
    n1, n2 = d1d2[0] + 1, d1d2[1] + 1
    if _finite(value):
        return
    ok = (isinstance(value, list) and len(value) == n1
          and all(isinstance(r, list) and len(r) == n2 and all(_finite(v) for v in r) for r in value))
    if not ok:
        problems.append(f"{key}: must be a number or a {n1}×{n2} nested list of numbers")


def _check_design_constraints(dsg, d1d2, problems):
    """[design] fixed inside the control net, [[design.linear]] coefficients of its shape."""
    if d1d2 is None:
        return
    n1, n2 = d1d2[0] + 1, d1d2[1] + 1
    fixed = dsg.get("fixed")
    if isinstance(fixed, list):
        for p in fixed:
            if isinstance(p, list) and len(p) == 2 and not (0 <= p[0] < n1 and 0 <= p[1] < n2):
                problems.append(f"design.fixed: control point {p} is outside the {n1}×{n2} control net "
                                f"(i in 0..{n1 - 1}, j in 0..{n2 - 1})")
    rows = dsg.get("linear")
    if isinstance(rows, list):
        for k, r in enumerate(rows):
            if isinstance(r, dict) and "coefficients" in r:
                c = r["coefficients"]
                if _finite(c) or not (isinstance(c, list) and len(c) == n1 and all(
                        isinstance(v, list) and len(v) == n2 and all(_finite(t) for t in v) for v in c)):
                    problems.append(f"design.linear[{k}].coefficients: must be a {n1}×{n2} nested list of numbers "
                                    "(one per control point, like design.initial)")


BLOCK_LOADS = ("top_traction", "right_traction")
CASE_NAME = re.compile(r"[A-Za-z0-9_.+-]+")


def _check_load_cases(cases, d1d2, problems) -> list:
    """[[load_cases]]: each a name, loads in the form of [loads] (none required) and an optional
    target in the form of objective.target. Returns the cases as written (validated)."""
    if not (isinstance(cases, list) and cases and all(isinstance(c, dict) for c in cases)):
        problems.append("load_cases: must be a non-empty array of tables [[load_cases]] with a name, "
                        "loads as in [loads] and an optional target")
        return []
    allowed = ["name", *SCHEMA["loads"], "target", "steps"]
    _check_named_loads(cases, "load_cases", allowed, "case", "the case's history column and plots", problems)
    for n, case in enumerate(cases):
        if "steps" in case:
            case["steps"] = _check_load_steps(case["steps"], f"load_cases[{n}].steps", problems)
        if "target" in case:
            if isinstance(case["target"], dict):
                _check_target(case["target"], d1d2, problems, f"load_cases[{n}].target")
            else:
                problems.append(f"load_cases[{n}].target: must be a table like objective.target")
    return cases


def _check_named_loads(items, where, allowed, what, names_what, problems) -> None:
    """Load cases or load steps: each a unique name and loads in the form of [loads] (plus the
    keys ``allowed``); every problem appended to ``problems``."""
    seen = set()
    for n, item in enumerate(items):
        name = item.get("name")
        if not (isinstance(name, str) and CASE_NAME.fullmatch(name)):
            problems.append(f"{where}[{n}].name = {name!r}: must be a name of letters, digits and _ . + - "
                            f"(it names {names_what})")
        elif name in seen:
            problems.append(f"{where}[{n}].name = {name!r}: another {what} has this name")
        seen.add(name)
        for k, val in item.items():
            if k not in allowed:
                problems.append(f"{where}[{n}].{k}: unknown key (allowed: {', '.join(allowed)})")
            elif k in SCHEMA["loads"]:
                _, check, desc = SCHEMA["loads"][k]
                if not check(val):
                    problems.append(f"{where}[{n}].{k} = {val!r}: must be {desc}")


def _check_load_steps(steps, where, problems) -> list:
    """[[load_steps]] (or a case's [[load_cases.steps]]): in order, each a name, the TOTAL loads at
    its end in the form of [loads] and an optional ``substeps`` ≥ 1. Returns them with substeps."""
    if not (isinstance(steps, list) and steps and all(isinstance(c, dict) for c in steps)):
        problems.append(f"{where}: must be a non-empty array of tables with a name, loads as in [loads] "
                        "and an optional substeps")
        return []
    allowed = ["name", *SCHEMA["loads"], "substeps"]
    _check_named_loads(steps, where, allowed, "step", "the step's output directory", problems)
    for n, step in enumerate(steps):
        sub = step.setdefault("substeps", 1)
        if not _posint(sub):
            problems.append(f"{where}[{n}].substeps = {sub!r}: must be an integer ≥ 1 (equal increments of "
                            "the loads from the previous step's)")
    return steps


def _check_step_names(data, problems, obstacle=None) -> None:
    """objective.steps names steps of every path; steps at the top level and in cases exclude each
    other; a force-controlled ``obstacle`` (the raw [obstacle] table) takes no steps."""
    cases = data.get("load_cases", [])
    if "load_steps" in data and any("steps" in c for c in cases):
        problems.append("load_steps: the configuration has [[load_steps]] and [[load_cases.steps]]; give each "
                        "load case its own steps, or the top-level steps without steps in the cases")
    if "load_steps" in data or any("steps" in c for c in cases):
        if isinstance(obstacle, dict) and obstacle.get("control") == "force":
            problems.append("load_steps: a load path is not yet taken with a force-controlled [obstacle] (its "
                            "translation would be an unknown of every step); use obstacle.control = 'fixed' or "
                            "'displacement'")
    chosen = data["objective"]["steps"]
    if not isinstance(chosen, list):
        return
    paths = [("load_steps", data.get("load_steps"))] if "load_steps" in data else []
    paths += [(f"load_cases[{n}].steps", c.get("steps")) for n, c in enumerate(cases) if "steps" in c]
    if not paths:
        problems.append(f"objective.steps = {chosen!r}: names load steps, but the configuration has no "
                        "[[load_steps]]")
    for where, steps in paths:
        names = [s.get("name") for s in steps or []]
        for v in chosen:
            if v not in names:
                problems.append(f"objective.steps: {v!r} is no step of {where} (steps: "
                                f"{', '.join(map(str, names))})")


def _check_combination(raw, data, problems):
    """objective.combine/weights name the load cases; without cases only the default max is allowed."""
    obj, cases = data["objective"], data.get("load_cases", [])
    names = [c.get("name") for c in cases]
    weights = obj["weights"]
    if not cases:
        if obj["combine"] != "max":
            problems.append(f"objective.combine = {obj['combine']!r}: combines load cases, but the "
                            "configuration has no [[load_cases]]")
        if weights:
            problems.append("objective.weights: weighs load cases, but the configuration has no [[load_cases]]")
    elif isinstance(weights, list) and weights and len(weights) != len(cases):
        problems.append(f"objective.weights: has {len(weights)} number(s) for {len(cases)} load cases "
                        f"({', '.join(map(str, names))})")
    elif isinstance(weights, dict):
        for k in weights:
            if k not in names:
                problems.append(f"objective.weights.{k}: no load case has this name "
                                f"(cases: {', '.join(map(str, names))})")
    w = list(weights.values()) if isinstance(weights, dict) else weights
    if cases and w and all(_nonneg(v) for v in w) and not any(v > 0 for v in w) and (
            isinstance(weights, list) or len(weights) == len(cases)):
        problems.append("objective.weights: at least one load case must weigh more than 0")
    has_target = obj["type"] == "target_normal_force" or any(
        isinstance(t, dict) and t.get("type") == "target_normal_force" for t in obj.get("terms") or [])
    if any("target" in c for c in cases) and not has_target:
        problems.append(f"load_cases: a case's target is the target of objective.type = "
                        f"'target_normal_force', not {obj['type']!r}")


TERM_KEYS = {"type", "weight", "region", "aggregate", "rho", "p", "target"}


def _check_objective(raw, data, d1d2, problems):
    """[[objective.terms]]: each a known type with its weight and keys (defaults filled in); with
    terms the type is 'sum' (implied), and 'sum' needs terms."""
    obj = data["objective"]
    given = raw.get("objective", {}) if isinstance(raw.get("objective"), dict) else {}
    terms = obj["terms"] if isinstance(obj["terms"], list) else []
    if terms and "type" not in given:
        obj["type"] = "sum"
    if terms and obj["type"] != "sum":
        problems.append(f"objective.type = {obj['type']!r}: with [[objective.terms]] the objective is their "
                        "weighted sum (write type = 'sum' or leave it out)")
    if obj["type"] == "sum" and not terms:
        problems.append("objective.type = 'sum': needs [[objective.terms]]")
    out = []
    for n, t in enumerate(terms):
        key = f"objective.terms[{n}]"
        for k in t:
            if k not in TERM_KEYS:
                problems.append(f"{key}.{k}: unknown key (allowed: {', '.join(sorted(TERM_KEYS))})")
        if t.get("type") not in OBJECTIVE_TYPES:
            problems.append(f"{key}.type = {t.get('type')!r}: must be one of "
                            f"{', '.join(repr(v) for v in OBJECTIVE_TYPES)}")
        term = {"type": t.get("type")}
        for k in ("weight", "region", "aggregate", "rho", "p"):
            default, check, desc = (1.0, _nonneg, "a number ≥ 0") if k == "weight" else SCHEMA["objective"][k]
            val = t.get(k, default)
            _check_value(f"{key}.{k}", val, check, desc, problems)
            term[k] = float(val) if isinstance(val, int) and not isinstance(val, bool) and k != "region" else val
        if "target" in t:
            if t.get("type") != "target_normal_force":
                problems.append(f"{key}.target: only a target_normal_force term has a target")
            elif isinstance(t["target"], dict):
                _check_target(t["target"], d1d2, problems, key=f"{key}.target")
            else:
                problems.append(f"{key}.target: must be a table like objective.target")
            term["target"] = t["target"]
        elif t.get("type") == "target_normal_force":
            term["target"] = {"kind": "constant", "value": 0.0}
        out.append(term)
    if terms and not any(_nonneg(t["weight"]) and t["weight"] > 0 for t in out):
        problems.append("objective.terms: at least one term must weigh more than 0")
    obj["terms"] = out if terms else obj["terms"]


def _check_body(raw, data, problems):
    """A body from a file has no [geometry]/[mesh] and no block loads; on the block, a configuration
    that lists its own tractions or pressures gets no default block loads."""
    loads_raw = raw.get("loads", {}) if isinstance(raw.get("loads"), dict) else {}
    if data["body"]["mesh"]:
        path = Path(data["body"]["mesh"])
        if not path.is_file():
            problems.append(f"body.mesh = {data['body']['mesh']!r}: no such file")
        for sec in ("geometry", "mesh"):
            if sec in raw:
                problems.append(f"[{sec}]: describes the built-in block; with body.mesh the body comes from the "
                                f"mesh file (remove [{sec}])")
            data.pop(sec, None)
        for k in BLOCK_LOADS:
            if k in loads_raw:
                problems.append(f"loads.{k}: is a load on a part of the built-in block; on a body from a file "
                                "use [[loads.traction]] with on = \"<part>\"")
            data["loads"].pop(k, None)
            for n, case in enumerate(data.get("load_cases", [])):
                if k in case:
                    problems.append(f"load_cases[{n}].{k}: is a load on a part of the built-in block; on a "
                                    "body from a file use traction = [{ on = \"<part>\", value = [...] }]")
            for n, step in enumerate(data.get("load_steps", [])):
                if k in step:
                    problems.append(f"load_steps[{n}].{k}: is a load on a part of the built-in block; on a "
                                    "body from a file use traction = [{ on = \"<part>\", value = [...] }]")
    elif ("traction" in loads_raw or "pressure" in loads_raw or data.get("load_cases")
          or data.get("load_steps")):
        # with load cases a case's loads are exactly [loads] as written plus the case's own
        for k in BLOCK_LOADS:
            if k not in loads_raw:
                data["loads"][k] = [0.0, 0.0, 0.0]


def _check_graded_block(raw, data, problems) -> None:
    """[mesh] x1/x2/x3: node coordinates from 0 to a/b/c, strictly increasing, instead of nx/ny/nz.
    A coordinate list sets its side of the block when [geometry] does not (and must end on it when
    it does); the resolved configuration keeps either the list or the count of a direction."""
    m, g = data["mesh"], data["geometry"]
    raw_m = raw.get("mesh", {}) if isinstance(raw.get("mesh"), dict) else {}
    raw_g = raw.get("geometry", {}) if isinstance(raw.get("geometry"), dict) else {}
    for ax, n, side in (("x1", "nx", "a"), ("x2", "ny", "b"), ("x3", "nz", "c")):
        x = m[ax]
        if x == []:
            m.pop(ax)            # equal elements: the resolved configuration keeps the count alone
            continue
        if not _axis(x):
            continue
        if n in raw_m:
            problems.append(f"mesh.{ax} and mesh.{n}: give the node coordinates or the number of elements "
                            f"in {ax}, not both")
        m.pop(n, None)
        m[ax] = x = [float(v) for v in x]
        drops = [k for k in range(1, len(x)) if not x[k] > x[k - 1]]
        if drops:
            k = drops[0]
            problems.append(f"mesh.{ax} = {x}: must be strictly increasing ({ax}[{k}] = {x[k]:g} ≤ "
                            f"{ax}[{k - 1}] = {x[k - 1]:g}; {len(drops)} such step(s))")
            continue
        if x[0] != 0.0:
            problems.append(f"mesh.{ax} = {x}: must start at 0 (the block is [0, a]×[0, b]×[0, c], its contact "
                            "face on x3 = 0)")
            continue
        if side in raw_g:
            if _pos(g[side]) and not math.isclose(x[-1], g[side], rel_tol=1e-12):
                problems.append(f"mesh.{ax} ends at {x[-1]:g}, geometry.{side} = {g[side]:g}: the coordinates "
                                f"run from 0 to geometry.{side} (or leave geometry.{side} out: the last "
                                "coordinate sets it)")
        else:
            g[side] = x[-1]


def _check_foundation(given, data, problems) -> dict:
    """[foundation]: exactly one of `mesh` and `block`; the material's missing keys are the body's."""
    if not isinstance(given, dict):
        problems.append("[foundation]: must be a table")
        return {}
    out = _check_table(given, FOUNDATION, "foundation", problems)
    if isinstance(out["mesh"], str) and isinstance(out["block"], dict):
        if bool(out["mesh"]) == bool(out["block"]):
            problems.append("[foundation]: give exactly one of `mesh` (a mesh file) and `block` (a generated box)")
        elif out["mesh"] and not Path(out["mesh"]).is_file():
            problems.append(f"foundation.mesh = {out['mesh']!r}: no such file")
    if isinstance(out["block"], dict) and out["block"] and _block_spec(out["block"]):
        b = out["block"]
        out["block"] = {"size": [float(v) for v in b["size"]], "cells": list(b["cells"]),
                        "origin": [float(v) for v in b.get("origin", [0.0, 0.0])],
                        "element": b.get("element", "hexahedron")}
    if isinstance(out["loads"], dict):
        out["loads"] = {**{k: copy.deepcopy(v[0]) for k, v in FOUNDATION_LOADS.items()}, **out["loads"]}
    if isinstance(out["material"], dict) and _material_spec(out["material"]):
        out["material"] = {k: float(out["material"].get(k, data["material"][k])) for k in ("E", "nu")}
    return out


def _check_obstacle(given, data, problems) -> dict:
    """[obstacle]: the keys its shape needs; excludes [foundation]."""
    if not isinstance(given, dict):
        problems.append("[obstacle]: must be a table")
        return {}
    out = _check_table(given, OBSTACLE, "obstacle", problems)
    shape = out["shape"]
    need = {"sphere": ("center", "radius"), "cylinder": ("point", "axis", "radius"), "surface": ("mesh",)}
    for k in need.get(shape, ()):
        if k not in given:
            problems.append(f"obstacle.{k}: required with shape = {shape!r}")
    if shape in ("sphere", "cylinder") and "radius" in given and _nonneg(out["radius"]) and not out["radius"] > 0:
        problems.append(f"obstacle.radius = {out['radius']!r}: must be > 0")
    if shape == "surface" and out["mesh"] and isinstance(out["mesh"], str) and not Path(out["mesh"]).is_file():
        problems.append(f"obstacle.mesh = {out['mesh']!r}: no such file")
    if out["control"] == "force" and _vec3(out["force"]) and not any(v != 0 for v in out["force"]):
        problems.append("obstacle.force = [0, 0, 0]: with control = 'force' the obstacle translates along the "
                        "force, which has no direction (a force with no component along any free direction)")
    obj = data.get("objective", {})
    types = [obj.get("type")] + [t.get("type") for t in obj.get("terms") or [] if isinstance(t, dict)]
    moves = out["control"] == "force" or (out["control"] == "displacement" and _vec3(out["displacement"])
                                          and any(out["displacement"][:2]))
    if "frictional_dissipation" in types and (shape != "plane" or moves):
        problems.append(f"objective 'frictional_dissipation' with obstacle.shape = {shape!r}, control = "
                        f"{out['control']!r}: the objective takes the slip as the body's own (x1, x2) "
                        "displacement, which holds on the fixed plane only")
    if "foundation" in data:
        problems.append("[obstacle] and [foundation] exclude each other: the body touches either a rigid "
                        "obstacle or an elastic foundation")
    for k in ("center", "point", "axis", "displacement", "force"):
        if _vec3(out[k]):
            out[k] = [float(v) for v in out[k]]
    return out


# the former [linear_solver] backend: its value as (path, library); None keeps the key's own value
LEGACY_BACKEND = {"auto": (None, None), "pardiso": ("condensation", "pardiso"),
                  "scipy": ("condensation", "scipy"), "delassus": ("delassus", None),
                  "amg": ("fullspace", None)}


def _legacy_backend(raw: dict, source: str, problems: list) -> dict:
    """``[linear_solver] backend`` (deprecated) read as the keys ``path`` and ``library`` that
    replaced it, with a warning naming them; it overrides them when both are given."""
    ls = raw.get("linear_solver")
    if not isinstance(ls, dict) or "backend" not in ls:
        return raw
    value = ls["backend"]
    new = {k: v for k, v in ls.items() if k != "backend"}
    if value not in LEGACY_BACKEND:
        problems.append(f"linear_solver.backend = {value!r}: must be one of "
                        f"{', '.join(repr(v) for v in LEGACY_BACKEND)} (a deprecated key: write "
                        "linear_solver.path and linear_solver.library instead)")
        return {**raw, "linear_solver": new}
    path, library = LEGACY_BACKEND[value]
    new.update({k: v for k, v in (("path", path), ("library", library)) if v is not None})
    spelled = ", ".join(f"{k} = {new[k]!r}" for k in ("path", "library") if k in new) or "path = 'auto'"
    log.warning("%s: [linear_solver] backend = %r is deprecated; write %s instead", source, value, spelled)
    return {**raw, "linear_solver": new}


def _check_value(key: str, val, check, desc: str, problems: list) -> None:
    """Append ``"key = val: must be desc"`` to ``problems`` when ``check(val)`` fails or raises."""
    try:
        ok = check(val)
    except Exception:
        ok = False
    if not ok:
        problems.append(f"{key} = {val!r}: must be {desc}")


def _check_table(given: dict, keys: dict, sec: str, problems: list) -> dict:
    """The keys of table ``sec`` with their defaults filled in; unknown keys and values that fail
    their check are appended to ``problems`` (an integer where a float is expected becomes one)."""
    for k in given:
        if k not in keys:
            problems.append(f"{sec}.{k}: unknown key (allowed: {', '.join(keys)})")
    out = {}
    for k, (default, check, desc) in keys.items():
        val = given.get(k, copy.deepcopy(default))
        _check_value(f"{sec}.{k}", val, check, desc, problems)
        out[k] = float(val) if isinstance(val, int) and isinstance(default, float) and not isinstance(val, bool) else val
    return out


def validate(raw: dict, source: str = "<dict>") -> Config:
    """Fill defaults and check every key; raise ConfigError listing all problems at once."""
    if not isinstance(raw, dict):
        raise ConfigError([f"{source}: the configuration must be a table"])
    problems = []
    data = {}
    for key in raw:
        if key not in SCHEMA and key not in TOP_LEVEL and key not in ("load_cases", "foundation", "obstacle",
                                                                   "load_steps"):
            problems.append(f"{key}: unknown section (allowed: "
                            f"{', '.join(list(TOP_LEVEL) + list(SCHEMA) + ['foundation', 'obstacle', 'load_cases', 'load_steps'])})")
    for key, (default, check, desc) in TOP_LEVEL.items():
        val = raw.get(key, default)
        if not check(val):
            problems.append(f"{key} = {val!r}: must be {desc}")
        data[key] = val
    raw = _legacy_backend(raw, source, problems)
    for sec, keys in SCHEMA.items():
        given = raw.get(sec, {})
        if not isinstance(given, dict):
            problems.append(f"[{sec}]: must be a table")
            given = {}
        data[sec] = _check_table(given, keys, sec, problems)
    if not (isinstance(raw.get("material"), dict) and "formulation" in raw["material"]):
        # absent means 'auto': a configuration that does not name it resolves as it did before the key
        data["material"].pop("formulation", None)
    deg = data["design"]["degree"]
    d1d2 = deg if isinstance(deg, list) and len(deg) == 2 and all(_posint(v) for v in deg) else None
    _check_matrix(data["design"]["initial"], d1d2, "design.initial", problems)
    _check_design_constraints(data["design"], d1d2, problems)
    if isinstance(data["objective"]["target"], dict):
        _check_target(data["objective"]["target"], d1d2, problems)
    if "load_cases" in raw:
        data["load_cases"] = _check_load_cases(raw["load_cases"], d1d2, problems)
    _check_objective(raw, data, d1d2, problems)
    if "load_steps" in raw:
        data["load_steps"] = _check_load_steps(raw["load_steps"], "load_steps", problems)
    _check_step_names(data, problems, obstacle=raw.get("obstacle"))
    _check_combination(raw, data, problems)
    _check_body(raw, data, problems)
    if "foundation" in raw:
        data["foundation"] = _check_foundation(raw["foundation"], data, problems)
    if "obstacle" in raw:
        data["obstacle"] = _check_obstacle(raw["obstacle"], data, problems)
    if "mesh" in data:
        _check_graded_block(raw, data, problems)
    dsg = data["design"]
    if _finite(dsg["lower"]) and _pos(dsg["C0"]) and dsg["lower"] > dsg["C0"]:
        problems.append(f"design.lower = {dsg['lower']}: must be ≤ design.C0 = {dsg['C0']} (the control "
                        "points' lower bound above their upper bound leaves no admissible design)")
    if "geometry" in data:
        g = data["geometry"]
        if _pos(g["c"]) and _pos(data["design"]["C0"]) and data["design"]["C0"] >= g["c"]:
            problems.append(f"design.C0 = {data['design']['C0']}: must be < geometry.c = {g['c']} "
                            "(a surface reaching the top face inverts the mesh)")
    if problems:
        raise ConfigError([f"{source}: {p}" for p in problems])
    return Config(data, source)


SECTION_DOCS = {
    "body": "The body: a mesh file with named parts, or (no `mesh`) the paper's block of [geometry] and [mesh]. "
            "Parts are group names of the file (Gmsh physical groups, meshio cell/point sets; the block has "
            "`clamped`, `top`, `right`, `front`, `back`, `contact`) or predicate tables on the reference "
            "coordinates, `{ x1 = 0.0 }` or `{ box = [[x1lo, x1hi], [x2lo, x2hi], [x3lo, x3hi]] }`.",
    "geometry": "The built-in block [0,a]×[0,b]×[0,c] (only without `body.mesh`).",
    "mesh": "Elements of the built-in block per direction (only without `body.mesh`): `nx`, `ny`, `nz` equal "
            "elements, or a graded block with the node coordinates `x1`, `x2`, `x3` of a direction instead of its "
            "count (e.g. `x3 = [0.0, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0]`, fine at the contact face).",
    "material": "Isotropic linear elasticity.",
    "friction": "Coulomb friction between the body and the foundation (the rigid x3 ≤ 0, or [foundation]).",
    "loads": "Loads on parts of the body, integrated on the current (designed) geometry.",
    "design": "The Bézier contact surface ϑ_α and the admissible set U of its control points (paper §5.2).",
    "objective": "The cost functional J(α, y) of the state.",
    "state": "The discrete Coulomb contact problem and its solver.",
    "linear_solver": "The solver path of the state and adjoint, and its sparse direct solver.",
    "optimizer": "The bundle-trust method.",
}


def reference_markdown() -> str:
    """The configuration reference (docs/configuration.md): every key with its default and meaning."""
    import tomli_w
    lines = ["# Configuration reference", "",
             "A configuration is a TOML file (or a built-in example: `example1`, `example2`, `example3`).",
             "Every key is optional; the whole file is validated up front and every problem is listed at",
             "once. This page is generated from the schema in `src/contactopt/config.py`",
             "(`python -m contactopt.config > docs/configuration.md`).", "",
             "| key | default | meaning |", "|---|---|---|"]
    for key, (default, _, desc) in TOP_LEVEL.items():
        lines.append(f"| `{key}` | `{default!r}` | {desc} |")
    for sec, keys in SCHEMA.items():
        lines += ["", f"## [{sec}]", "", SECTION_DOCS.get(sec, ""), "", "| key | default | meaning |", "|---|---|---|"]
        for k, (default, _, desc) in keys.items():
            shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip() if default != [] else "[]"
            text = desc.replace("|", "\\|")
            lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [foundation]", "",
              "Optional: an elastic foundation under the body (docs/foundation.md). Absent, the foundation is "
              "the rigid half-space x3 ≤ 0. Its top face lies on x3 = 0 under the contact face; each contact "
              "node has a partner on that face (`partner`). Runs on the condensation path.",
              "", "| key | default | meaning |", "|---|---|---|"]
    for k, (default, _, desc) in FOUNDATION.items():
        shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip() if default not in ([], {}) else repr(default)
        text = desc.replace("|", "\\|")
        lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [obstacle]", "",
              "Optional: a rigid obstacle of any shape (docs/obstacles.md). Absent, it is the plane x3 = 0, "
              "fixed. Each contact node gets a frame (t1, t2, n) from the obstacle at its closest point; the "
              "gap and the Coulomb law act in that frame. A shape other than the plane runs on the "
              "condensation path; excludes [foundation].",
              "", "| key | default | meaning |", "|---|---|---|"]
    for k, (default, _, desc) in OBSTACLE.items():
        shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip()
        text = desc.replace("|", "\\|")
        lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [[load_cases]]", "",
              "Optional named load cases (an array of tables). Each has a `name` (letters, digits, `_ . + -`), "
              "any of the keys of [loads] (none required) and optionally a `target` in the form of "
              "`objective.target`. A case's loads are its own plus those written in [loads] (with cases, "
              "the block's default `top_traction`/`right_traction` are off unless [loads] writes them). "
              "`objective.combine` joins the cases' objectives: the max (worst case) or the weighted sum. "
              "A case may have its own load path, `[[load_cases.steps]]` in the form of [[load_steps]].",
              "", "## [[load_steps]]", "",
              "Optional load path (an array of tables, in order; docs/load_paths.md): quasi-static steps, each "
              "with a `name`, the TOTAL loads at its end in the keys of [loads] ([loads] adds to every step) and "
              "`substeps` (default 1: equal increments, linear in the loads, from the previous step's loads). "
              "Coulomb's law acts on the slip of each step. `objective.steps` says which steps Θ is taken on. "
              "Without steps the problem is one step, the static problem."]
    return "\n".join(lines) + "\n"


def load_config(path_or_name) -> Config:
    """Load a TOML file or a built-in example (``example1``, ``example2``, ``example3``)."""
    if isinstance(path_or_name, Config):
        return path_or_name
    if isinstance(path_or_name, dict):
        return validate(path_or_name)
    name = str(path_or_name)
    if name in EXAMPLES:
        text = resources.files("contactopt").joinpath("examples", f"{name}.toml").read_text()
        source = f"built-in {name}"
    else:
        p = Path(name)
        if not p.exists():
            raise ConfigError([f"{name}: no such file, and not a built-in example ({', '.join(EXAMPLES)})"])
        if p.is_dir():
            raise ConfigError([f"{name}: is a directory, expected a TOML file"])
        text = p.read_text()
        source = str(p)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{source}: not valid TOML: {exc}"]) from None
    body = raw.get("body")
    if name not in EXAMPLES and isinstance(body, dict) and isinstance(body.get("mesh"), str) and body["mesh"]:
        # a mesh path is relative to the TOML file; the resolved configuration keeps it absolute
        body["mesh"] = str((Path(name).parent / body["mesh"]).resolve())
    obst = raw.get("obstacle")
    if name not in EXAMPLES and isinstance(obst, dict) and isinstance(obst.get("mesh"), str) and obst["mesh"]:
        obst["mesh"] = str((Path(name).parent / obst["mesh"]).resolve())
    found = raw.get("foundation")
    if name not in EXAMPLES and isinstance(found, dict) and isinstance(found.get("mesh"), str) and found["mesh"]:
        found["mesh"] = str((Path(name).parent / found["mesh"]).resolve())
    return validate(raw, source)


if __name__ == "__main__":          # python -m contactopt.config > docs/configuration.md
    print(reference_markdown(), end="")
