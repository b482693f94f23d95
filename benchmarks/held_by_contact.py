"""A body held only by contact (docs/obstacles.md, "Bodies held only by contact"): one command,

    PYTHONPATH=src python benchmarks/held_by_contact.py

The block 2 × 1 × 1 (hexahedra 8 × 4 × 3) without clamps on the plane x3 = 0, a top pressure 0.1
(N = 0.2) and a side traction 0.02 on its right face (Q = 0.02 < F·N = 0.06), F = 0.3. Prints

- the anchor iterations and the state's distance to the converged one for the anchor stiffness
  γ = c · mean diag S, c = 1e-1 … 1e-4 (the default is 1e-3), on a design with gaps;
- the free block against the same block clamped at three nodes that stick in contact (u, λ, τ and
  the clamps' reactions against the free body's contact forces at those nodes), and against the
  block clamped at one node in some components (the clamp's force);
- the subgradient against Richardson-extrapolated central differences (3 seeded directions) on
  hexahedra, and the time of one evaluation of the free block over that of the block clamped on
  its top (same run);
- the refusal of Q = 0.07 > F·N.
"""

from __future__ import annotations

import time

import numpy as np

import contactopt.paths.rigid as rigid
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient


def block(side=0.02, clamped=(), **updates):
    cfg = {"friction": {"coefficient": 0.3}, "linear_solver": {"path": "condensation"},
           "state": {"method": "newton", "tol": 1e-12},
           "loads": {"top_traction": [0.0, 0.0, -0.1], "right_traction": [side, 0.0, 0.0]},
           "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0},
           "geometry": {"a": 2.0, "b": 1.0, "c": 1.0}, "mesh": {"nx": 8, "ny": 4, "nz": 3},
           "body": {"clamped": list(clamped) if not isinstance(clamped, str) else clamped}}
    cfg.update(updates)
    return load_config("example1").with_updates(cfg)


def main():
    gapped = None
    print("anchor stiffness γ/mean diag S | anchor steps | max |u − u(1e-3)| / max |u|")
    ref = None
    for c in (1e-3, 1e-1, 1e-2, 1e-4):
        rigid.GAMMA_FACTOR = c
        p = ShapeProblem(block())
        gapped = 0.002 * np.sin(np.arange(p.model.n_design)) + 0.001
        st = p.solve_state(gapped)
        ref = st.u if ref is None else ref
        print(f"{c:g} | {st.info['rigid_iterations']} | {np.abs(st.u - ref).max() / np.abs(ref).max():.2e}")
    rigid.GAMMA_FACTOR = 1e-3

    p = ShapeProblem(block())
    zero = np.zeros(p.model.n_design)
    st = p.solve_state(zero)
    m = p.model
    pts = m.body.reference.points
    stick = m.contact_nodes[st.class_names == "M3+"]
    xy = pts[stick, :2]
    b = int(np.argmax(np.linalg.norm(xy - xy[0], axis=1)))
    d, e = xy[b] - xy[0], xy - xy[0]
    still = [stick[0], stick[b], stick[int(np.argmax(np.abs(d[0] * e[:, 1] - d[1] * e[:, 0])))]]
    box = [{"box": [[x - 1e-3, x + 1e-3], [y - 1e-3, y + 1e-3], [-1e-3, 1e-3]]} for x, y, _ in pts[still]]
    sc = ShapeProblem(block(clamped=box)).solve_state(zero)
    keep = ~np.isin(m.contact_nodes, still)
    asm = m.assemble(zero)
    reaction = m.assembler.to_full(asm.A @ sc.u[m.assembler.free] - asm.L).reshape(-1, 3)[still]
    i = np.searchsorted(m.contact_nodes, still)
    force = np.c_[-st.tau[i], st.lam[i]]
    print(f"\nclasses {st.counts}; clamped at the still nodes {still}:")
    print(f"  max |u − u_clamped| / max |u| = {np.abs(sc.u - st.u).max() / np.abs(st.u).max():.2e}")
    print(f"  max |λ − λ_clamped|, |τ − τ_clamped| / max λ = {np.abs(sc.lam - st.lam[keep]).max() / st.lam.max():.2e}, "
          f"{np.abs(sc.tau - st.tau[keep]).max() / st.lam.max():.2e}")
    print(f"  max |clamp reaction − free contact force| / max λ = {np.abs(reaction - force).max() / st.lam.max():.2e}")

    one_node(zero)

    rep = check_gradient(p, gapped, seed=1, n_directions=3, state_method="newton", state_tol=1e-13)
    print(f"\nsubgradient vs central differences: {np.array2string(rep.rel_errors, precision=2)}, "
          f"Taylor rate {rep.taylor_rate:.2f}")
    clamped = ShapeProblem(block(clamped="top"))
    times = []
    for prob in (p, clamped):
        prob.evaluate(gapped)
        t0 = time.perf_counter()
        for k in range(10):
            prob.clear_cache()
            prob.evaluate(gapped + 1e-5 * k)
        times.append(time.perf_counter() - t0)
    print(f"one evaluation (state + subgradient), free block / block clamped on its top: {times[0] / times[1]:.2f}")
    try:
        ShapeProblem(block(side=0.07))
    except ConfigError as exc:
        print("\nQ = 0.07:", exc.problems[0])


def one_node(alpha) -> None:
    """The free block against the block clamped at ONE node, the centre (1, 0.5, 0) of the contact
    face, in some components: u2 under the side traction (the symmetry plane x2 = 0.5), u1 and u2
    under the side traction, u1 and u2 under the top pressure alone (double symmetry)."""
    tight = {"state": {"method": "newton", "tol": 1e-14}}
    print("\none clamped node (1, 0.5, 0), state tol 1e-14:")
    print("side traction | clamped | motions left | max |u − u_free| / max |u| | clamp force / max λ | "
          "free body's (−τ1, −τ2, λ) there / max λ")
    for side, comps in ((0.02, [2]), (0.02, [1, 2]), (0.0, [1, 2])):
        free = ShapeProblem(block(side=side, **tight))
        st = free.solve_state(alpha)
        m = free.model
        pts = m.body.reference.points
        node = int(np.flatnonzero(np.all(np.abs(pts - [1.0, 0.5, 0.0]) < 1e-12, axis=1))[0])
        box = {"box": [[0.999, 1.001], [0.499, 0.501], [-1e-3, 1e-3]]}
        clamped = ShapeProblem(block(side=side, clamped=[{"on": box, "components": comps}], **tight))
        sc = clamped.solve_state(alpha)
        asm = m.assemble(alpha)
        force = m.assembler.to_full(asm.A @ sc.u[m.assembler.free] - asm.L).reshape(-1, 3)
        force[clamped.model.contact_nodes] -= np.c_[-sc.tau, sc.lam]
        k = int(np.searchsorted(m.contact_nodes, node))
        scale = st.lam.max()
        print(f"{side:g} | u{', u'.join(map(str, comps))} | {clamped.model.body.rigid.count} | "
              f"{np.abs(sc.u - st.u).max() / np.abs(st.u).max():.1e} | "
              f"{np.array2string(force[node] / scale, precision=2)} | "
              f"{np.array2string(np.r_[-st.tau[k], st.lam[k]] / scale, precision=3)}")


if __name__ == "__main__":
    main()
