"""Mindlin–Deresiewicz hysteresis: the paraboloidal pad of benchmarks/cattaneo_mindlin.py pressed
by P, then its clamped top face moved tangentially by δ up to δ*, back to −δ* and up to δ* again
in steps at constant P; the contact force Q = Στ1 against δ, the displacement of the clamped top
relative to the foundation's clamped bottom (docs/load_paths.md).

The top's displacement is prescribed through its equivalent nodal load: with u_d = δ e1 on the
top's DOFs, the free DOFs carry −K_fd u_d (K the stiffness on every DOF), which is added to the
step's loads. δ(Q) is then the remote relative displacement of Mindlin's theory plus the finite
bodies' bulk compliance, linear in Q. Analytic (Johnson, Contact Mechanics §7.2; x = Q/μP,
K = (2 − ν1)/G1 + (2 − ν2)/G2, a Hertz's radius):

    loading     δ = (3μPK/16a)·[1 − (1 − x)^(2/3)]
    unloading   δ = δ* − 2·δ_loading((Q* − Q)/2),   reloading δ = −δ* + 2·δ_loading((Q* + Q)/2)
    per cycle   ΔW = (9μ²P²K/10a)·[1 − (1 − x*)^(5/3) − (5x*/6)(1 + (1 − x*)^(2/3))]

Measured: the loop's area ∮δ dQ (trapezoids over the steps) and the friction work Σ_k τ^k·Δu_t^k
over the cycle's solves (the energy the interface dissipates), each against ΔW; and the branches
with the initial full-stick slope subtracted (FE: from the first small increment; theory: K/8a).

The FE's own contact radius (from the second moment of λ, Σλr²/Σλ = (2/5)a²) gives a second ΔW
next to Hertz's a from the measured P. ``--graded``: each n is instead a graded block, elements of
side 2/n on |x1 − 1|, |x2 − 1| ≤ 0.45 (1.7 Hertz radii) and in depth at the contact face, growing
by a factor 1.25 towards the sides, the top and the foundation's bottom; the foundation is the same
grid in (x1, x2) (a mesh file, node-to-node partners).

    PYTHONPATH=src python benchmarks/mindlin_deresiewicz_loop.py [n ...] [--steps m] [--graded] [--nu ν]
        [--target Q*/μP] [--depth d] [--f3 f] [--fine w]
        [--ring k,r0,r1] [--figure out.png]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import cattaneo_mindlin
from cattaneo_mindlin import ESTAR, F3, MU, NU, E, R, config, moment_radius
from contactopt.config import load_config
from contactopt.fem.loadset import LoadSet
from contactopt.problem import ShapeProblem

G = E / (2 * (1 + NU))
KCOMP = 2 * (2 - NU) / G                     # (2 − ν1)/G1 + (2 − ν2)/G2, one material
DEPTH = 1.0                                  # of the pad and of the foundation (graded meshes)
FINE = 0.45                                  # half-width of the graded meshes' fine zone about the centre
RING = None                                  # (k, r0, r1): spacing k·h on |x − 1| < r0, h on r0–r1 only


def set_poisson(nu: float) -> None:
    """Both bodies' Poisson ratio (default 0.3) and the constants that depend on it. With ν = 0 a
    tangential traction moves the surface only along itself, and Mindlin's solution (slip parallel
    to Q) is exact rather than an approximation."""
    global NU, G, KCOMP, ESTAR
    NU, G = nu, E / (2 * (1 + nu))
    KCOMP, ESTAR = 2 * (2 - nu) / G, E / (2 * (1 - nu ** 2))
    cattaneo_mindlin.NU, cattaneo_mindlin.ESTAR = NU, ESTAR


def set_geometry(depth: float | None = None, f3: float | None = None, fine: float | None = None) -> None:
    """The graded meshes' depth of both bodies (default 1), the pressing body force f3 (default
    −0.08) and the fine zone's half-width (default 0.45)."""
    global DEPTH, F3, FINE
    DEPTH, F3, FINE = depth or DEPTH, f3 or F3, fine or FINE


