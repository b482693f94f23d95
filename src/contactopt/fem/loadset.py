"""A set of loads on named parts of the body: L(α) and its design-derivative contraction.

One load set is what ``[loads]`` of a configuration describes (and, with load cases, each case):

- tractions t (force per unit area, a fixed vector in the global frame) on parts,
  ``[[loads.traction]] on = <part>, value = [t1, t2, t3]``; the block's ``top_traction`` and
  ``right_traction`` are tractions on its parts ``top`` and ``right``;
- pressures p on parts, ``[[loads.pressure]] on = <part>, value = p``: the traction −p n with n
  the outward unit normal of the current (moved) face, so p > 0 pushes into the body;
- a body force f per unit volume in Ω(α).

Every term is integrated on the current geometry x(α) (paper (2.9)) and differentiated exactly
with respect to the node coordinates. Vectors are full length, DOF 3n + m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from . import loads as L


@dataclass
class LoadSet:
    """Loads resolved to faces: ``tractions`` [(name, faces, t)], ``pressures`` [(name, faces, p)],
    ``body_force`` (3,)."""

    tractions: list = field(default_factory=list)
    pressures: list = field(default_factory=list)
    body_force: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __add__(self, other: "LoadSet") -> "LoadSet":
        """Both sets acting together (a load case: the common ``[loads]`` plus the case's own)."""
        return LoadSet(self.tractions + other.tractions, self.pressures + other.pressures,
                       self.body_force + other.body_force)

    def scaled(self, t: float) -> "LoadSet":
        """Every load times ``t`` (a substep of a load step interpolates linearly between two sets)."""
        return LoadSet([(n, f, t * v) for n, f, v in self.tractions], [(n, f, t * v) for n, f, v in self.pressures],
                       t * self.body_force)

    def vector(self, coords: np.ndarray, assembler) -> np.ndarray:
        """Full-length L(α) for the node coordinates ``coords``."""
        out = np.zeros(coords.size)
        a = assembler
        for _, faces, t in self.tractions:
            if np.any(t):
                out += L.surface_load(coords, faces, t, face=a.element.face)
        for _, faces, p in self.pressures:
            if p != 0.0:
                out += L.pressure_load(coords, faces, p, face=a.element.face)
        if np.any(self.body_force):
            out += L.body_load(coords, a.elements, self.body_force, element=a.element)
        return out

    def shape_contraction(self, coords: np.ndarray, v_full: np.ndarray, assembler) -> np.ndarray:
        """vᵀ ∂L/∂x_{c,m} for every node c and coordinate m: array (n_nodes, 3)."""
        out = np.zeros((coords.shape[0], 3))
        a = assembler
        for _, faces, t in self.tractions:
            if np.any(t):
                out += L.surface_load_shape_contraction(coords, faces, t, v_full, face=a.element.face)
        for _, faces, p in self.pressures:
            if p != 0.0:
                out += L.pressure_load_shape_contraction(coords, faces, p, v_full, face=a.element.face)
        if np.any(self.body_force):
            out += L.body_load_shape_contraction(coords, a.elements, self.body_force, v_full, element=a.element)
        return out


def load_set(body, loads, where: str = "loads") -> LoadSet:
    """Resolve loads in the form of ``[loads]`` (:class:`~contactopt.config.Loads`: of the
    configuration, a load case, a load step or the foundation) on the parts of ``body``; a load
    not given is none."""
    problems = []
    out = LoadSet(body_force=np.array(loads.body_force if loads.body_force is not None else [0.0, 0.0, 0.0], float))
    entries = [("traction", name, value, f"{where}.{name}_traction")
               for name, value in (("top", loads.top_traction), ("right", loads.right_traction)) if value is not None]
    entries += [("traction", e.on, e.value, f"{where}.traction[{i}]") for i, e in enumerate(loads.traction)]
    entries += [("pressure", e.on, e.value, f"{where}.pressure[{i}]") for i, e in enumerate(loads.pressure)]
    for kind, on, given, key in entries:
        value = np.array(given, float) if kind == "traction" else float(given)
        if not np.any(value):
            continue
        try:
            part = body.part(on)
        except ConfigError as exc:
            problems += [f"{key}: {p}" for p in exc.problems]
            continue
        if part.faces.shape[0] == 0:
            problems.append(f"{key}: part {part.name} has no boundary faces to carry a {kind}")
            continue
        (out.tractions if kind == "traction" else out.pressures).append((part.name, part.faces, value))
    if problems:
        raise ConfigError(problems)
    return out
