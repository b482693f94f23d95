"""The discretised elastic body of a configuration: design space → mesh → A(α), L(α).

``ElasticModel`` owns everything that does not change with α (surface, admissible set, mesh
topology, the CSR pattern, the contact DOFs) and produces, for a design α, the stiffness A(α) and
load L(α) on the free DOFs, plus the design-derivative contraction vᵀ(∂A/∂α u − ∂L/∂α)
(DESIGN.md §2) without ever forming ∂A/∂α_k.

Contact ordering: contact node m (mesh node set ``contact``) owns the condensed DOFs
3m, 3m+1, 3m+2 = (u1, u2, u3) = (tangent t1, tangent t2, normal ν) — the foundation is the
half-space x3 ≤ 0 with outward normal e3 of the foundation, so u_ν = u3 and the gap is
g_m = ϑ_α(x'_m) (non-penetration u_ν + g ≥ 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..config import Config, load_config
from ..design.admissible import AdmissibleSet
from ..design.bezier import BezierSurface
from ..mesh.hexmesh import HexMesh
from .elasticity import ElasticityAssembler
from .loads import body_load, body_load_shape_contraction, surface_load, surface_load_shape_contraction


@dataclass
class Assembled:
    """A(α) and L(α) for one design: ``A`` on free DOFs, ``L`` full-length, ``coords`` of the nodes."""

    alpha: np.ndarray
    coords: np.ndarray
    A: sp.csr_matrix
    L_full: np.ndarray
    L: np.ndarray          # on the free DOFs
    gap: np.ndarray        # g = ϑ_α at the contact nodes


class ElasticModel:
    """Design-independent part of the discrete problem of a configuration."""

    def __init__(self, config):
        cfg = load_config(config) if not isinstance(config, Config) else config
        self.config = cfg
        g, d = cfg["geometry"], cfg["design"]
        d1, d2 = d["degree"]
        self.surface = BezierSurface(d1, d2, g["a"], g["b"])
        self.admissible = AdmissibleSet(d1, d2, g["a"], g["b"], d["C0"], d["C1"], d["C2"], d["slope_divisor"])
        m = cfg["mesh"]
        self.mesh = HexMesh(m["nx"], m["ny"], m["nz"], self.surface, g["c"])
        clamped = self.mesh.node_sets["clamped"]
        fixed = (3 * clamped[:, None] + np.arange(3)).ravel()
        mat = cfg["material"]
        self.assembler = ElasticityAssembler(self.mesh.elements, self.mesh.n_nodes, fixed, mat["E"], mat["nu"])
        self.contact_nodes = self.mesh.node_sets["contact"]
        full = (3 * self.contact_nodes[:, None] + np.arange(3)).ravel()
        self.contact_dofs = self.assembler.full_to_free[full]
        assert np.all(self.contact_dofs >= 0)
        self.gap_matrix = self.mesh.gap_matrix()
        self._dx3 = self.mesh.dx3_dalpha()
        loads = cfg["loads"]
        self.tractions = [(self.mesh.faces["top"], np.array(loads["top_traction"], float)),
                          (self.mesh.faces["right"], np.array(loads["right_traction"], float))]
        self.body_force = np.array(loads["body_force"], float)

    @property
    def n_contact(self) -> int:
        return self.contact_nodes.size

    @property
    def n_design(self) -> int:
        return self.surface.size

    def initial_design(self) -> np.ndarray:
        """α0 of the configuration (a scalar fills every control point)."""
        init = self.config["design"]["initial"]
        if np.isscalar(init):
            return np.full(self.n_design, float(init))
        return self.surface.as_vector(init)

    def load_vector(self, coords: np.ndarray) -> np.ndarray:
        """Full-length L(α) = tractions + body force."""
        L = np.zeros(3 * self.mesh.n_nodes)
        for quads, t in self.tractions:
            if np.any(t):
                L += surface_load(coords, quads, t)
        if np.any(self.body_force):
            a = self.assembler
            L += body_load(coords, self.mesh.elements, a.N, a.dN, a.w, self.body_force)
        return L

    def assemble(self, alpha) -> Assembled:
        """A(α), L(α) and the gaps for a design (no feasibility check against U here)."""
        alpha = self.surface.as_vector(alpha)
        coords = self.mesh.coordinates(alpha)
        A = self.assembler.stiffness(coords)
        L_full = self.load_vector(coords)
        return Assembled(alpha, coords, A, L_full, L_full[self.assembler.free], self.gap_matrix @ alpha)

    def design_contraction(self, coords: np.ndarray, u_full: np.ndarray, v_full: np.ndarray) -> np.ndarray:
        """vᵀ(∂A/∂α_k u − ∂L/∂α_k) for every design variable k (full-length u, v; DESIGN.md §2).

        Only the x3 coordinates move with α: ∂x3/∂α = β^i β^j (1 − s).
        """
        d = self.assembler.stiffness_shape_contraction(coords, u_full, v_full)
        for quads, t in self.tractions:
            if np.any(t):
                d -= surface_load_shape_contraction(coords, quads, t, v_full)
        if np.any(self.body_force):
            a = self.assembler
            d -= body_load_shape_contraction(coords, self.mesh.elements, a.N, a.dN, a.w, self.body_force, v_full)
        return self._dx3.T @ d[:, 2]