def graded_axis(h: float, half: float = 0.45, growth: float = 1.25, side: float = 2.0, ring=None) -> list:
    """Node coordinates on [0, side]: spacing h on |x − side/2| ≤ half, growing by ``growth`` outside;
    with ``ring`` = (k, r0, r1) spacing k·h on |x − side/2| < r0 and h on r0–r1 instead (a band at
    the contact's edge refined alone)."""
    if ring is None:
        right = [side / 2 + k * h for k in range(int(round(half / h)) + 1)]
    else:
        k, r0, r1 = ring
        right = [side / 2 + j * k * h for j in range(int(round(r0 / (k * h))) + 1)]
        right += [right[-1] + j * h for j in range(1, int(round((side / 2 + r1 - right[-1]) / h)) + 1)]
    step = h
    while right[-1] < side - 1e-12:
        step *= growth
        right.append(right[-1] + step)
    if right[-1] - right[-2] < 0.5 * (right[-2] - right[-3]):
        del right[-2]
    right[-1] = side
    left = [side - x for x in reversed(right[1:])]
    out = left + right
    out[0] = 0.0
    return out


def depth_axis(h: float, depth: float = 1.0, growth: float = 1.25) -> list:
    """Node coordinates on [0, depth]: spacing h at 0, growing by ``growth``."""
    z, step = [0.0], h
    while z[-1] < depth - 1e-12:
        z.append(z[-1] + step)
        step *= growth
    if depth - z[-2] < 0.5 * (z[-2] - z[-3]):
        del z[-2]
    z[-1] = depth
    return z


def graded_config(n: int, steps: list, where: Path) -> dict:
    """``config`` of benchmarks/cattaneo_mindlin.py on graded grids (module docstring); the
    foundation's mesh file is written to ``where``."""
    import meshio

    from contactopt.mesh.block import graded_block_mesh
    h = 2.0 / n
    xy, z = graded_axis(h, FINE, ring=RING), depth_axis(h, DEPTH)
    cfg = config(n, steps)
    cfg["geometry"]["c"] = DEPTH
    cfg["mesh"] = {"x1": xy, "x2": xy, "x3": z}
    found = graded_block_mesh(xy, xy, z)
    pts = found.points.copy()
    pts[:, 2] = -pts[:, 2]                  # mirrored (top face on x3 = 0, below it), cells re-oriented
    path = where / f"foundation{n}.vtu"
    meshio.write(path, meshio.Mesh(pts, [("hexahedron", found.cells[:, [4, 5, 6, 7, 0, 1, 2, 3]])]))
    cfg["foundation"] = {"mesh": str(path), "top": {"x3": 0.0}, "clamped": {"x3": -DEPTH},
                         "material": {"E": E, "nu": NU}}
    return cfg


class WithNodal(LoadSet):
    """A load set plus a fixed nodal force vector (the prescribed top displacement's −K_fd u_d)."""

    def __init__(self, base: LoadSet, extra: np.ndarray):
        super().__init__(base.tractions, base.pressures, base.body_force)
        self.extra = extra

    def vector(self, coords, assembler):
        return super().vector(coords, assembler) + self.extra


def top_unit_load(pr) -> np.ndarray:
    """−K_fd u_d for u_d = e1 on the clamped top's DOFs (full length, zero on the fixed DOFs)."""
    asm = pr.model.assembler
    coords = pr.model.mesh.coordinates(pr.model.initial_design())
    K = asm.full_stiffness(coords)
    top = pr.model.body.part("top").nodes
    ud = np.zeros(asm.n_full)
    ud[3 * top] = 1.0
    out = -(K @ ud)
    fixed = np.ones(asm.n_full, bool)
    fixed[asm.free] = False
    out[fixed] = 0.0
    return out


def analytic(P, a):
    C = 3 * MU * P * KCOMP / (16 * a)

    def loading(Q):
        return C * (1 - (1 - np.asarray(Q) / (MU * P)) ** (2 / 3))

    def dissipation(Qs):
        x = Qs / (MU * P)
        return 9 * MU ** 2 * P ** 2 * KCOMP / (10 * a) * (1 - (1 - x) ** (5 / 3) - 5 * x / 6 * (1 + (1 - x) ** (2 / 3)))
    return loading, dissipation


