"""The discretised elastic body of a configuration: design space → mesh → A(α), L(α).

``ElasticModel`` owns everything that does not change with α (the body and its parts, surface,
admissible set, the reference mesh and its morph, the CSR pattern, the contact DOFs) and
produces, for a design α, the stiffness A(α) and load L(α) on the free DOFs, plus the
design-derivative contraction vᵀ(∂A/∂α u − ∂L/∂α) (DESIGN.md §2) without ever forming ∂A/∂α_k.

One geometry path (DESIGN.md §9): a reference mesh (the block, or a mesh file) with its contact
face on x3 = 0, moved by x(α) = x_ref + ϑ_α(x1, x2)·w·e3 with a harmonic weight w
(:mod:`contactopt.mesh.morph`, :mod:`contactopt.fem.weight`).

Contact ordering: contact node m (the nodes of the contact face with no clamped component, by
node number) owns the condensed DOFs 3m, 3m+1, 3m+2 = (u1, u2, u3) = (tangent t1, tangent t2,
normal ν) — the foundation is the half-space x3 ≤ 0 with outward normal e3 of the foundation, so
u_ν = u3 and the gap is g_m = ϑ_α(x'_m) (non-penetration u_ν + g ≥ 0).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .._threads import sequential_openblas
from ..config import Config, load_config
from ..design.admissible import AdmissibleSet
from ..design.bezier import BezierSurface
from ..errors import ConfigError
from ..mesh.body import build_body
from ..mesh.hexmesh import HexMesh
from ..mesh.morph import JacobianRatio, MorphedMesh
from .elasticity import BBAR_AUTO_NU, ElasticityAssembler, element_geometry, resolve_formulation
from .elements import element_type
from .loads import face_areas_nodal
from .loadset import load_set
from .weight import harmonic_weight

log = logging.getLogger(__name__)


@dataclass
class Assembled:
    """A(α) and L(α) for one design: ``A`` on free DOFs, ``L`` full-length, ``coords`` of the nodes."""

    alpha: np.ndarray
    coords: np.ndarray
    A: sp.csr_matrix
    L_full: np.ndarray
    L: np.ndarray          # on the free DOFs
    gap: np.ndarray        # g = ϑ_α (+ the height of the face in the mesh) at the contact nodes


class ElasticModel:
    """Design-independent part of the discrete problem of a configuration."""

    def __init__(self, config, *, body=None, memory_estimate=None):
        """``body``: the configuration's body if already built; ``memory_estimate``: the peak
        memory estimate (a function of the body) of the solver path that will run, checked
        against the memory available before anything costly is built (the condensation's by
        default)."""
        cfg = load_config(config) if not isinstance(config, Config) else config
        self.config = cfg
        self.body = body = build_body(cfg) if body is None else body
        formulation = _formulation(cfg, body.reference.cell_type)
        check = None
        if cfg["linear_solver"]["memory_check"]:   # refuse a mesh too large before building on it
            from .memory import check_memory
            est = check_memory(body, estimate=memory_estimate)

            def check(extra):                      # an elastic foundation's part, held beside it
                return check_memory(body, estimate=lambda b: est.with_parts(extra))
        ref = body.reference
        d = cfg["design"]
        d1, d2 = d["degree"]
        (x1lo, x1hi), (x2lo, x2hi) = body.domain
        a, b = x1hi - x1lo, x2hi - x2lo
        self.surface = BezierSurface(d1, d2, a, b, x1lo, x2lo)
        self.admissible = AdmissibleSet(d1, d2, a, b, d["C0"], d["C1"], d["C2"], d["slope_divisor"])
        mat = cfg["material"]
        self.assembler = ElasticityAssembler(ref.cells, ref.n_nodes, body.fixed_dofs, mat["E"], mat["nu"],
                                             element=element_type(ref.cell_type),
                                             formulation=formulation)
        self._check_reference(ref)
        zero = np.concatenate([np.asarray(v, np.int64) for v in body.fixed_shape.values()] or [np.zeros(0, np.int64)])
        self.weight = harmonic_weight(self.assembler, ref.points, body.contact_face.nodes, zero)
        if cfg["body"]["mesh"]:
            self.mesh = MorphedMesh(ref, self.surface, self.weight, body.contact_nodes,
                                    fixed_shape=tuple(body.fixed_shape))
        else:
            m = cfg["mesh"]
            self.mesh = HexMesh(m["nx"], m["ny"], m["nz"], self.surface, cfg["geometry"]["c"], reference=ref,
                                weight=self.weight, contact_nodes=body.contact_nodes,
                                fixed_shape=tuple(body.fixed_shape))
        self.mesh.ratio = self._jacobian_ratio(ref, body)
        self.contact_nodes = body.contact_nodes
        full = (3 * self.contact_nodes[:, None] + np.arange(3)).ravel()
        self.contact_dofs = self.assembler.full_to_free[full]
        assert np.all(self.contact_dofs >= 0)
        self.gap_matrix = self.mesh.gap_matrix()
        # initial gap of a contact face above x3 = 0 (body.initial_gap = "mesh"); 0 on the plane
        self.gap0 = (ref.points[self.contact_nodes, 2].copy() if cfg["body"].get("initial_gap") == "mesh"
                     else np.zeros(self.contact_nodes.size))
        self.loads = load_set(body, cfg["loads"])
        self.body_force = self.loads.body_force
        self.foundation = None      # [foundation]: the elastic foundation under the contact face
        if "foundation" in cfg.data:
            from .foundation import Foundation
            self.foundation = Foundation(cfg, body, check=check)

    # ------------------------------------------------------------------ checks
    def _check_reference(self, ref) -> None:
        """The reference mesh as given must not be inverted (det J > 0 at every quadrature point)."""
        det = self.assembler.jacobian_determinants(ref.points)
        if not np.all(det > 0):
            bad = np.unique(np.nonzero(~(det > 0))[0])
            e = int(bad[0])
            raise ConfigError([f"{ref.source}: the mesh is inverted as given: {bad.size} of {ref.n_cells} element(s) "
                               f"have det J ≤ 0, first element {e} at {_fmt(ref.points[ref.cells[e]].mean(axis=0))}"
                               " (node order of the cells: meshio/VTK)"])
        self._det_ref = det

    def _jacobian_ratio(self, ref, body) -> JacobianRatio:
        """det J(α)/det J_ref = 1 + Rα (mesh.morph); C0 must keep it above the threshold on U."""
        G, _ = element_geometry(ref.points[ref.cells], self.assembler.dN)
        centroids = ref.points[ref.cells].mean(axis=1)
        thr = self.config["body"]["min_jacobian_ratio"]
        jr = JacobianRatio(ref.cells, G[..., 2], self.mesh.dx3_dalpha(), thr, qpoints=centroids,
                           fixed_parts={name: nodes for name, nodes in body.fixed_shape.items()})
        C0 = self.config["design"]["C0"]
        worst, e, _, _ = jr.worst_on_box(C0)
        self.safe_C0 = jr.safe_C0()
        if worst <= thr:
            raise ConfigError([f"{self.config.source}: design.C0 = {C0:g} lets admissible designs "
                               f"{'invert' if worst <= 0 else 'distort'} element {e} at {_fmt(centroids[e])} "
                               f"(Jacobian ratio down to {worst:.3g} ≤ body.min_jacobian_ratio = {thr:g}); "
                               f"the largest safe C0 for this mesh and morph is {self.safe_C0:.4g}"])
        return jr

    # ------------------------------------------------------------------ sizes
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

    def contact_areas(self) -> np.ndarray:
        """Tributary areas ∫N_m dS of the contact nodes on the (flat) reference contact face, which
        turn a contact stress σ into nodal forces λ_m ≈ σ(x'_m)·A_m: the consistent nodal forces
        of a uniform stress (on six-node triangles they vanish at the corners, as do the nodal
        forces of a uniform pressure)."""
        ref = self.body.reference
        areas = face_areas_nodal(ref.points, self.body.contact_face.faces, face=self.assembler.element.face)
        return areas[self.contact_nodes]

    # ------------------------------------------------------------------ A(α), L(α)
    def load_vector(self, coords: np.ndarray, loads=None) -> np.ndarray:
        """Full-length L(α) of a load set (default: the configuration's ``[loads]``)."""
        return (loads or self.loads).vector(coords, self.assembler)

    def assemble(self, alpha, loads=None) -> Assembled:
        """A(α), L(α) and the gaps for a design (no feasibility check against U here).

        Assembled on one OpenBLAS thread wherever it is called: the element kernels' matrix
        products are split differently over threads, and on some CPUs (AMD, OpenBLAS's Haswell and
        Prescott kernels) that changes A in its last bits, so a checkpoint's design rebuilt outside
        a state solve would not give the matrix the uninterrupted run had."""
        alpha = self.surface.as_vector(alpha)
        with sequential_openblas():
            coords = self.mesh.coordinates(alpha)
            A = self.assembler.stiffness(coords)
            L_full = self.load_vector(coords, loads)
        return Assembled(alpha, coords, A, L_full, L_full[self.assembler.free],
                         self.gap_matrix @ alpha + self.gap0)

    def design_contraction(self, coords: np.ndarray, u_full: np.ndarray, v_full: np.ndarray, loads=None) -> np.ndarray:
        """vᵀ(∂A/∂α_k u − ∂L/∂α_k) for every design variable k (full-length u, v; DESIGN.md §2).

        Only the x3 coordinates move with α: ∂x3/∂α_k = β_k(x1, x2)·w (mesh.morph).
        """
        d = self.assembler.stiffness_shape_contraction(coords, u_full, v_full)
        d -= (loads or self.loads).shape_contraction(coords, v_full, self.assembler)
        return self.mesh.contract_dx3(d[:, 2])


def _formulation(cfg, cell_type) -> str:
    """The element formulation of ``[material] formulation`` on the mesh's cells; ConfigError if
    the mesh's element type does not take it."""
    mat = cfg["material"]
    form = mat.get("formulation", "auto")
    try:
        resolved = resolve_formulation(form, cell_type, mat["nu"])
    except ValueError:
        raise ConfigError([f"{cfg.source}: material.formulation = {form!r}: B-bar is a formulation of hexahedra; "
                           f"the mesh has {cell_type} cells, which take 'standard' (or 'auto'). For a nearly "
                           "incompressible material on tetrahedra use quadratic ones (tetra10), which lock far "
                           "less than linear ones; from ν ≈ 0.49 on, hexahedra with 'bbar' "
                           "(docs/materials.md)"]) from None
    if cell_type == "tetra" and mat["nu"] >= BBAR_AUTO_NU:
        log.warning("%s: linear tetrahedra lock at ν = %g (too stiff, contact pressures too high); use "
                    "quadratic tetrahedra (tetra10) or hexahedra with material.formulation = 'auto'",
                    cfg.source, mat["nu"])
    elif resolved != "standard" or mat["nu"] >= BBAR_AUTO_NU:
        log.info("element formulation: %s (%s cells, ν = %g)", resolved, cell_type, mat["nu"])
    return resolved


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.asarray(x)) + ")"
