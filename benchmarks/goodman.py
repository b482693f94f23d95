"""Friction in the Hertz contact of a rigid sphere (docs/obstacles.md, "Friction"): how much does
F change the pressure, and is it the normal–tangential coupling? One command,

    PYTHONPATH=src python benchmarks/goodman.py [--levels 2] [--nus 0.3 0.4 0.49]
    PYTHONPATH=src python benchmarks/goodman.py --steps 1 4 8 16 [--levels 2] [--nus 0.3]

The quarter model of benchmarks/hertz.py (a rigid sphere R = 10 pressed by the force P of the
frictionless contact radius 0.5, the block clamped at its far face, E = 1).

Without ``--steps`` (the static problem, no loading history): F = 0, 0.3 and 1.0 at the same P.
Printed per ν and mesh: the peak pressure at the centre node and fitted, the fitted contact radius
and the approach δ, each relative to F = 0, the node classes, and Dundurs'
β = (1 − 2ν)/(2(1 − ν)), the coupling of normal and tangential tractions of a rigid body on an
elastic one (β = 0: no coupling, friction cannot change the pressure; ν = 0.49 on B-bar hexahedra).

With ``--steps N …`` (monotonic indentation): the sphere's force raised from 0 to P in N equal
load steps (``[[load_steps]]``, one step of N substeps, Coulomb's law on each increment's slip),
F = 0.3. Printed per ν, mesh and N: the same quantities against the frictionless run and against
Hertz, the resultant Σλ against P, and the stick zone of the last increment (the nodes whose slip
increment vanishes, M3+): c/a from the areas (tributary areas of the sticking nodes and of the
nodes in contact), the largest sticking and the smallest slipping radius over the fitted a.
N = 1 is the static problem.

With ``--halfspace`` (no FE): the same monotonic indentation of an elastic half-space from its
axisymmetric surface integral equations on rings (``contactopt.verification.spence.indent``), F = 0.3,
on 60, 120, 240 uniform rings and 1, 4, 8 rings per step; each quantity relative to the frictionless
run on the same rings, at the same P (self-similarity: P ∝ a³, p0 ∝ a, δ ∝ a²) or the same a.

    PYTHONPATH=src python benchmarks/goodman.py --halfspace [--nus 0.3 0.4 0.49]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from contactopt.problem import ShapeProblem
from contactopt.verification.hertz import A_TARGET, R, configure, fit, graded_axis, pressure


def sphere(h: float, nu: float, friction: float, size=20.0, steps: int = 0) -> dict:
    """The quarter model pressed by P; ``steps`` N > 0: P reached in N equal increments."""
    e_star = 1.0 / (1 - nu ** 2)
    force = 4 * e_star * A_TARGET ** 3 / (3 * R)
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    updates = {
        "material": {"E": 1.0, "nu": nu}, "friction": {"coefficient": friction},
        "state": {"method": "newton", "tol": 1e-12, "max_iter": 200}, "linear_solver": {"path": "condensation"},
        "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
        "design": {"degree": [2, 2], "initial": 0.0, "C0": 0.1, "C1": 1.0, "C2": 0.0},
        "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "sphere", "center": [0.0, 0.0, -R], "radius": R, "control": "force",
                     "force": [0.0, 0.0, force / 4]}}
    if steps:
        updates["load_steps"] = [{"name": "press", "substeps": steps}]
    cfg = configure(updates)
    t0 = time.perf_counter()
    pr = ShapeProblem(cfg)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    r, p, _, _ = pressure(pr, st)
    a, p0 = fit(r, p)
    A = pr.model.contact_areas()
    shear = np.linalg.norm(st.tau, axis=1) / A
    names = st.class_names
    stick, slip = (names == "M3+") & (st.lam > 0), (names == "M1") & (st.lam > 0)
    return {"p0_node": float(p[np.argmin(r)]), "p0": p0, "a": a, "delta": st.obstacle.translation,
            "P": force, "sum_lam": 4 * float(st.lam.sum()), "e_star": e_star,
            "counts": st.counts, "shear_max": float(shear.max()), "time": time.perf_counter() - t0,
            "c_area": math.sqrt(4 * A[stick].sum() / math.pi), "a_area": math.sqrt(4 * A[st.lam > 0].sum() / math.pi),
            "stick": float(r[stick].max(initial=0.0)), "slip": float(r[slip].min(initial=np.inf)),
            "solves": st.obstacle.solves, "r": r, "p": p, "names": names}


def static_table(levels: int, nus) -> None:
    print("| ν | β | h | F | p0 (centre node) | p0 (fit) | a (fit) | δ | max shear / p0(F=0) | stick / slip nodes | time |")
    print("|---" * 11 + "|")
    for nu in nus:
        beta = (1 - 2 * nu) / (2 * (1 - nu))
        for level in range(levels):
            h = A_TARGET / (3 * 2 ** level)
            ref = sphere(h, nu, 0.0)
            for F in (0.0, 0.3, 1.0):
                q = ref if F == 0 else sphere(h, nu, F)
                rel = {k: q[k] / ref[k] - 1 for k in ("p0_node", "p0", "a", "delta")}
                print(f"| {nu:g} | {beta:.3f} | a/{3 * 2 ** level} | {F:g} | {rel['p0_node']:+.2%} | {rel['p0']:+.2%} | "
                      f"{rel['a']:+.2%} | {rel['delta']:+.2%} | {q['shear_max'] / ref['p0_node']:.3f} | "
                      f"{q['counts']['M3+']} / {q['counts']['M1']} | {q['time']:.1f} s |", flush=True)


def steps_table(levels: int, nus, counts, friction: float = 0.3) -> dict:
    """The monotonic indentation in N steps against the frictionless run and Hertz (module docstring)."""
    print("| ν | β | h | N | p0 node vs F = 0 | p0 fit vs F = 0 | a fit vs F = 0 | δ vs F = 0 | p0 fit vs Hertz | "
          "a fit vs Hertz | Σλ / P | c/a (areas) | stick out to r/a | slip from r/a | stick / slip nodes | time |")
    print("|---" * 16 + "|")
    out = {}
    for nu in nus:
        beta = (1 - 2 * nu) / (2 * (1 - nu))
        for level in range(levels):
            h = A_TARGET / (3 * 2 ** level)
            ref = sphere(h, nu, 0.0)
            a_H = A_TARGET
            p0_H = 3 * ref["P"] / (2 * math.pi * a_H ** 2)
            print(f"| {nu:g} | {beta:.3f} | a/{3 * 2 ** level} | F = 0 | — | — | — | — | {ref['p0'] / p0_H - 1:+.2%} | "
                  f"{ref['a'] / a_H - 1:+.2%} | {ref['sum_lam'] / ref['P']:.4f} | — | — | — | — | "
                  f"{ref['time']:.1f} s |", flush=True)
            for n in counts:
                q = sphere(h, nu, friction, steps=n)
                out[(nu, level, n)] = (q, ref)
                rel = {k: q[k] / ref[k] - 1 for k in ("p0_node", "p0", "a", "delta")}
                print(f"| {nu:g} | {beta:.3f} | a/{3 * 2 ** level} | {n} | {rel['p0_node']:+.2%} | {rel['p0']:+.2%} | "
                      f"{rel['a']:+.2%} | {rel['delta']:+.2%} | {q['p0'] / p0_H - 1:+.2%} | {q['a'] / a_H - 1:+.2%} | "
                      f"{q['sum_lam'] / q['P']:.4f} | {q['c_area'] / q['a_area']:.3f} | {q['stick'] / q['a']:.3f} | "
                      f"{q['slip'] / q['a']:.3f} | {q['counts']['M3+']} / {q['counts']['M1']} | {q['time']:.1f} s |",
                      flush=True)
    return out


def punch(h: float, friction: float = 0.3) -> dict:
    """The flat punch of radius a(1 + 1/24) (the rim between nodes, benchmarks/hertz.py) pressed by
    P with friction, static, ν = 0.3: its stick zone. Its contact area is fixed and its tractions
    scale with P, so the static problem is the monotonic one; and an increment of the monotonic
    Hertz indentation at contact radius a is this punch's problem (below), so the two c/a agree."""
    import tempfile

    from contactopt.verification.hertz import P_SPHERE, punch_problem, punch_stl
    radius = A_TARGET * (1 + 1 / 24)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        stl = punch_stl(f"{tmp}/punch.stl", radius / math.cos(math.pi / 96) ** 0.5)
        pr = punch_problem(h, stl, radius, P_SPHERE, friction=friction)
        st = pr.solve_state(np.zeros(pr.model.n_design))
    m = pr.model
    x = m.body.reference.points[m.contact_nodes]
    r = np.hypot(x[:, 0], x[:, 1])
    A = m.contact_areas()
    names = st.class_names
    stick, slip, touch = (names == "M3+") & (st.lam > 0), (names == "M1") & (st.lam > 0), st.lam > 0
    return {"c_area": math.sqrt(4 * A[stick].sum() / math.pi), "a_area": math.sqrt(4 * A[touch].sum() / math.pi),
            "stick": float(r[stick].max(initial=0.0)), "slip": float(r[slip].min(initial=np.inf)), "radius": radius,
            "counts": st.counts, "time": time.perf_counter() - t0}


