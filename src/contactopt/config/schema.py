"""The schema of a configuration: every section and key with its default, its check and a
description of its allowed values. The one place where a default is written: the typed
sections (:mod:`.sections`) and the JSON Schema (:mod:`.json_schema`) are derived from it."""

from __future__ import annotations

import re

from .checks import (
                     _axis,
                     _block_spec,
                     _clamp_spec,
                     _finite,
                     _load_list,
                     _material_spec,
                     _natint,
                     _nonneg,
                     _oneof,
                     _part_spec,
                     _part_specs,
                     _pos,
                     _posint,
                     _unit3,
                     _vec3,
)

EXAMPLES = ("example1", "example2", "example3")

OBJECTIVE_TYPES = ("target_normal_force", "compliance", "pressure_uniformity", "max_pressure",
                   "frictional_dissipation", "peak_stress")
_PART_SHORT = "a part (a group name or a predicate table)"
_PART = "a part: a group name such as \"bottom\", or a predicate table such as { x1 = 0.0 } or { box = [[x1lo, x1hi], [x2lo, x2hi], [x3lo, x3hi]] }"

# section -> key -> (default, check, description of the allowed values)
SCHEMA = {
    "body": {
        "mesh": ("", lambda x: isinstance(x, str),
                 "a path to a mesh file (Gmsh .msh, .vtu, .inp, … read by meshio), relative to this file; "
                 "empty: the block of [geometry] and [mesh]"),
        "clamped": ("clamped", _clamp_spec,
                    _PART + "; or { on = <part>, components = [1, 3] } to fix some components; or a list of these. "
                    "On the contact face a clamped u1 or u2 (a symmetry plane) keeps the node a contact node "
                    "with friction in its free direction; a clamped u3 takes it out of the contact set. [] or "
                    "clamps that leave rigid motions free: the contact holds them (the condensation, "
                    "full-space and PETSc paths; not the Delassus path)"),
        "contact": ("contact", _part_specs, _PART + " (the designed contact face, on x3 = 0 in the mesh)"),
        "fixed_shape": ("auto", lambda x: x == "auto" or (isinstance(x, list) and all(_part_spec(v) for v in x)),
                        "'auto' (the named parts that share no node with the contact face) or a list of parts "
                        "whose shape the morph keeps"),
        "tolerance": (1e-3, lambda x: _pos(x) and x < 0.5,
                      "a number in (0, 0.5) (geometric tolerance of plane and predicate checks, relative to the "
                      "median boundary edge length)"),
        "min_jacobian_ratio": (0.1, lambda x: _finite(x) and 0 < x < 1,
                               "a number in (0, 1) (smallest det J(α)/det J_ref accepted at a quadrature point)"),
        "initial_gap": ("zero", _oneof("zero", "mesh"),
                        "'zero' (the contact face lies on the plane x3 = 0, the foundation plane where there is no "
                        "[obstacle] or [foundation]: the gap there is ϑ_α) or 'mesh' "
                        "(the contact face may lie above it, e.g. an exported optimal body: the gap is its "
                        "height x3 in the mesh plus ϑ_α)"),
        "graph_tolerance": (0.0, lambda x: _nonneg(x) and x < 0.5,
                            "a number in [0, 0.5): two nodes of the contact face closer than this (relative to "
                            "the median boundary edge length) in chart coordinates make it no graph over its "
                            "chart, and a face within it of a plane or cylinder is that plane or cylinder; 0: "
                            "body.tolerance"),
        "penetration_tolerance": (0.0, lambda x: _nonneg(x) and x < 0.5,
                                  "a number in [0, 0.5): how deep (relative to the median boundary edge length) a "
                                  "node of the body may lie inside the counterpart in the reference mesh without "
                                  "body.interference; 0: body.tolerance"),
        "interference": (False, lambda x: isinstance(x, bool),
                         "true or false: allow the contact face to overlap its counterpart in the reference mesh "
                         "(a negative initial gap: press and shrink fits); false refuses an overlap deeper than "
                         "the penetration tolerance, naming the nodes"),
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
        "formulation": ("auto", _oneof("auto", "standard", "bbar"),
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
        "degree": ([7, 3], lambda x: isinstance(x, list) and len(x) == 2 and all(_natint(v) for v in x),
                   "a list of 2 integers ≥ 0 (Bézier degrees d1, d2 along the chart's directions ξ1, ξ2; 0: "
                   "a profile along the other direction only)"),
        "C0": (0.75, _pos, "a number > 0 (upper bound of the control points)"),
        "lower": (0.0, _finite, "a number ≤ C0 (lower bound of the control points; 0 is the paper's U, a negative "
                  "bound admits crowned faces such as a paraboloid, whose Bézier net dips below 0)"),
        "nonnegative_gap": (True, lambda x: isinstance(x, bool),
                            "true or false (keep the contact face off its counterpart: ϑ_α ≥ 0 at every node of "
                            "the face on the foundation plane, with initial_gap = 'mesh' its height in the mesh + "
                            "ϑ_α ≥ 0, on an obstacle its distance + ϑ_α ≥ 0; linear constraints of U, needed only "
                            "where design.lower < 0; none with body.interference, whose overlap is intended)"),
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
        "motion": ("vertical", _oneof("vertical", "normal"),
                   "'vertical' (the paper's map: ϑ_α lifts the face along e3) or 'normal' (ϑ_α moves each node "
                   "of the face along the face's inward unit normal in the reference mesh; ϑ_α > 0 removes "
                   "material)"),
        "chart": ("auto", _oneof("auto", "plane", "cylinder"),
                  "'auto', 'plane' or 'cylinder': the coordinates ξ the design surface ϑ_α(ξ) lives on. 'plane': "
                  "the best-fit plane of the contact face (x3 = 0: ξ = (x1, x2)); 'cylinder': the best-fit "
                  "circular cylinder, ξ = (arc length around the axis, position along it); 'auto': (x1, x2) when "
                  "the face is a graph over them with the body above it (the paper's case), else the best-fit "
                  "plane when the face is planar, else the cylinder when it is cylindrical, else the best-fit "
                  "plane when the face is a graph over it; any other face is refused"),
        "axis": ([], lambda x: x == [] or _unit3(x),
                 "[] (fitted) or a unit vector [a1, a2, a3] (|a| = 1 to 1e-9): the axis of a cylindrical chart, "
                 "the normal of a plane chart"),
        "origin": ([], lambda x: x == [] or _vec3(x),
                   "[] (fitted) or [x1, x2, x3]: a point on the axis of a cylindrical chart, or the origin of a "
                   "plane chart"),
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
                   "node in the part, or with a node in it for a boundary part; in an assembly \"<body>.<part>\" "
                   "or \"<body>\", also of a counterpart body held by its clamps)"),
        "contacts": ([], lambda x: isinstance(x, list) and all(
            (isinstance(v, str) and v) or (isinstance(v, int) and not isinstance(v, bool) and v >= 0) for v in x),
                     "a list of contact pairs by name or index in [[contacts]] (the pressure objectives "
                     "pressure_uniformity and max_pressure: the nodes of those pairs; empty: every pair)"),
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
        "threads": (1, lambda x: isinstance(x, int) and not isinstance(x, bool) and x >= 0,
                    "an integer ≥ 0 (MKL's threads inside an evaluation on the condensation path: PARDISO "
                    "and the dense factorizations of the contact solve. 1: every evaluation is that of a "
                    "single-threaded run, bit for bit, whatever MKL_NUM_THREADS says, and on a 2-core machine "
                    "shared with other work also the fastest (docs/measurements.md); 0: MKL's own count "
                    "(MKL_NUM_THREADS, else one per core); N > 1: N threads)"),
    },
    "optimizer": {
        "eps": (1e-4, lambda x: _pos(x) and x < 1,
                "a number in (0, 1) (the certified stop: stationarity of Θ/Θ(α0) ≤ eps; "
                "contactopt.optimize.minimize_bundle's default is 1e-7; a run that cannot certify "
                "ends by the f-change test or by ftol, docs/stopping.md)"),
        "max_iter": (400, _posint, "an integer ≥ 1"),
        "ftol": (5e-4, lambda x: _nonneg(x) and x < 1,
                 "a number in [0, 1) (stop when, right after a serious step, the bundle model "
                 "predicts a relative decrease of Θ below this fraction: J within about ftol of a "
                 "local optimum, docs/stopping.md; 0: off, as in contactopt.optimize.minimize_bundle, "
                 "whose test problems ask f* to 1e-6)"),
        "ftol_window": (5, _posint, "an integer ≥ 1 (serious steps before the ftol test may stop "
                        "the run)"),
        "metric": ("bfgs", _oneof("auto", "bfgs", "diagonal", "none"),
                   "'bfgs', 'auto', 'diagonal' or 'none' (the variable metric of the bundle QP's "
                   "proximal term: damped BFGS from the last `metric_memory` serious steps, for a "
                   "piecewise smooth Θ; 'auto' lets the method choose BFGS while those steps show "
                   "curvature and the identity while they show kinks; a diagonal secant estimate; "
                   "or the identity, the default of contactopt.optimize.minimize_bundle, for "
                   "polyhedral functions; docs/stopping.md)"),
        "metric_memory": (20, _posint, "an integer ≥ 1 (serious steps the metric is estimated "
                          "from)"),
        "scale": ("bounds", _oneof("bounds", "none"),
                  "'bounds' or 'none' (the variables the method works in: 'bounds' scales each "
                  "design variable by the width of its box relative to the others, the identity "
                  "where the widths are equal, as in the paper's admissible set; 'none' for a box "
                  "that is only a safeguard, far wider than the range the variables move in; "
                  "docs/stopping.md)"),
    },
}


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
    "partner": ("auto", _oneof("auto", "point", "average", "mortar"),
                "'point' (a contact node's partner is the point of the top face directly below it: exact "
                "node-to-node coupling on matching meshes), 'average' (the mean of the foundation's "
                "displacement over the node's tributary area: a foundation finer than the body then "
                "converges; linear body elements only), 'mortar' (the relative displacement weighted by "
                "the node's dual basis function over the segmented faces: the contact patch test passes "
                "on non-matching meshes; the transformed dual basis on six-node triangles, on a flat face) "
                "or 'auto' ('point' where every partner is a node of the top face or the body's faces are "
                "quadratic on a curved face, else 'mortar')"),
    "tolerance": (1e-3, lambda x: _pos(x) and x < 0.5,
                  "a number in (0, 0.5) (geometric tolerance of the checks of the foundation's mesh, "
                  "relative to its median boundary edge length)"),
    "control": ("fixed", _oneof("fixed", "displacement", "force"),
                "'fixed' (the foundation held by `clamped` alone), 'displacement' (the part `loaded` moved by "
                "the rigid translation `displacement`) or 'force' (the part `loaded` pressed by the resultant "
                "`force`: it translates along the force, its translation an unknown of the state); the "
                "foundation translates rigidly with that part, so `clamped` may hold elsewhere only "
                "components the translation leaves at zero (symmetry planes); condensation path"),
    "loaded": ("bottom", _part_spec, _PART + " (control = 'displacement' or 'force': the part of the foundation "
               "that is moved or loaded; all three components of its nodes follow the translation)"),
    "displacement": ([0.0, 0.0, 0.0], _vec3,
                     "control = 'displacement': the translation [d1, d2, d3] of the part `loaded` (and with it "
                     "of the foundation)"),
    "force": ([0.0, 0.0, 0.0], _vec3, "control = 'force': the resultant [f1, f2, f3] applied to the part `loaded`, "
              "pressing the foundation onto the body (without foundation loads, the resultant of the contact "
              "forces on the body)"),
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
                "unknown of the state; condensation, Delassus and full-space paths)"),
    "displacement": ([0.0, 0.0, 0.0], _vec3,
                     "control = 'displacement': the obstacle's rigid translation [d1, d2, d3] (it enters the "
                     "gap of contact node m as −d·n_m)"),
    "force": ([0.0, 0.0, 0.0], _vec3, "control = 'force': the resultant [f1, f2, f3] the obstacle exerts on the "
              "body"),
    "weighting": ("node", _oneof("node", "mortar"),
                  "'node' (each contact node's gap is its own distance to the obstacle) or 'mortar' (the "
                  "dual-weighted gap D_jj⁻¹ ∫ Φ_j g dA over the faces around the node, Φ_j the dual basis of the "
                  "face: linear faces on the paper's map or a normal motion without a chart; docs/mortar.md)"),
}

