"""The discretised elastic body of a configuration: design space → mesh → A(α), L(α).

``ElasticModel`` owns everything that does not change with α (the body and its parts, surface,
admissible set, the reference mesh and its morph, the CSR pattern, the contact DOFs) and
produces, for a design α, the stiffness A(α) and load L(α) on the free DOFs, plus the
design-derivative contraction vᵀ(∂A/∂α u − ∂L/∂α) without ever forming ∂A/∂α_k.

One geometry path: a reference mesh (the block, or a mesh file) with its contact
face on x3 = 0, moved by x(α) = x_ref + ϑ_α(x1, x2)·w·e3 with a harmonic weight w
(:mod:`contactopt.mesh.morph`, :mod:`contactopt.fem.weight`).

Contact ordering: contact node m (the nodes of the contact face whose normal component is not
clamped, by node number) owns the condensed DOFs 3m, 3m+1, 3m+2 = (u1, u2, u3) = (tangent t1,
tangent t2, normal ν) — the foundation is the half-space x3 ≤ 0 with outward normal e3 of the foundation, so
u_ν = u3 and the gap is g_m = ϑ_α(x'_m) (non-penetration u_ν + g ≥ 0).

A clamped tangential component of a contact node (a symmetry plane through the contact face,
:mod:`contactopt.mesh.body`) is a *pinned* DOF: a free DOF whose row and column of A(α) keep only
the diagonal entry and whose load is zero, so that the contact DOF layout stays three per node on
every path. The Coulomb law then gives u = 0 and a zero contact force there, the paths set both
exactly (:attr:`ElasticModel.contact_pinned`), and the design contraction sees u = ṽ = 0 on
them: the rows and columns of A(α) it differentiates are the clamped ones.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._threads import sequential_openblas
from ..config import Config, load_config
from ..design.admissible import AdmissibleSet
from ..design.bezier import BezierSurface
from ..design.chart import motion_directions
from ..design.several import DesignSurfaces, ProductAdmissible, surfaces_of
from ..errors import ConfigError
from ..mesh.block import block_axes
from ..mesh.body import Body, build_body
from ..mesh.hexmesh import HexMesh
from ..mesh.morph import JacobianRatio, MorphedMesh
from ..mesh.obstacle import Obstacle, contact_frames, make_obstacle, tangent_frames
from .counterparts import build_counterparts
from .cpdesigns import PaddedMorph, build_counterpart_designs, padded_ratio
from .designs import design_surfaces, design_weights, initial_designs, several_morphs
from .elasticity import BBAR_AUTO_NU, ElasticityAssembler, element_geometry, resolve_formulation
from .elements import element_type, face_type
from .foundation import Foundation
from .loads import face_areas_nodal
from .loadset import LoadSet, load_set
from .memory import InsufficientMemoryError, PathEstimates, check_memory
from .mortar import dual_weighted
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


@dataclass(frozen=True)
class ObstacleForce:
    """A force-controlled obstacle (``[obstacle] control = "force"``) seen from the contact nodes: it
    translates by s f̂ along its force f of length ``magnitude``; per contact node m ``b`` (p, 3) =
    R_mᵀ f̂ in the node's frame (t1, t2, n), so that the resultant along f̂ is Σ_m b_m·r_m (r_m the
    force on the body in that frame), and ``gap_rate`` (p,) = f̂·n_m, by which the gap g_m falls per
    unit of s (:mod:`contactopt.paths.force`).

    A force-controlled elastic foundation (``[foundation] control = "force"``) translates the same
    way: its partners move by ``motion`` (p, 3) per unit s (Π f̂ per node frame, b_m where the
    partner weights sum to one); ``gap_rate`` is then motion's normal part. None: the counterpart
    is rigid and moves by b_m under every node."""

    magnitude: float
    b: np.ndarray
    gap_rate: np.ndarray
    motion: np.ndarray | None = None

    @property
    def slip(self) -> np.ndarray:
        """(3p,) the tangential translation under each contact node per unit s (per node (t1, t2, n),
        normal parts 0): the law sees w = u_c − s·slip."""
        m = self.b if self.motion is None else self.motion
        return (m * [1.0, 1.0, 0.0]).ravel()


@dataclass(init=False, eq=False, repr=False)
class ElasticModel:
    """Design-independent part of the discrete problem of a configuration.

    The optional parts are None where the configuration has none: ``obstacle`` (absent: the fixed
    plane x3 = 0), ``frames`` (p, 3, 3) per contact node with columns (t1, t2, n) on an obstacle
    other than the plane (absent: the axes (e1, e2, e3)), ``slip_shift`` (p, 3) the tangential part
    of an obstacle's prescribed translation per node frame (normal parts 0), ``obstacle_force`` a
    force-controlled obstacle's :class:`ObstacleForce`, ``foundation`` an elastic ``[foundation]``
    under the contact face."""

    config: Config
    body: Body
    surface: BezierSurface
    assembler: ElasticityAssembler
    weight: np.ndarray
    mesh: MorphedMesh
    obstacle: Obstacle | None
    frames: np.ndarray | None
    slip_shift: np.ndarray | None
    obstacle_force: ObstacleForce | None
    admissible: AdmissibleSet
    safe_C0: float
    contact_nodes: np.ndarray        # (p,) node numbers of the contact nodes
    contact_dofs: np.ndarray         # (3p,) their free DOFs, per node (t1, t2, ν)
    pinned_dofs: np.ndarray          # full DOF indices of the clamped tangential components
    pinned_free: np.ndarray          # ... as free DOFs
    pinned_columns: np.ndarray | None   # per pinned DOF its frame column, where a pinned u3 is a tangent
    contact_pinned: np.ndarray       # (p, 3) True on the pinned components (t1, t2, ν)
    contact_pinned_global: np.ndarray   # ... in global components (u1, u2, u3)
    contact_friction: np.ndarray | None  # (p,) Coulomb coefficient F_m per contact node; None: [friction]'s
    gap_matrix: object               # g = gap_matrix α + gap0 at the contact nodes
    gap0: np.ndarray
    loads: LoadSet
    body_force: object
    foundation: Foundation | None
    _det_ref: np.ndarray             # det J of the reference mesh at its quadrature points
    _pin_mask: tuple | None          # ((shape, nnz) of A's pattern, the CSR entries pinning zeroes)

    def __init__(self, config, *, body=None, memory_estimate=None, condensed: bool = True):
        """``body``: the configuration's body if already built; ``memory_estimate``: the peak
        memory estimate (a function of the body and its elastic counterparts' sizes, keyword
        ``counterparts``) of the solver path that will run, or a
        :class:`~contactopt.fem.memory.PathEstimates` with those of the other paths that take the
        model (a refusal names them), checked against the memory available before anything costly
        is built: the body's first, then again as each counterpart's mesh is read, with every
        counterpart read so far (the condensation's by default); ``condensed=False``: an elastic
        foundation is kept assembled, not condensed onto its support (the full-space path's,
        :class:`~contactopt.fem.foundation.Foundation`)."""
        self._condensed = condensed
        cfg = load_config(config) if not isinstance(config, Config) else config
        self.config = given = cfg
        cfg = cfg.face_body_designs()         # the counterparts' designs: fem.cpdesigns, at the end
        self.body = body = build_body(cfg) if body is None else body
        formulation = _formulation(cfg.material, body.reference.cell_type, cfg.source)
        check = None
        if cfg.linear_solver.memory_check:   # refuse a mesh too large before building on it
            paths = memory_estimate if isinstance(memory_estimate, PathEstimates) else PathEstimates(memory_estimate)
            try:
                check_memory(body, estimate=paths.run, alternatives=paths.others, path=paths.name)
            except InsufficientMemoryError:
                # an elastic [foundation], read next, only adds to the estimate of every path: the
                # refusal waits for its sizes (its mesh, before K_f is assembled), so that the path it
                # names as fitting is measured with the foundation counted, not the body alone
                if cfg.foundation is None or cfg.pairs:
                    raise
            counted = []

            def check(size):                       # an elastic counterpart, with those before it
                counted.append(size)
                return check_memory(body, estimate=paths.run, counterparts=counted, alternatives=paths.others,
                                    path=paths.name)
        ref = body.reference
        d1, d2 = cfg.design.degree
        (x1lo, x1hi), (x2lo, x2hi) = body.domain
        a, b = x1hi - x1lo, x2hi - x2lo
        self.surface = BezierSurface(d1, d2, a, b, x1lo, x2lo) if not body.designs else design_surfaces(cfg, body)
        self.face_surface = self.surface      # the face body's designs (α's first block, fem.cpdesigns)
        mat = cfg.material
        self.assembler = ElasticityAssembler(ref.cells, ref.n_nodes, body.fixed_dofs, mat.E, mat.nu,
                                             element=element_type(ref.cell_type),
                                             formulation=formulation)
        self._check_reference(ref)
        zero = np.concatenate([np.asarray(v, np.int64) for v in body.fixed_shape.values()] or [np.zeros(0, np.int64)])
        if body.designs:          # several designed faces: a weight per face, one morph (fem.designs)
            self.weight = design_weights(self.assembler, body, zero)
        else:
            self.weight = harmonic_weight(self.assembler, ref.points, body.contact_face.nodes, zero)
        chart = {}            # a chart of the face and normal motion (design.chart); none: the paper's map
        if body.chart is not None:
            chart["chart"] = body.chart
        if cfg.design.motion == "normal":
            chart["directions"] = motion_directions(ref.points, body.contact_face, ref.face_type, body.chart)
        if body.designs:
            self.mesh = several_morphs(cfg, body, self.surface, self.weight)
        elif cfg.body.mesh:
            self.mesh = MorphedMesh(ref, self.surface, self.weight, body.contact_nodes,
                                    fixed_shape=tuple(body.fixed_shape), **chart)
        else:
            nx, ny, nz = (x.size - 1 for x in block_axes(cfg.geometry, cfg.mesh))
            self.mesh = HexMesh(nx, ny, nz, self.surface, cfg.geometry.c, reference=ref,
                                weight=self.weight, contact_nodes=body.contact_nodes,
                                fixed_shape=tuple(body.fixed_shape), **chart)
        self.obstacle = self.frames = self.slip_shift = self.obstacle_force = None     # set by _obstacle*
        self.pinned_columns = None  # per pinned DOF its frame column, where a pinned u3 is a tangent
        face_frames = self._obstacle(cfg.obstacle, ref, body)
        self.foundation = None      # [foundation]: the elastic foundation under the contact face
        rigid = self._rigid_pairs(cfg, ref, body)      # several pairs, some against rigid counterparts
        self.pair_of = body.pair_of   # (p,) the pair of each row of the law (rows b: fem.faces)
        self._p_off = 0               # rows b: the contact nodes of faces off the face body (fem.faces)
        if (cfg.foundation is not None or cfg.pairs) and (body.chart is not None or body.pair_charts or cfg.off_faces):
            self._curved_foundation(cfg, ref, body, check, rigid)
        elif rigid and any(np.abs(R - np.eye(3)).max() > 0 for _, rows, R, _ in rigid.values()):
            self._set_frames(ref, body, np.broadcast_to(np.eye(3), (body.contact_nodes.size, 3, 3)).copy(), rigid,
                             "rigid counterpart")
        self.admissible = self._admissible_set(ref, body, face_frames)
        self.mesh.ratio = self._jacobian_ratio(ref, body)
        self.contact_nodes = body.contact_nodes
        full = (3 * self.contact_nodes[:, None] + np.arange(3)).ravel()
        self.contact_dofs = self.assembler.full_to_free[full]
        assert np.all(self.contact_dofs >= 0)
        self.pinned_dofs = np.asarray(body.pinned_dofs, np.int64)       # full DOF indices
        self.pinned_free = self.assembler.full_to_free[self.pinned_dofs]
        # (p, 3) per contact node (t1, t2, ν): True on the pinned components; in global components
        # (u1, u2, u3) for what is held per DOF of the body (they differ where a clamped component is
        # another column of the node's frame: a pinned u3 that is a tangent, a pinned u2 made t1)
        self.contact_pinned_global = np.isin(full, self.pinned_dofs).reshape(-1, 3)
        self.contact_pinned = self.contact_pinned_global
        if self.pinned_columns is not None:
            node, _ = np.divmod(self.pinned_dofs, 3)
            self.contact_pinned = np.zeros_like(self.contact_pinned_global)
            self.contact_pinned[np.searchsorted(self.contact_nodes, node), self.pinned_columns] = True
        self._pin_mask = None       # ((shape, nnz) of A's pattern, the CSR entries pinning zeroes)
        # several pairs: each contact node's Coulomb coefficient, its pair's (None: [friction] everywhere)
        self.contact_friction = None
        if cfg.pairs:
            mu = np.array([pr.friction for pr in cfg.pairs])[body.pair_of]
            self.contact_friction = None if np.all(mu == cfg.friction.coefficient) else mu
        self.gap_matrix = self.mesh.gap_matrix()
        if body.pair_charts and cfg.assembly.designs and not body.designs:   # pairs off the designed face: the morph leaves them
            self.gap_matrix = self.weight[self.contact_nodes][:, None] * self.gap_matrix
        # initial gap of a contact face above x3 = 0 (body.initial_gap = "mesh"); 0 on the plane
        self.gap0 = (ref.points[self.contact_nodes, 2].copy() if cfg.body.initial_gap == "mesh"
                     else np.zeros(self.contact_nodes.size))
        if face_frames is not None:
            self._obstacle_gap(cfg.obstacle, face_frames)
        if cfg.obstacle is not None and cfg.obstacle.weighting == "mortar":
            self._weighted_gap(cfg.obstacle, ref, body)
        if self.foundation is not None:          # a curved face: gaps along the contact normals
            n = self.frames[:, :, 2]
            self.gap_matrix = self._gap_factor(n, self.contact_nodes)[:, None] * self.gap_matrix
            self.gap0 = self.foundation.gap0.copy()
        elif rigid:                              # on x3 = 0: the rigid pairs' gaps along their obstacles' normals
            for _, rows, R, dist in rigid.values():
                self.gap_matrix[rows] = self._gap_factor(R[:, :, 2], self.contact_nodes[rows])[:, None] * \
                    self.gap_matrix[rows]
                self.gap0[rows] = dist
        if self._p_off:                          # rows b: no design moves them, their gaps are the partners'
            self.gap_matrix = np.vstack([np.asarray(self.gap_matrix, float),
                                         np.zeros((self._p_off, self.gap_matrix.shape[1]))])
            self.contact_pinned = np.vstack([self.contact_pinned, self.foundation.off_pinned])
            self.pair_of = np.concatenate([body.pair_of, self.foundation.off_pairs])
            if cfg.pairs:
                mu = np.array([pr.friction for pr in cfg.pairs])[self.pair_of]
                self.contact_friction = None if np.all(mu == cfg.friction.coefficient) else mu
        self.loads = load_set(body, cfg.loads)
        self.body_force = self.loads.body_force
        if cfg.pairs and self.foundation is None:
            self.foundation = build_counterparts([pr.foundation for pr in cfg.pairs], body, cfg.source, check,
                                                 frames=self.frames, rigid=self._rigid_specs(rigid),
                                                 names=[c.counterpart.split(".")[0] for c in cfg.assembly.contacts],
                                                 condensed=self._condensed)
        if cfg.pairs:
            held = cfg.friction.coefficient if self.contact_friction is None else self.contact_friction
            self.foundation.check_held(held, [p.counterpart.split(".")[0] for p in cfg.assembly.contacts], cfg.source)
        if cfg.pairs:
            self._pair_force(rigid)
        if cfg.foundation is not None and self.foundation is None:
            self.foundation = Foundation(cfg.foundation, body, source=cfg.source, check=check,
                                         condensed=condensed)
            if self.foundation.basis is not None:   # six-node triangles, mortar partners: ĝ = T⁻ᵀ g (fem.mortar)
                lu = spla.splu(sp.csc_matrix(self.foundation.basis.transpose()))
                self.gap_matrix = lu.solve(np.asarray(self.gap_matrix, float))
                self.gap0 = lu.solve(np.asarray(self.gap0, float))
        if cfg.foundation is not None and cfg.foundation.control == "force":
            self._foundation_force(cfg.foundation)
        self.cp_designs = None     # designs on counterpart bodies (fem.cpdesigns)
        if given.counterpart_designs:
            self._counterpart_designs(given)

    def _counterpart_designs(self, cfg) -> None:
        """α = (the face body's designs, the counterparts'): the surfaces, the face body's morph and
        Jacobian ratio padded with the counterparts' columns, their gap columns and admissible sets
        (fem.cpdesigns)."""
        cp = self.cp_designs = build_counterpart_designs(self, cfg, self.foundation)
        face = surfaces_of(self.surface)
        self.face_surface = self.surface
        self.surface = DesignSurfaces(tuple(face) + tuple(d.surface for d in cp.designs))
        ratio = self.mesh.ratio
        self.mesh = PaddedMorph(self.mesh, self.surface, cp.n_face)
        self.mesh.ratio = padded_ratio(ratio, self.surface.size - cp.n_face)
        self.gap_matrix = np.hstack([np.asarray(self.gap_matrix, float),
                                     np.zeros((self.contact_nodes.size, self.surface.size - cp.n_face))])
        self.gap_matrix += cp.gap_columns(self.contact_nodes.size, self.surface.size)
        sets = list(self.admissible.sets) if isinstance(self.admissible, ProductAdmissible) else [self.admissible]
        init = self.surface.split(self.initial_design())
        ref = self.body.reference
        for d in cp.designs:
            dsg = cfg.designs[d.index]
            sets.append(self._admissible_one(replace(dsg, nonnegative_gap=False), d.surface, d.morph, d.face.nodes,
                                             init[d.index], f"designs[{d.index}]", ref))
        self.admissible = ProductAdmissible(sets)

    def _foundation_force(self, spec) -> None:
        """A force-controlled foundation: its loaded part, and the foundation with it, translate by
        s f̂ (:class:`ObstacleForce`); the contact forces on the body balance the force on the part
        and the foundation's own loads along f̂: Σ_m b_m·r_m = |f| + f̂·(their resultant)."""
        fnd = self.foundation
        f = np.asarray(spec.force, float)
        fhat = f / np.linalg.norm(f)
        p = self.contact_nodes.size
        R = self.frames if self.frames is not None else np.broadcast_to(np.eye(3), (p, 3, 3))
        motion = fnd.motion.reshape(-1, 3)
        total = float(np.linalg.norm(f) + fhat @ fnd.load_resultant)
        if not total > 0:
            raise ConfigError([f"{self.config.source}: foundation.force = {spec.force}: the foundation's own loads "
                               f"pull it away from the body by more than the force (the contact resultant along "
                               f"the force would be {total:.6g} ≤ 0)"])
        self.obstacle_force = ObstacleForce(total, np.einsum("mij,i->mj", R, fhat), motion[:, 2].copy(), motion)
        if not np.any(self.obstacle_force.gap_rate > 0):
            raise ConfigError([f"{self.config.source}: foundation.force = {spec.force}: no contact node's normal has "
                               "a component along the force: the foundation cannot press the body"])

    def _pair_force(self, rigid: dict) -> None:
        """A rigid counterpart of one of several pairs pressed by a force (its table's control =
        "force"): it translates by s f̂ as the one obstacle does (:class:`ObstacleForce`, no
        ``motion``), with b_m = R_mᵀ f̂ and c_m = f̂·n_m on its pair's contact nodes and zero on the
        others', so that Σ_m b_m·r_m is the resultant along f̂ of its pair alone. A counterpart
        body pressed by a force: :meth:`_body_force`."""
        p = self.contact_nodes.size
        R = self.frames if self.frames is not None else np.broadcast_to(np.eye(3), (p, 3, 3))
        if self.foundation.pressed is not None:
            self._body_force(R)
        for k, (spec, rows, _, _) in rigid.items():
            if spec.control != "force":
                continue
            f = np.asarray(spec.force, float)
            fhat = f / np.linalg.norm(f)
            b, c = np.zeros((p, 3)), np.zeros(p)
            b[rows] = np.einsum("mij,i->mj", R[rows], fhat)
            c[rows] = R[rows, :, 2] @ fhat
            self.obstacle_force = ObstacleForce(float(np.linalg.norm(f)), b, c)
            if not np.any(c > 0):
                raise ConfigError([f"{self.config.source}: contacts[{k}].counterpart.force = {spec.force}: no contact "
                                   "node's normal has a component along the force: the counterpart cannot press the "
                                   "body"])

    def _body_force(self, R: np.ndarray) -> None:
        """A counterpart body of several pairs pressed by a force (``bodies.<name>.control =
        "force"``): its loaded part, and the body with it, translate by s f̂ as a force-controlled
        ``[foundation]`` does (:meth:`_foundation_force`), its partners by ``motion`` per unit s on
        its pairs' contact nodes and not at all on the other pairs'; b_m = R_mᵀ f̂ on its pairs'
        nodes and zero elsewhere, so that Σ_m b_m·r_m, the resultant along f̂ of its pairs alone,
        balances |f| + f̂·(its own loads' resultant)."""
        cps = self.foundation
        k = cps.pressed
        part, rows = cps.parts[k], cps.rows[k]
        spec = self.config.pairs[cps.pairs[k][0]].foundation
        f = np.asarray(spec.force, float)
        fhat = f / np.linalg.norm(f)
        b = np.zeros((self.contact_nodes.size, 3))
        b[rows] = np.einsum("mij,i->mj", R[rows], fhat)
        motion = cps.motion.reshape(-1, 3)
        total = float(np.linalg.norm(f) + fhat @ part.load_resultant)
        where = f"{self.config.source}: the counterpart of {' and '.join(f'contacts[{j}]' for j in cps.pairs[k])}"
        if not total > 0:
            raise ConfigError([f"{where}: force = {spec.force}: the body's own loads pull it away from the face body "
                               f"by more than the force (the contact resultant along the force would be "
                               f"{total:.6g} ≤ 0)"])
        self.obstacle_force = ObstacleForce(total, b, motion[:, 2].copy(), motion)
        if not np.any(self.obstacle_force.gap_rate > 0):
            raise ConfigError([f"{where}: force = {spec.force}: no contact node's normal has a component along the "
                               "force: the counterpart cannot press the body"])

    @property
    def force(self) -> float | None:
        """|f| of a force-controlled obstacle, else None."""
        return None if self.obstacle_force is None else self.obstacle_force.magnitude

    @property
    def force_b(self) -> np.ndarray | None:
        """(p, 3) b_m = R_mᵀ f̂ of a force-controlled obstacle (:class:`ObstacleForce`), else None."""
        return None if self.obstacle_force is None else self.obstacle_force.b

    @property
    def force_gap(self) -> np.ndarray | None:
        """(p,) f̂·n_m of a force-controlled obstacle (:class:`ObstacleForce`), else None."""
        return None if self.obstacle_force is None else self.obstacle_force.gap_rate

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

    def _obstacle(self, spec, ref, body):
        """The frames of the contact face's nodes on an ``[obstacle]`` (None without one, and on the
        plane x3 = 0, whose frames are (e1, e2, e3): that path stays the one without an obstacle).
        Sets ``obstacle`` and, off the plane, ``frames`` (p, 3, 3) per contact node, columns (t1, t2, n)."""
        if spec is None:
            return None
        self.obstacle = make_obstacle(spec)
        fr = contact_frames(self.obstacle, ref.points, body.contact_face.nodes, body.penetration_tol,
                            self.config.source, interference=self.config.body.interference)
        if spec.shape == "plane":
            return fr
        where = np.searchsorted(body.contact_face.nodes, body.contact_nodes)
        R = fr.R[where]
        if body.pinned_dofs.size:
            # a clamped tangential component must be one of the node's local tangents: where e_k ⟂ n,
            # take t_k = e_k (t1 = t2 × n, or t2 = n × t1), the plane's frames stay (e1, e2, e3)
            node, comp = np.divmod(body.pinned_dofs, 3)
            m = np.searchsorted(body.contact_nodes, node)
            R = R.copy()
            if np.any(comp == 2):               # a tangent e3 (a face on a chart, not the plane)
                self._pinned_frames(f"{spec.shape} obstacle", ref, body, R, m, comp)
                return fr
            for mm, k in zip(m, comp):
                n = R[mm, :, 2]
                if abs(n[k]) < 1e-12 and np.abs(R[mm, :, k] - np.eye(3)[k]).max() > 1e-12:
                    t = np.eye(3)[k]
                    R[mm, :, k] = t
                    R[mm, :, 1 - k] = np.cross(t, n) if k == 1 else np.cross(n, t)
            off = np.abs(R[m, :, comp] - np.eye(3)[comp]).max(axis=1) > 1e-12
            if np.any(off):
                n = int(node[off][0])
                raise ConfigError([f"{self.config.source}: body.clamped: contact node {n} at {_fmt(ref.points[n])} has its "
                                   f"component u{int(comp[off][0]) + 1} clamped, which is not a tangent of its "
                                   f"frame on the {spec.shape} obstacle (the symmetry plane must contain the "
                                   "obstacle's normal there)"])
        self.frames = R
        return fr

    def _pinned_frames(self, what, ref, body, R, m, comp):
        """Frames of contact nodes with clamped components on a face of any chart: each clamped
        component e_k (⟂ n) becomes a tangent column of the node's frame (t1 first), the frame
        right-handed; ``pinned_columns`` maps the pinned DOFs to those columns (t1, t2). Sets
        ``frames``; ``what`` names the counterpart in messages."""
        cols = {}
        for mm, k in zip(m, comp):
            cols.setdefault(int(mm), []).append(int(k))
        self.pinned_columns = np.zeros(comp.size, np.int64)
        for mm, ks in cols.items():
            n = R[mm, :, 2]
            bad = [k for k in ks if abs(n[k]) > 1e-9]
            if bad or len(ks) > 2:
                nn = int(body.contact_nodes[mm])
                raise ConfigError([f"{self.config.source}: body.clamped: contact node {nn} at {_fmt(ref.points[nn])} "
                                   f"has its component u{(bad or ks)[0] + 1} clamped, which is not a tangent of its "
                                   f"frame on the {what} (the symmetry plane must contain the contact normal "
                                   "there)"])
            t1 = np.eye(3)[ks[0]]
            t2 = np.eye(3)[ks[1]] if len(ks) == 2 else np.cross(n, t1)
            order = list(ks)
            if np.cross(t1, t2) @ n < 0:
                t1, t2, order = t2, t1, order[::-1]
            R[mm, :, 0], R[mm, :, 1] = t1 - (t1 @ n) * n, t2 - (t2 @ n) * n
            R[mm, :, 0] /= np.linalg.norm(R[mm, :, 0])
            R[mm, :, 1] /= np.linalg.norm(R[mm, :, 1])
            for i in np.flatnonzero(m == mm):
                self.pinned_columns[i] = order.index(int(comp[i])) if len(ks) == 2 else 0
        self.frames = R

    def _rigid_pairs(self, cfg, ref, body) -> dict:
        """{pair k: (its [obstacle], its rows of the contact nodes, their frames R (p_k, 3, 3) with
        columns (t1, t2, n) and their distances to the obstacle along n)} of the pairs of a model of
        several pairs whose counterpart is rigid; each pair's nodes meet their own obstacle as the
        contact face of one pair does (:meth:`_obstacle`), an overlap deeper than the penetration
        tolerance refused unless ``body.interference``."""
        out = {}
        for k, pr in enumerate(cfg.pairs):
            if not pr.rigid:
                continue
            rows = np.flatnonzero(body.pair_of == k)
            nodes = body.contact_nodes[rows]
            try:
                fr = contact_frames(make_obstacle(pr.obstacle), ref.points, nodes, body.penetration_tol,
                                    cfg.source, interference=cfg.body.interference)
            except ConfigError as exc:
                raise ConfigError([q.replace("obstacle", f"contacts[{k}].counterpart", 1) for q in exc.problems]) from None
            out[k] = (pr.obstacle, rows, np.array(fr.R), np.array(fr.distance))
        return out

    @staticmethod
    def _rigid_specs(rigid: dict) -> dict:
        """The rigid pairs as :func:`~contactopt.fem.counterparts.build_counterparts` takes them."""
        return {k: (spec, dist) for k, (spec, _, _, dist) in rigid.items()}

    def _set_frames(self, ref, body, R, rigid, what) -> None:
        """The contact nodes' frames R (p, 3, 3), the rigid pairs' rows those of their obstacles, the
        clamped components of contact nodes made tangents of theirs (:meth:`_pinned_frames`)."""
        for _, rows, Rk, _ in rigid.values():
            R[rows] = Rk
        if body.pinned_dofs.size:
            node, comp = np.divmod(body.pinned_dofs, 3)
            self._pinned_frames(what, ref, body, R, np.searchsorted(body.contact_nodes, node), comp)
        else:
            self.frames = R

    def _curved_foundation(self, cfg, ref, body, check, rigid=None) -> None:
        """An elastic foundation under a curved contact face (fem.foundation): contact normals
        n_m = the chart's inward normal at the node (from the foundation to the body), frames
        (t1, t2, n_m) with the clamped components as tangents, the partners and initial gaps along
        n_m; an overlap deeper than the penetration tolerance needs ``body.interference``."""
        x = ref.points[body.contact_nodes]
        n = -body.contact_outward()
        R = tangent_frames(n)
        rigid = rigid or {}
        if rigid:                  # the rigid pairs' nodes take their obstacles' frames
            self._set_frames(ref, body, R.copy(), rigid, "counterpart")
        elif body.pinned_dofs.size:
            node, comp = np.divmod(body.pinned_dofs, 3)
            self._pinned_frames("elastic foundation", ref, body, R.copy(), np.searchsorted(body.contact_nodes, node),
                                comp)
        else:
            self.frames = R
        if cfg.pairs:
            faces = {k: (name, cfg.pairs[k].contact) for k, name in cfg.off_faces.items()}
            self.foundation = build_counterparts([pr.foundation for pr in cfg.pairs], body, cfg.source, check,
                                                 normals=n, frames=self.frames, rigid=self._rigid_specs(rigid),
                                                 condensed=self._condensed, faces=faces,
                                                 names=[c.counterpart.split(".")[0] for c in cfg.assembly.contacts])
            self._p_off = self.foundation.p - body.contact_nodes.size
        else:
            self.foundation = Foundation(cfg.foundation, body, source=cfg.source, check=check, normals=n,
                                         condensed=self._condensed)
            self.foundation.rotate(self.frames)
        g = self.foundation.gap0
        deep = np.flatnonzero(g < -body.penetration_tol)
        if deep.size and not cfg.body.interference:
            deep = deep[np.argsort(g[deep], kind="stable")]
            raise ConfigError([f"{cfg.source}: foundation: {deep.size} contact node(s) of the body lie inside the "
                               f"foundation deeper than the tolerance {body.penetration_tol:.3g}, deepest first: "
                               + ", ".join(f"node {int(body.contact_nodes[k])} at {_fmt(x[k])} (depth {-g[k]:.3g})"
                                           for k in deep[:5])
                               + " (an intended overlap, a press or shrink fit: body.interference = true)"])

    def _obstacle_gap(self, spec, fr) -> None:
        """Gap on an obstacle: g_m = d_m + (n_m·e3) ϑ_α(x'_m) − d·n_m (mesh.obstacle); the plane
        without a translation keeps the gap as it is, bit for bit."""
        where = np.searchsorted(self.body.contact_face.nodes, self.contact_nodes)
        n = fr.normal[where]
        shift = np.asarray(spec.displacement, float) if spec.control == "displacement" else np.zeros(3)
        R = self.frames if self.frames is not None else np.broadcast_to(np.eye(3), (n.shape[0], 3, 3))
        if np.any(shift[:2] != 0) or (self.frames is not None and np.any(shift != 0)):
            # a translation's tangential part moves the obstacle under the node: the contact law sees
            # the slip relative to it (per node (t1, t2, 0) in its frame; paths/condensation.py)
            self.slip_shift = np.einsum("mij,i->mj", R, shift) * [1.0, 1.0, 0.0]
        if spec.control == "force":
            f = np.asarray(spec.force, float)
            fhat = f / np.linalg.norm(f)
            # the obstacle translates by s·f̂: the gap falls by s (f̂·n_m); the resultant along f̂ is
            # Σ_m b_m·r_m with b_m = R_mᵀ f̂ (r_m per node (t1, t2, n) in its frame)
            self.obstacle_force = ObstacleForce(float(np.linalg.norm(f)), np.einsum("mij,i->mj", R, fhat), n @ fhat)
            if not np.any(self.obstacle_force.gap_rate > 0):
                raise ConfigError([f"{self.config.source}: obstacle.force = {spec.force}: no contact node's "
                                   "normal has a component along the force: the obstacle cannot press the body "
                                   "(a force with no component along any free direction)"])
        if spec.shape == "plane":
            if shift[2] != 0.0:
                self.gap0 = self.gap0 - shift[2]
            return
        self.gap_matrix = self._gap_factor(n, self.contact_nodes)[:, None] * self.gap_matrix
        self.gap0 = fr.distance[where] - n @ shift

    def _weighted_gap(self, spec, ref, body) -> None:
        """``[obstacle] weighting = "mortar"``: the gap of contact node j becomes the dual-weighted
        g̃_j = D_jj⁻¹ ∫_Γ Φ_j g dA of the gap g the node-wise rule reads at the node
        (:func:`contactopt.fem.mortar.dual_weighted`), on the reference face: g0 from the distance to
        the obstacle at each point (on the plane the face's height with ``initial_gap = "mesh"``,
        less the obstacle's translation along n), the design's rows from n·e3 ϑ_α at each point, and a
        force-controlled obstacle's gap rate f̂·n with them (the resultant's normal parts b_m·e_ν
        alike, so that the force stays work-conjugate to the weighted gaps). The faces' projection
        on the design's chart and the frames stay as they are; the weighted gap is affine in α like
        the node-wise one, so every path's subgradient takes it through ``gap_matrix``.

        Sign convention: g̃_j > 0 open, < 0 overlapping, as the node-wise gap; rows in contact-node
        order, per node the frame (t1, t2, n) with n from the obstacle to the body."""
        ft = face_type(ref.face_type)
        src = self.config.source
        if ft.degree != 1:
            raise ConfigError([f"{src}: obstacle.weighting = 'mortar' needs linear contact faces (triangles of "
                               f"linear tetrahedra, quadrilaterals of hexahedra), not {ft.name} (the six-node "
                               "triangle's dual basis has no weight at its corners): use weighting = 'node'"])
        if self.mesh.directions is not None:
            raise ConfigError([f"{src}: obstacle.weighting = 'mortar' with design.motion = 'normal': the weighted "
                               "gap is built for a design that lifts the face along x3; use weighting = 'node'"])
        shift = np.asarray(spec.displacement, float) if spec.control == "displacement" else np.zeros(3)
        fhat = np.asarray(spec.force, float) / max(np.linalg.norm(spec.force), 1e-300)
        height = self.config.body.initial_gap == "mesh"
        obstacle, surface, mesh = self.obstacle, self.surface, self.mesh

        def values(x):
            xi = mesh.chart_points(x)
            B = surface.basis_matrix(xi[:, 0], xi[:, 1])
            if obstacle is None or obstacle.shape == "plane":
                g0 = (x[:, 2] if height else np.zeros(x.shape[0])) - shift[2]
                return np.c_[g0, np.full(x.shape[0], fhat[2]), B]
            fr = obstacle.frames(x)
            n = fr.normal
            return np.c_[fr.distance - n @ shift, n @ fhat, n[:, 2:3] * B]

        _, v = dual_weighted(ft, body.contact_face.faces, ref.points, self.contact_nodes, values)
        self.gap0, self.gap_matrix = v[:, 0].copy(), v[:, 2:].copy()
        if self.obstacle_force is not None:
            b = self.obstacle_force.b.copy()
            b[:, 2] = v[:, 1]
            self.obstacle_force = ObstacleForce(self.obstacle_force.magnitude, b, v[:, 1].copy())

    def _gap_factor(self, n, nodes) -> np.ndarray:
        """n_m·d_m per node: the counterpart's normal n_m (towards the body) against the motion's
        direction d_m (e3 on the paper's map, whose factor is n_m3 itself)."""
        d = self.mesh.directions
        return n[:, 2].copy() if d is None else np.einsum("ij,ij->i", n, d[nodes])

    def _admissible_set(self, ref, body, frames=None) -> AdmissibleSet:
        """U of ``[design]``; with ``nonnegative_gap`` ϑ_α + g0 ≥ 0 at the nodes of the contact face
        (g0 the face's height in the mesh with ``initial_gap = "mesh"``, else 0); on an obstacle
        other than the plane (n_m·e3) ϑ_α + d_m ≥ 0, d_m the node's distance to it (mesh.obstacle).
        Built for every configuration (a state reports the constraints its design breaks); whether
        U is fit for an optimization on this mesh is :meth:`design_space_problems`. Several designs:
        the product of each design's U on its face (:class:`~contactopt.design.several.ProductAdmissible`)."""
        if not body.designs:
            return self._admissible_one(self.config.design, self.surface, self.mesh, body.contact_face.nodes,
                                        self.initial_design(), "design", ref, frames)
        init = self.surface.split(self.initial_design())
        return ProductAdmissible([self._admissible_one(d, s, m, df.face.nodes, a0, f"designs[{k}]", ref)
                                  for k, (d, s, m, df, a0) in enumerate(zip(self.config.designs, self.surface.surfaces,
                                                                            self.mesh.morphs, body.designs, init))])

    def _admissible_one(self, d, s, mesh, nodes, initial, key, ref, frames=None) -> AdmissibleSet:
        """U of one design ``d`` (its surface ``s``, morph ``mesh``, face ``nodes``; ``key`` names it)."""
        gap = {}
        if d.nonnegative_gap and not self.config.body.interference:
            xy = mesh._in_domain(mesh.chart_points(ref.points[nodes]))
            g0 = (ref.points[nodes, 2].copy() if self.config.body.initial_gap == "mesh"
                  else np.zeros(nodes.size))
            B = s.basis_matrix(xy[:, 0], xy[:, 1])
            if frames is not None and self.frames is not None:
                B, g0 = self._gap_factor(frames.normal, nodes)[:, None] * B, frames.distance.copy()
            gap = dict(gap_basis=B, gap_offset=g0, gap_nodes=nodes,
                       gap_points=ref.points[nodes, :2], counterpart=self.config.counterpart)
        extra = {}             # [design] direction and [[design.linear]] (absent: the paper's U)
        if d.direction != "both":
            extra.update(direction=d.direction, initial=initial)
        if d.linear:
            extra["linear"] = tuple((r.coefficients, "upper" if r.upper is not None else "equal", r.bound)
                                    for r in d.linear)
        U = AdmissibleSet(s.d1, s.d2, s.a, s.b, d.C0, d.C1, d.C2, d.slope_divisor,
                          lower=d.lower, **gap, **extra)
        if extra and not U.nonempty():      # a contradiction within [design], refused as lower > C0 is
            raise ConfigError([f"{self.config.source}: {key}.direction / {key}.linear leave no admissible "
                               "design: the bounds, slopes, mean value and these rows have no common point"])
        return U

    def _jacobian_ratio(self, ref, body) -> JacobianRatio:
        """det J(α)/det J_ref = 1 + Rα (mesh.morph), which refuses a design that inverts or distorts
        an element; ``safe_C0`` the largest C0 that keeps it above the threshold on U's box."""
        G, _ = element_geometry(ref.points[ref.cells], self.assembler.dN)
        centroids = ref.points[ref.cells].mean(axis=1)
        jr = JacobianRatio(ref.cells, self.mesh.ratio_gradient(G), self.mesh.dx3_dalpha(),
                           self.config.body.min_jacobian_ratio, qpoints=centroids,
                           fixed_parts={name: nodes for name, nodes in body.fixed_shape.items()})
        self.safe_C0 = jr.safe_C0(self.config.design.lower) if not body.designs else np.nan
        return jr

    # ------------------------------------------------------------------ the design space
    def design_space_problems(self) -> list[str]:
        """Why ``[design]``'s admissible set U is unfit for an optimization on this mesh (empty: it
        is fit): bounds C0 (and ``lower``) that let admissible designs invert or distort an element
        (the Jacobian ratio on U's box down to ``body.min_jacobian_ratio``). A state solve needs
        none of this: it is solved for any design that leaves the mesh valid (the mesh's
        ``coordinates`` refuse the others)."""
        d, src, jr = self.config.design, self.config.source, self.mesh.ratio
        problems = []
        if self.body.designs or self.cp_designs is not None:
            return self._designs_space_problems()
        worst, e, _, _ = jr.worst_on_box(d.C0, d.lower)
        if worst <= jr.threshold:
            what = f"design.C0 = {d.C0:g}" + (f" with design.lower = {d.lower:g}" if d.lower else "")
            safe = (f"the largest safe C0 for this mesh and morph is {self.safe_C0:.4g}" if self.safe_C0 > d.lower
                    else "no C0 is safe with this lower bound: raise design.lower towards 0")
            problems.append(f"{src}: {what} lets admissible designs {'invert' if worst <= 0 else 'distort'} "
                            f"element {e} at {_fmt(jr.qpoints[e])} (Jacobian ratio down to {worst:.3g} ≤ "
                            f"body.min_jacobian_ratio = {jr.threshold:g}); {safe}")
        return problems

    def _designs_space_problems(self) -> list[str]:
        """:meth:`design_space_problems` of several designs: the Jacobian ratio on the product of
        their boxes [lower_d, C0_d]."""
        jr, U = self.mesh.ratio, self.admissible
        lo = np.concatenate([np.full(s.size, float(d.lower)) for d, s in zip(self.config.designs, self.surface.surfaces)])
        hi = np.concatenate([np.full(s.size, float(d.C0)) for d, s in zip(self.config.designs, self.surface.surfaces)])
        worst, e, scale = jr.worst_on_bounds(lo, hi)
        if worst > jr.threshold:
            return []
        what = ", ".join(f"{name}.C0 = {d.C0:g}" + (f" (lower {d.lower:g})" if d.lower else "")
                         for name, d in zip(U.names, self.config.designs))
        safe = (f"the C0 scaled by {scale:.4g} or less keep it valid" if scale > 0
                else "no C0 is safe with these lower bounds: raise them towards 0")
        return [f"{self.config.source}: {what} let admissible designs {'invert' if worst <= 0 else 'distort'} "
                f"element {e} at {_fmt(jr.qpoints[e])} (Jacobian ratio down to {worst:.3g} ≤ "
                f"body.min_jacobian_ratio = {jr.threshold:g}); {safe}"]

    def check_design_space(self) -> None:
        """Before an optimization: ConfigError listing :meth:`design_space_problems`; a warning
        when U lets the contact face overlap its counterpart (``design.lower < 0`` without
        ``nonnegative_gap``) where no overlap is intended (``body.interference`` false)."""
        problems = self.design_space_problems()
        if problems:
            raise ConfigError(problems)
        cfg = self.config
        for k, d in enumerate(cfg.designs):
            if d.lower < 0 and not d.nonnegative_gap and not cfg.body.interference:
                where = "below" if cfg.counterpart == "the foundation plane" else "into"
                key = f"designs[{k}]" if len(cfg.designs) > 1 else "design"
                log.warning("%s: %s.lower = %g < 0 with %s.nonnegative_gap = false: admissible designs may "
                            "put the contact face %s %s (an initial penetration; body.interference = true where "
                            "the overlap is intended)", cfg.source, key, d.lower, key, where, cfg.counterpart)

    # ------------------------------------------------------------------ sizes
    @property
    def n_contact(self) -> int:
        """p, the rows of the contact law: the face body's contact nodes, then those of the faces of
        pairs on other bodies (fem.faces)."""
        return self.contact_nodes.size + self._p_off

    @property
    def n_design(self) -> int:
        return self.surface.size

    def initial_design(self) -> np.ndarray:
        """α0 of the configuration (a scalar fills every control point)."""
        if self.body.designs or isinstance(self.surface, DesignSurfaces):
            return initial_designs(self.config, self.surface)
        init = self.config.design.initial
        if np.isscalar(init):
            return np.full(self.n_design, float(init))
        return self.surface.as_vector(init)

    def design_faces(self) -> list:
        """(faces, morph, reference points of its body) of each design in ``[[designs]]`` order: the
        face body's, then the counterparts' (fem.cpdesigns)."""
        ref = self.body.reference.points
        mesh = self.mesh if self.cp_designs is None else self.mesh.inner
        if self.body.designs:
            out = [(df.face.faces, m, ref) for df, m in zip(self.body.designs, mesh.morphs)]
        else:
            out = [(self.body.contact_face.faces, mesh, ref)]
        for d in (self.cp_designs.designs if self.cp_designs is not None else ()):
            out.append((d.face.faces, d.morph, d.morph.reference.points))
        return out

    def contact_areas(self) -> np.ndarray:
        """Tributary areas ∫N_m dS of the contact nodes on the (flat) reference contact face, which
        turn a contact stress σ into nodal forces λ_m ≈ σ(x'_m)·A_m: the consistent nodal forces
        of a uniform stress (on six-node triangles they vanish at the corners, as do the nodal
        forces of a uniform pressure). With mortar partners on six-node triangles the forces are
        those of the transformed basis N̂ = T N (:mod:`contactopt.fem.mortar`), and the areas
        ∫N̂_m dS = (T a)_m, positive at every node."""
        ref = self.body.reference
        areas = face_areas_nodal(ref.points, self.body.contact_faces, face=self.assembler.element.face)
        areas = areas[self.contact_nodes]
        if self.foundation is not None and self.foundation.basis is not None:
            return self.foundation.basis @ areas
        if self._p_off:                      # rows b: the nodal areas of their faces (fem.faces)
            return np.concatenate([areas, self.foundation.off_areas])
        return areas

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
        if self.pinned_free.size:
            A = self.pin(A)
        return Assembled(alpha, coords, A, L_full, self.free_load(L_full), self.gap_matrix @ alpha + self.gap0)

    def free_load(self, L_full: np.ndarray) -> np.ndarray:
        """L on the free DOFs, zero on the pinned ones."""
        L = L_full[self.assembler.free]
        if self.pinned_free.size:
            L[self.pinned_free] = 0.0
        return L

    def pin(self, A: sp.csr_matrix) -> sp.csr_matrix:
        """A with the rows and columns of the pinned DOFs reduced to their diagonal entry (the
        symmetric elimination of u = 0 there; the CSR pattern is kept, so factorizations that
        reuse it still apply)."""
        A = sp.csr_matrix(A)
        if not A.has_sorted_indices:
            A = A.copy()
            A.sort_indices()
        if self._pin_mask is None or self._pin_mask[0] != (A.shape, A.nnz):
            pinned = np.zeros(A.shape[0], bool)
            pinned[self.pinned_free] = True
            rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
            off = (pinned[rows] | pinned[A.indices]) & (rows != A.indices)
            self._pin_mask = ((A.shape, A.nnz), np.flatnonzero(off))
        data = A.data.copy()
        data[self._pin_mask[1]] = 0.0
        return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)

    def unpin(self, u_full: np.ndarray) -> np.ndarray:
        """``u_full`` (full length) with exact zeros on the pinned DOFs."""
        if self.pinned_dofs.size == 0:
            return u_full
        u_full = np.array(u_full, dtype=float)
        u_full[self.pinned_dofs] = 0.0
        return u_full

    def design_contraction(self, coords: np.ndarray, u_full: np.ndarray, v_full: np.ndarray, loads=None) -> np.ndarray:
        """vᵀ(∂A/∂α_k u − ∂L/∂α_k) for every design variable k (full-length u, v).

        Only the x3 coordinates move with α: ∂x3/∂α_k = β_k(x1, x2)·w (mesh.morph). The pinned
        DOFs are clamped: u and v are zero there (module docstring).
        """
        u_full, v_full = self.unpin(u_full), self.unpin(v_full)
        d = self.assembler.stiffness_shape_contraction(coords, u_full, v_full)
        d -= (loads or self.loads).shape_contraction(coords, v_full, self.assembler)
        return self.mesh.contract_dx(d)