def solve_path(n: int, deltas: list, graded: bool = False, where: Path | None = None):
    """Press, then move the clamped top by each δ of ``deltas`` in turn (one load step each).
    Returns the problem and the states of the steps (the press first)."""
    steps = [{"name": "press", "body_force": [0.0, 0.0, F3]}]
    steps += [{"name": f"d{j}", "body_force": [0.0, 0.0, F3]} for j in range(1, len(deltas) + 1)]
    where = where or Path(tempfile.mkdtemp(prefix="mdloop"))
    cfg = graded_config(n, steps, where) if graded else config(n, steps)
    pr = ShapeProblem(load_config(cfg))
    unit = top_unit_load(pr)
    for step in pr.steps[0][1:]:
        step.loads = WithNodal(step.loads, deltas[step.index - 1] * unit)
    pr.solve_states(pr.model.initial_design())
    return pr, [st for _, _, st in pr.step_results()]


def calibrate(n: int, graded: bool = False, d0: float = 1e-4) -> dict:
    """Press, then a first increment δ = d0 that sticks everywhere: P, Q = k0 δ, Hertz's a and the
    FE's (second moment of λ), and the FE's stick compliance beyond Mindlin's K/8a (``bulk``)."""
    pr, sts = solve_path(n, [d0], graded)
    P = sts[0].lam.sum()
    k0 = sts[1].tau[:, 0].sum() / d0
    a_h = (3 * P * R / (4 * ESTAR)) ** (1 / 3)
    return {"P": P, "k0": k0, "a": a_h, "a_fe": moment_radius(sts[0], pr.model), "d0": d0,
            "bulk": 1 / k0 - KCOMP / (8 * a_h)}


def remote(cal: dict, x: float) -> float:
    """δ for Q/μP = x on Mindlin's loading curve plus the FE's extra stick compliance."""
    P = cal["P"]
    return float(analytic(P, cal["a"])[0](x * MU * P) + cal["bulk"] * x * MU * P)


def run(n: int, m: int, target: float = 0.7, graded: bool = False):
    """The cycle at n elements per side (``graded``: fine spacing 2/n near the contact) with m steps
    per quarter branch; δ* from a stick calibration so that Q*/μP ≈ ``target``. Returns the
    measurements (dict)."""
    tmp = Path(tempfile.mkdtemp(prefix="mdloop"))
    cal = calibrate(n, graded)
    P, k0, a_h, a_fe, d0, bulk = (cal[k] for k in ("P", "k0", "a", "a_fe", "d0", "bulk"))
    loading, dissipation = analytic(P, a_h)
    dstar = remote(cal, target)
    up = [dstar * j / m for j in range(1, m + 1)]
    down = [dstar * (1 - j / m) for j in range(1, 2 * m + 1)]
    back = [-dstar * (1 - j / m) for j in range(1, 2 * m + 1)]
    deltas = [d0] + up + down + back
    pr, sts = solve_path(n, deltas, graded, tmp)
    Q = np.array([st.tau[:, 0].sum() for st in sts[1:]])
    Ps = np.array([st.lam.sum() for st in sts])
    d = np.array(deltas)
    cyc = slice(m, None)                       # from δ* down to −δ* and back to δ*
    dq, dd = np.diff(Q[cyc]), np.diff(d[cyc])
    area = float(np.sum(0.5 * (d[cyc][1:] + d[cyc][:-1]) * dq))          # ∮ δ dQ (clockwise: > 0 below)
    work_loop = float(np.sum(0.5 * (Q[cyc][1:] + Q[cyc][:-1]) * dd))      # ∮ Q dδ
    work = 0.0
    for st in sts[m + 2:]:                   # the solves of the cycle (after δ*)
        work += float(np.sum(st.tau * st.slip_increment))
    Qs = 0.5 * (Q[m] - Q[3 * m])
    dW_fe = float(analytic(P, a_fe)[1](Qs))
    return {"n": n, "m": m, "graded": graded, "P": P, "P_range": (Ps[1:].min(), Ps[1:].max()), "a": a_h,
            "a_fe": a_fe, "dW_fe": dW_fe, "k0": k0, "Qs": Qs,
            "x": Qs / (MU * P), "dW": float(dissipation(Qs)), "area": -area, "work_loop": work_loop,
            "work": work, "Q": Q, "delta": d, "loading": loading, "bulk": bulk, "d0": d0}