# the assembly spelling (config/assembly.py): a body, a contact pair, a designed face
_BODY_REF = "\"<body>.<part>\": a body of [bodies] and one of its parts"
BODIES = {
    "mesh": ("", lambda x: isinstance(x, str),
             "a path to the body's mesh file (as body.mesh), relative to this file; empty: the built-in block of "
             "[geometry] and [mesh] (the body that carries the contact face) or `block` (a counterpart body)"),
    "block": FOUNDATION["block"],
    **{k: SCHEMA["body"][k] for k in ("clamped", "fixed_shape", "tolerance", "min_jacobian_ratio", "graph_tolerance",
                                      "penetration_tolerance")},
    "material": ({}, lambda x: isinstance(x, dict),
                 "a table { E = ..., nu = ... } (and formulation, as in [material], on the body that carries "
                 "the contact face); a key not given is [material]'s"),
    "body_force": ([0.0, 0.0, 0.0], _vec3, "[f1, f2, f3]: the body's force per unit volume"),
    **{k: FOUNDATION[k] for k in ("control", "loaded", "displacement", "force")},
}
CONTACTS = {
    "name": ("", lambda x: isinstance(x, str), "a name of letters, digits, _ and - (default: \"<face body>-<counterpart "
             "body>\", or \"<face body>-rigid\")"),
    "face": ("", lambda x: isinstance(x, (str, dict)), _BODY_REF + ", or a predicate table with body = \"<name>\" "
             "(the side whose nodes carry the contact forces; with several pairs on the face body, the body of "
             "contacts[0]'s face, or on a counterpart body of another pair against a third, elastic body: the "
             "condensation path)"),
    "counterpart": ("", lambda x: isinstance(x, (str, dict)),
                    _BODY_REF + " (an elastic counterpart), or a table with the keys of [obstacle] (a rigid one: "
                    "{ shape = \"plane\" } is the fixed plane x3 = 0)"),
    "friction": (0.3, _nonneg, "a number ≥ 0: the pair's Coulomb coefficient (default: [friction] coefficient)"),
    "partner": FOUNDATION["partner"],
    "interference": SCHEMA["body"]["interference"],
    "initial_gap": SCHEMA["body"]["initial_gap"],
}
DESIGNS = {"face": ("", lambda x: isinstance(x, (str, dict)), _BODY_REF + ", or a predicate table with body = "
                    "\"<name>\" (the designed face)"), **SCHEMA["design"]}