def _formulation(mat, cell_type, source: str) -> str:
    """The element formulation of ``[material] formulation`` (``mat``) on the mesh's cells;
    ConfigError if the mesh's element type does not take it."""
    form = mat.formulation
    try:
        resolved = resolve_formulation(form, cell_type, mat.nu)
    except ValueError:
        raise ConfigError([f"{source}: material.formulation = {form!r}: B-bar is a formulation of hexahedra; "
                           f"the mesh has {cell_type} cells, which take 'standard' (or 'auto'). For a nearly "
                           "incompressible material on tetrahedra use quadratic ones (tetra10), which lock far "
                           "less than linear ones; from ν ≈ 0.49 on, hexahedra with 'bbar' "
                           "(docs/materials.md)"]) from None
    if cell_type == "tetra" and mat.nu >= BBAR_AUTO_NU:
        log.warning("%s: linear tetrahedra lock at ν = %g (too stiff, contact pressures too high); use "
                    "quadratic tetrahedra (tetra10) or hexahedra with material.formulation = 'auto'",
                    source, mat.nu)
    elif resolved != "standard" or mat.nu >= BBAR_AUTO_NU:
        log.info("element formulation: %s (%s cells, ν = %g)", resolved, cell_type, mat.nu)
    return resolved


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.asarray(x)) + ")"
