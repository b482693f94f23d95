"""The meshes of examples/roller_bearing.toml: a segment of a cylindrical roller bearing, a half model.

    python examples/roller_bearing/make_mesh.py     # writes roller.msh, inner.msh, outer.msh here

The bearing's axis is the x2 axis; the roller (radius RHO, length LEN along x2) lies between the
inner race (outer radius R_IN) and the outer race (inner radius R_IN + 2 RHO), its axis at
x3 = R_IN + RHO. The half x1 ≥ 0 of everything is meshed (the plane x1 = 0 through both axes is a
symmetry plane). The roller is the cross-section of examples/roller_plates/make_mesh.py extruded along
x2 in elements graded towards both ends (where a straight roller's pressure peaks); each race is a
sector θ in [0, THETA] (from +x3 towards +x1) of an annulus of thickness T, graded towards θ = 0 and
its contact surface, and longer than the roller by OVERHANG at both ends. Groups of the roller: ``lower``, ``upper`` (the strips of its face at the inner
and the outer race), ``face`` (both), ``sym`` (x1 = 0), ``roller``. Groups of a race: ``surface`` (its contact
surface), ``back`` (the opposite one), ``sym``, ``ends`` (x2 = −OVERHANG and LEN + OVERHANG), ``race``.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
R_IN, RHO, LEN, T, THETA = 20.0, 5.0, 20.0, 6.0, 0.3
OVERHANG = 4.0          # the races reach this far beyond the roller's ends


def _plates():
    spec = importlib.util.spec_from_file_location("roller_plates_mesh", HERE.parent / "roller_plates" / "make_mesh.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def axial(n):
    """n + 1 points on [0, LEN], symmetric, finer towards both ends."""
    half = np.cumsum(1.2 ** np.arange(n // 2)[::-1])
    half = np.r_[0.0, half / half[-1]] * LEN / 2
    return np.unique(np.r_[half, LEN - half[::-1]])


def extruded(xz, quads, y):
    """Hexahedra over the cross-section (x1, x3) between the planes x2 = y[i], y[i+1]."""
    m, n = len(xz), len(y)
    pts = np.vstack([np.c_[xz[:, 0], np.full(m, v), xz[:, 1]] for v in y])
    layer = (np.arange(n - 1) * m)[:, None, None]
    hexes = np.concatenate([layer + quads[:, [0, 3, 2, 1]], layer + m + quads[:, [0, 3, 2, 1]]], axis=2).reshape(-1, 8)
    c = pts[hexes]
    vol = np.einsum("ij,ij->i", c[:, 1] - c[:, 0], np.cross(c[:, 3] - c[:, 0], c[:, 4] - c[:, 0]))
    flip = vol < 0
    hexes[flip] = np.concatenate([layer + quads, layer + m + quads], axis=2).reshape(-1, 8)[flip]
    return pts, hexes


def roller(mod, n_strip, n_ax, strip):
    mod.R, mod.LEN = RHO, LEN
    yz, quads = mod._quarter(n_strip)
    up = np.c_[yz[:, 0], 2 * RHO - yz[:, 1]]
    xz = np.vstack([yz, up])
    q = np.vstack([quads, quads[:, ::-1] + len(yz)])
    _, first, inverse = np.unique(np.round(xz / RHO, 9), axis=0, return_index=True, return_inverse=True)
    xz, q = xz[first], inverse.reshape(-1)[q]
    pts, hexes = extruded(xz + [0.0, R_IN], q, axial(n_ax))
    bnd = mod.boundary(hexes)
    c = pts[bnd]
    tol = 1e-9 * RHO
    on_face = np.all(np.abs(np.hypot(c[..., 0], c[..., 2] - R_IN - RHO) - RHO) < 1e-6 * RHO, axis=1)
    near = np.all(c[..., 0] < strip + tol, axis=1)
    low = on_face & near & np.all(c[..., 2] < R_IN + RHO, axis=1)
    high = on_face & near & np.all(c[..., 2] > R_IN + RHO, axis=1)
    groups = {"lower": bnd[low], "upper": bnd[high], "face": bnd[low | high],
              "sym": bnd[np.all(c[..., 0] < tol, axis=1)]}
    return pts, hexes, groups


def race(mod, r0, r1, surface_r, n_r, n_ax, h):
    """A sector of the annulus r0 ≤ r ≤ r1, θ in [0, THETA], graded towards θ = 0 and r = surface_r."""
    theta = mod.graded(h / surface_r, 1.0, THETA, growth=1.25)
    s = np.linspace(0.0, 1.0, n_r + 1) ** 1.6              # finer at the contact surface
    r = np.sort(r1 - (r1 - r0) * s if surface_r == r1 else r0 + (r1 - r0) * s)
    R, TH = np.meshgrid(r, theta, indexing="ij")
    xz = np.c_[(R * np.sin(TH)).ravel(), (R * np.cos(TH)).ravel()]
    n1, n2 = r.size, theta.size
    i = np.arange(n1 * n2).reshape(n1, n2)
    q = np.c_[i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()]
    y = axial(n_ax)
    out = np.cumsum(np.diff(y[:2]) * 1.4 ** np.arange(1, 12))
    out = out[out < OVERHANG]
    y = np.r_[-OVERHANG, -out[::-1], y, LEN + out, LEN + OVERHANG]   # longer than the roller
    pts, hexes = extruded(xz, q, y)
    bnd = mod.boundary(hexes)
    c = pts[bnd]
    rad = np.hypot(c[..., 0], c[..., 2])
    tol = 1e-9 * r1
    other = r0 if surface_r == r1 else r1
    groups = {"surface": bnd[np.all(np.abs(rad - surface_r) < 1e-7 * r1, axis=1)],
              "back": bnd[np.all(np.abs(rad - other) < 1e-7 * r1, axis=1)],
              "sym": bnd[np.all(c[..., 0] < tol, axis=1)],
              "ends": bnd[np.all((c[..., 1] < tol - OVERHANG) | (c[..., 1] > LEN + OVERHANG - tol), axis=1)]}
    return pts, hexes, groups


def main(out=HERE, n_strip=8, n_ax=12, h=0.25, strip=1.5):
    """Writes the three meshes into ``out``: ``n_strip`` elements across the roller's contact strips,
    ``n_ax`` along its length, ``h`` the races' element size at the contact line."""
    out = Path(out)
    mod = _plates()
    mod.write(out / "roller.msh", *roller(mod, n_strip, n_ax, strip), "roller")
    mod.write(out / "inner.msh", *race(mod, R_IN - T, R_IN, R_IN, 5, n_ax, h), "race")
    mod.write(out / "outer.msh", *race(mod, R_IN + 2 * RHO, R_IN + 2 * RHO + T, R_IN + 2 * RHO, 5, n_ax, h), "race")
    return out


if __name__ == "__main__":
    print(main(*sys.argv[1:2]))