TOP_LEVEL = {"name": ("custom", lambda x: isinstance(x, str) and x != "", "a non-empty string"),
             "description": ("", lambda x: isinstance(x, str), "a string"),
             "length_unit": ("", lambda x: isinstance(x, str) and len(x) <= 16 and x == x.strip(),
                             "the unit of the meshes' coordinates, such as \"mm\" (contactopt computes in whatever "
                             "consistent units the meshes, material and loads share; this names the length on "
                             "the axes of the figures); empty: none named")}


BLOCK_LOADS = ("top_traction", "right_traction")
CASE_NAME = re.compile(r"[A-Za-z0-9_.+-]+")
TERM_KEYS = {"type", "weight", "region", "aggregate", "rho", "p", "target", "contacts"}
# keys of the arrays of tables: a term's weight (its other keys as in [objective]), a step's substeps
TERM_WEIGHT = (1.0, _nonneg, "a number ≥ 0")
SUBSTEPS = (1, _posint, "an integer ≥ 1 (equal increments of the loads from the previous step's)")
# a step's force of a force-controlled [obstacle]: absent, the step takes obstacle.force
STEP_FORCE = (None, _vec3, "[f1, f2, f3], the resultant the force-controlled obstacle exerts on the body at the "
              "step's end, a positive multiple of obstacle.force (absent: obstacle.force); its substeps ramp "
              "it linearly from the previous step's (the first step's from zero)")

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