def branches(r):
    """(Q, δ − Q/k0) of the FE and (Q, δ_MD − QK/8a) of the theory on the cycle's two branches."""
    m, Q, d = r["m"], r["Q"], r["delta"]
    Qs, loading = r["Qs"], r["loading"]
    fe = d - Q / r["k0"]
    dstar = loading(Qs)
    q = np.linspace(-Qs, Qs, 201)
    un = dstar - 2 * loading((Qs - q) / 2)
    re = -dstar + 2 * loading((Qs + q) / 2)
    lin = KCOMP / (8 * r["a"])
    return (Q[m:3 * m + 1], fe[m:3 * m + 1]), (Q[3 * m:], fe[3 * m:]), (q, un - lin * q), (q, re - lin * q)


def figure(r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    (qu, fu), (qr, fr), (q, un), (_, re) = branches(r)
    mP = MU * r["P"]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(q / mP, un, "r-", lw=1.2, label="Mindlin–Deresiewicz, unloading")
    ax.plot(q / mP, re, "b-", lw=1.2, label="Mindlin–Deresiewicz, reloading")
    ax.plot(qu / mP, fu, "rs", ms=4, label="contactopt, unloading")
    ax.plot(qr / mP, fr, "bo", ms=4, label="contactopt, reloading")
    ax.set_xlabel("Q/μP")
    ax.set_ylabel("δ − (initial stick compliance)·Q")
    ax.set_title(f"Hysteresis loop, n = {r['n']}, Q*/μP = {r['x']:.2f}: ΔW FE/theory = {r['area'] / r['dW']:.3f}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main(argv):
    m, fig, sizes, graded, target = 4, None, [], False, 0.7
    it = iter(argv)
    for arg in it:
        if arg == "--steps":
            m = int(next(it))
        elif arg == "--target":
            target = float(next(it))
        elif arg == "--nu":
            set_poisson(float(next(it)))
        elif arg in ("--depth", "--f3", "--fine"):
            set_geometry(**{arg[2:]: float(next(it))})
        elif arg == "--ring":
            global RING
            RING = tuple(float(v) for v in next(it).split(","))
        elif arg == "--graded":
            graded = True
        elif arg == "--figure":
            fig = next(it)
        else:
            sizes.append(int(arg))
    print("| n | steps per quarter | Q*/μP | P range | ∮δ dQ | ∮Q dδ | friction work Στ·Δu_t | ΔW (MD) | "
          "area/ΔW | work/ΔW | branch error / δ* | a Hertz | a FE | area/ΔW(a FE) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    last = None
    for n in sizes or [16, 24]:
        r = run(n, m, target, graded=graded)
        (qu, fu), (qr, fr), _, _ = branches(r)
        loading, Qs = r["loading"], r["Qs"]
        dstar, lin = loading(Qs), KCOMP / (8 * r["a"])
        th_u = dstar - 2 * loading((Qs - qu) / 2) - lin * qu
        th_r = -dstar + 2 * loading((Qs + qr) / 2) - lin * qr
        # the FE loop is centred on its own mid-line: compare shapes (both branches, offset removed)
        off = 0.5 * (np.mean(fu - th_u) + np.mean(fr - th_r))
        err = max(np.abs(fu - th_u - off).max(), np.abs(fr - th_r - off).max()) / dstar
        print(f"| {n} | {m} | {r['x']:.3f} | {r['P_range'][0]:.5g}–{r['P_range'][1]:.5g} | {r['area']:.4e} | "
              f"{r['work_loop']:.4e} | {r['work']:.4e} | {r['dW']:.4e} | {r['area'] / r['dW']:.3f} | "
              f"{r['work'] / r['dW']:.3f} | {err:.3f} | {r['a']:.4f} | {r['a_fe']:.4f} | "
              f"{r['area'] / r['dW_fe']:.3f} |", flush=True)
        last = r
    if fig:
        figure(last, fig)


if __name__ == "__main__":
    main(sys.argv[1:])