def spence_table(nus, friction: float = 0.3) -> None:
    """c/a of the frictional flat punch from the half-space's integral equations
    (:mod:`contactopt.verification.spence`) on 60, 120, 200 rings, with its two checks."""
    from contactopt.verification.spence import load_ratio, punch_system, stick_ratio
    print("| ν | β/F | rings | P/(2aE*δ) frictionless | bonded / Mossakovskii | c/a between | time |")
    print("|---" * 7 + "|")
    for nu in nus:
        for n in (60, 120, 200):
            t0 = time.perf_counter()
            s = punch_system(nu, n)
            lo, hi = stick_ratio(s, friction)
            bonded = load_ratio(s, True) / (math.log(3 - 4 * nu) / (2 * s.beta))
            print(f"| {nu:g} | {s.beta / friction:.3f} | {n} | {load_ratio(s, False):.6f} | {bonded:.6f} | "
                  f"{lo:.4f} – {hi:.4f} | {time.perf_counter() - t0:.1f} s |", flush=True)


def halfspace_table(nus, friction: float = 0.3, rings=(60, 120, 240), steps=(1, 4, 8)) -> None:
    """The monotonic frictional indentation of the half-space on rings against the frictionless one:
    the centre pressure, the contact radius and the approach at the same P, the same read through a
    fitted Hertz profile (as the FE's columns "fit"), P at the same a, c/a against the punch's, and
    P/(aδ) against (4/3)E* times the punch's P/(2aE*δ); the frictionless run against Hertz."""
    from contactopt.verification.spence import indent, punch_load_ratio, punch_system, ring_system, stick_ratio
    print("| ν | rings | rings / step | F = 0: P, δ, p0 vs Hertz | p0 (centre) | p0 (fit) | a | a (fit) | δ | "
          "P at the same a | c/a (punch) | P/(aδ) / punch's | time |")
    print("|---" * 13 + "|")
    for nu in nus:
        ps = punch_system(nu, 200)
        lo, hi = stick_ratio(ps, friction)
        k_punch = punch_load_ratio(ps, friction)
        for n in rings:
            t0 = time.perf_counter()
            s = ring_system(nu, np.linspace(0.0, 1.0, n + 1))
            z = indent(s, 0.0)
            zh, (za, zp) = z.hertz(), z.fitted()
            for st in steps:
                f = indent(s, friction, rings_per_step=st)
                fh, (fa, fp) = f.hertz(), f.fitted()
                ar = (zh["P"] / fh["P"]) ** (1 / 3)          # a at the same P over the frictionless a
                print(f"| {nu:g} | {n} | {st} | {zh['P'] - 1:+.1e}, {zh['delta'] - 1:+.1e}, {zh['p0'] - 1:+.1e} | "
                      f"{fh['p0'] / zh['p0'] * ar - 1:+.2%} | {fp / zp * ar - 1:+.2%} | {ar - 1:+.2%} | "
                      f"{fa / za * ar - 1:+.2%} | {fh['delta'] / zh['delta'] * ar * ar - 1:+.2%} | "
                      f"{fh['P'] / zh['P'] - 1:+.2%} | {f.c:.4f} ({lo:.4f} – {hi:.4f}) | "
                      f"{fh['P/(a delta)'] / zh['P/(a delta)'] / k_punch:.5f} | {time.perf_counter() - t0:.1f} s |",
                      flush=True)
        b = indent(s, math.inf).hertz()["P/(a delta)"] / zh["P/(a delta)"]
        print(f"bonded, ν = {nu:g}, {rings[-1]} rings: P/(aδ) over (4/3)E* = {b:.5f}, "
              f"Mossakovskii's ln(3 − 4ν)/(2β) = {math.log(3 - 4 * nu) / (2 * s.beta):.5f}\n", flush=True)


def punch_table(levels: int) -> None:
    print("| h | c/a (areas) | stick out to r/a | slip from r/a | stick / slip nodes | time |")
    print("|---" * 6 + "|")
    for level in range(levels):
        q = punch(A_TARGET / (3 * 2 ** level))
        print(f"| a/{3 * 2 ** level} | {q['c_area'] / q['a_area']:.3f} | {q['stick'] / q['radius']:.3f} | "
              f"{q['slip'] / q['radius']:.3f} | {q['counts']['M3+']} / {q['counts']['M1']} | {q['time']:.1f} s |",
              flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=2)
    ap.add_argument("--nus", type=float, nargs="+", default=[0.3, 0.4, 0.49])
    ap.add_argument("--steps", type=int, nargs="*", default=None,
                    help="load steps N of the monotonic indentation (F = 0.3); absent: the static table")
    ap.add_argument("--punch", action="store_true",
                    help="the stick zone of the flat punch with F = 0.3, the monotonic Hertz c/a's counterpart: "
                         "from the half-space's integral equations (--nus), and by the FE (static, ν = 0.3)")
    ap.add_argument("--halfspace", action="store_true",
                    help="the monotonic indentation of the half-space on rings (F = 0.3, --nus), no FE")
    args = ap.parse_args()
    if args.halfspace:
        halfspace_table(args.nus)
    elif args.punch:
        spence_table(args.nus)
        punch_table(args.levels)
    elif args.steps:
        steps_table(args.levels, args.nus, args.steps)
    else:
        static_table(args.levels, args.nus)


if __name__ == "__main__":
    main()
