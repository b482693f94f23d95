"""The typed sections of a validated configuration: one frozen dataclass per section, one small
record per table of an array of tables (load cases, load steps, objective terms, linear design
constraints, part loads, targets).

The dataclasses declare names and types only; every default lives in ``contactopt.config.schema`` and the
validator fills it in, so a section is built from the resolved dict (``from_dict``) and a key the
validator leaves out on purpose (a block key of a body from a file, the count of a graded
direction) is ``None``. Values that are tables or lists in the TOML (part predicates, nested
control-point lists) stay lists and dicts, as ``tomllib`` gives them.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

from .checks import ALL_COMPONENTS
from .schema import FOUNDATION, OBSTACLE, SCHEMA


def _build(cls, table: dict, defaults: dict, **typed):
    """``cls`` from a resolved table: the fields of ``typed`` as given, the rest from the table
    (a key the table lacks: the schema's default, or None for a field declared ``| None``)."""
    values = {}
    for f in dataclasses.fields(cls):
        if f.name in typed:
            values[f.name] = typed[f.name]
        elif f.name in table:
            values[f.name] = copy.deepcopy(table[f.name])
        elif "None" in str(f.type) or f.name not in defaults:
            values[f.name] = None
        else:
            values[f.name] = copy.deepcopy(defaults[f.name][0])
    return cls(**values)


def _defaults(section: str) -> dict:
    return SCHEMA[section]


@dataclass(frozen=True)
class Clamp:
    """One clamp of ``clamped``: a part and the displacement components it fixes (1, 2, 3 or
    'x1', 'x2', 'x3'; all three where the table names none)."""

    on: Any
    components: list

    @classmethod
    def all_of(cls, value) -> tuple["Clamp", ...]:
        """The clamps of a ``clamped`` value: a part, a table { on, components } or a list of these."""
        items = value if isinstance(value, list) else [value]
        return tuple(cls(copy.deepcopy(it["on"]), list(it.get("components", ALL_COMPONENTS)))
                     if isinstance(it, dict) and "on" in it else cls(copy.deepcopy(it), list(ALL_COMPONENTS))
                     for it in items)


@dataclass(frozen=True)
class Body:
    """``[body]``: the mesh file (empty: the block) and its named parts."""

    mesh: str
    clamped: tuple[Clamp, ...]
    contact: Any
    fixed_shape: Any
    tolerance: float
    min_jacobian_ratio: float
    initial_gap: str
    graph_tolerance: float
    penetration_tolerance: float
    interference: bool

    @classmethod
    def from_dict(cls, d: dict) -> "Body":
        return _build(cls, d, _defaults("body"), clamped=Clamp.all_of(d["clamped"]))


@dataclass(frozen=True)
class Geometry:
    """``[geometry]``: the block [0, a]×[0, b]×[0, c]."""

    a: float
    b: float
    c: float

    @classmethod
    def from_dict(cls, d: dict) -> "Geometry":
        return _build(cls, d, _defaults("geometry"))


@dataclass(frozen=True)
class Mesh:
    """``[mesh]``: per direction a count of equal elements or a list of node coordinates (the
    other one None)."""

    nx: int | None
    ny: int | None
    nz: int | None
    x1: list | None
    x2: list | None
    x3: list | None

    @classmethod
    def from_dict(cls, d: dict) -> "Mesh":
        return _build(cls, d, _defaults("mesh"))

    @property
    def graded(self) -> bool:
        """Whether a direction is given by its node coordinates."""
        return any((self.x1, self.x2, self.x3))


@dataclass(frozen=True)
class Material:
    """``[material]``: isotropic linear elasticity and the element formulation."""

    E: float
    nu: float
    formulation: str

    @classmethod
    def from_dict(cls, d: dict) -> "Material":
        return _build(cls, d, _defaults("material"))


@dataclass(frozen=True)
class Friction:
    """``[friction]``: the Coulomb coefficient F."""

    coefficient: float

    @classmethod
    def from_dict(cls, d: dict) -> "Friction":
        return _build(cls, d, _defaults("friction"))


@dataclass(frozen=True)
class PartLoad:
    """One entry ``{ on = <part>, value = … }`` of ``traction`` or ``pressure``."""

    on: Any
    value: Any

    @classmethod
    def from_dict(cls, d: dict) -> "PartLoad":
        return cls(copy.deepcopy(d["on"]), copy.deepcopy(d["value"]))


@dataclass(frozen=True)
class Loads:
    """Loads in the form of ``[loads]``: of the configuration (every key resolved; the block loads
    None on a body from a file), of a load case or step, or of the foundation (a key not written:
    None, or no entries)."""

    top_traction: list | None
    right_traction: list | None
    body_force: list | None
    traction: tuple[PartLoad, ...]
    pressure: tuple[PartLoad, ...]

    @classmethod
    def from_dict(cls, d: dict) -> "Loads":
        return cls(copy.deepcopy(d.get("top_traction")), copy.deepcopy(d.get("right_traction")),
                   copy.deepcopy(d.get("body_force")),
                   tuple(PartLoad.from_dict(e) for e in d.get("traction", [])),
                   tuple(PartLoad.from_dict(e) for e in d.get("pressure", [])))


@dataclass(frozen=True)
class LinearConstraint:
    """One ``[[design.linear]]`` row: Σ c·α ≤ upper, or Σ c·α = equal (the other None)."""

    coefficients: list
    upper: float | None
    equal: float | None

    @classmethod
    def from_dict(cls, d: dict) -> "LinearConstraint":
        return cls(copy.deepcopy(d["coefficients"]), d.get("upper"), d.get("equal"))

    @property
    def bound(self) -> float:
        return self.upper if self.upper is not None else self.equal


@dataclass(frozen=True)
class Design:
    """``[design]``: the Bézier surface ϑ_α and the admissible set U of its control points."""

    degree: list
    C0: float
    lower: float
    nonnegative_gap: bool
    C1: float
    C2: float
    slope_divisor: str
    initial: Any
    domain: list
    symmetry: list
    fixed: list
    direction: str
    linear: tuple[LinearConstraint, ...]
    motion: str
    chart: str
    axis: list
    origin: list

    @classmethod
    def from_dict(cls, d: dict) -> "Design":
        return _build(cls, d, _defaults("design"),
                      linear=tuple(LinearConstraint.from_dict(r) for r in d.get("linear", [])))


@dataclass(frozen=True)
class Region:
    """A region ``{ x1 = [lo, hi], x2 = [lo, hi], value }`` of a 'step' target (a bound not
    given: unbounded)."""

    x1: tuple
    x2: tuple
    value: float

    @classmethod
    def from_dict(cls, d: dict) -> "Region":
        inf = float("inf")
        return cls(tuple(d.get("x1", (-inf, inf))), tuple(d.get("x2", (-inf, inf))), d["value"])


@dataclass(frozen=True)
class Target:
    """A target normal force table (``objective.target``, a case's or a term's ``target``): its
    ``kind`` and that kind's keys ('constant': value; 'step': default, regions, per_area;
    'values': values; 'design': alpha)."""

    kind: str
    value: float = 0.0
    default: float = 0.0
    regions: tuple[Region, ...] = ()
    per_area: bool = False
    values: list | None = None
    alpha: Any = None

    @classmethod
    def from_dict(cls, d: dict) -> "Target":
        given = {k: copy.deepcopy(v) for k, v in d.items() if k in ("value", "default", "per_area", "values",
                                                                    "alpha")}
        return cls(d["kind"], regions=tuple(Region.from_dict(r) for r in d.get("regions", [])), **given)


@dataclass(frozen=True)
class ObjectiveTerm:
    """One ``[[objective.terms]]`` table (defaults filled in by the validator)."""

    type: str
    weight: float
    region: Any
    aggregate: str
    rho: float
    p: float
    target: Target | None
    contacts: tuple = ()

    @classmethod
    def from_dict(cls, d: dict) -> "ObjectiveTerm":
        return cls(d["type"], d["weight"], copy.deepcopy(d["region"]), d["aggregate"], d["rho"], d["p"],
                   Target.from_dict(d["target"]) if "target" in d else None, tuple(d.get("contacts", ())))


@dataclass(frozen=True)
class Objective:
    """``[objective]``: J(α, y), its terms, and how load cases and load steps are combined."""

    type: str
    target: Target
    scale: float
    region: Any
    contacts: tuple
    aggregate: str
    rho: float
    p: float
    terms: tuple[ObjectiveTerm, ...]
    combine: str
    weights: Any
    steps: Any
    active_tol: float

    @classmethod
    def from_dict(cls, d: dict) -> "Objective":
        return _build(cls, d, _defaults("objective"), target=Target.from_dict(d["target"]),
                      terms=tuple(ObjectiveTerm.from_dict(t) for t in d.get("terms", [])),
                      contacts=tuple(d.get("contacts", ())))

    @property
    def types(self) -> set:
        """The objective types in use (the terms' types, or the one type)."""
        return {t.type for t in self.terms} or {self.type}


@dataclass(frozen=True)
class State:
    """``[state]``: the discrete Coulomb contact problem's solver."""

    method: str
    tol: float
    max_iter: int
    zone: bool
    zone_margin: float
    reuse_delassus: bool

    @classmethod
    def from_dict(cls, d: dict) -> "State":
        return _build(cls, d, _defaults("state"))


@dataclass(frozen=True)
class LinearSolver:
    """``[linear_solver]``: the solver path of state and adjoint, and its sparse direct solver."""

    path: str
    library: str
    crossover: int
    petsc_options: str
    memory_check: bool
    threads: int

    @classmethod
    def from_dict(cls, d: dict) -> "LinearSolver":
        return _build(cls, d, _defaults("linear_solver"))


@dataclass(frozen=True)
class Optimizer:
    """``[optimizer]``: the bundle-trust method."""

    eps: float
    max_iter: int
    ftol: float
    ftol_window: int
    metric: str
    metric_memory: int
    scale: str

    @classmethod
    def from_dict(cls, d: dict) -> "Optimizer":
        return _build(cls, d, _defaults("optimizer"))


@dataclass(frozen=True)
class FoundationBlock:
    """``foundation.block``: the box [o1, o1+s1]×[o2, o2+s2]×[−s3, 0]."""

    size: list
    cells: list
    origin: list
    element: str

    @classmethod
    def from_dict(cls, d: dict) -> "FoundationBlock":
        return cls(list(d["size"]), list(d["cells"]), list(d["origin"]), d["element"])


@dataclass(frozen=True)
class FoundationMaterial:
    """``foundation.material`` resolved: a key not given is the body's."""

    E: float
    nu: float


@dataclass(frozen=True)
class Foundation:
    """``[foundation]``: an elastic foundation under the body."""

    mesh: str
    block: FoundationBlock | None
    top: Any
    clamped: tuple[Clamp, ...]
    material: FoundationMaterial
    loads: Loads
    partner: str
    tolerance: float
    control: str = "fixed"
    loaded: Any = "bottom"
    displacement: list = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    force: list = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])

    @classmethod
    def from_dict(cls, d: dict) -> "Foundation":
        return _build(cls, d, FOUNDATION, clamped=Clamp.all_of(d["clamped"]), block=FoundationBlock.from_dict(d["block"]) if d["block"] else None,
                      material=FoundationMaterial(d["material"]["E"], d["material"]["nu"]),
                      loads=Loads.from_dict(d["loads"]))

    @property
    def translation(self) -> tuple | None:
        """The direction the part ``loaded`` translates along: the displacement itself (control =
        'displacement'), the force's unit vector (control = 'force'), None when fixed."""
        if self.control == "displacement":
            return tuple(float(v) for v in self.displacement)
        if self.control == "force":
            norm = sum(float(v) ** 2 for v in self.force) ** 0.5
            return tuple(float(v) / norm for v in self.force)
        return None


@dataclass(frozen=True)
class Obstacle:
    """``[obstacle]``: a rigid obstacle and how it is driven."""

    shape: str
    center: list
    radius: float
    point: list
    axis: list
    mesh: str
    control: str
    displacement: list
    force: list
    weighting: str = "node"

    @classmethod
    def from_dict(cls, d: dict) -> "Obstacle":
        return _build(cls, d, OBSTACLE)

    @property
    def moves_tangentially(self) -> bool:
        """Whether the obstacle may move along the contact face (pressed by a force, or displaced
        in x1/x2)."""
        return self.control == "force" or (self.control == "displacement" and any(self.displacement[:2]))


@dataclass(frozen=True)
class LoadStep:
    """One ``[[load_steps]]`` table: the TOTAL loads at its end, reached in ``substeps`` equal
    increments."""

    name: str
    loads: Loads
    substeps: int
    obstacle_force: tuple | None = None    # a force-controlled obstacle's force at the step's end (None: obstacle.force)

    @classmethod
    def from_dict(cls, d: dict) -> "LoadStep":
        force = d.get("obstacle_force")
        return cls(d["name"], Loads.from_dict(d), d["substeps"], None if force is None else tuple(map(float, force)))


@dataclass(frozen=True)
class LoadCase:
    """One ``[[load_cases]]`` table: its loads, its own target (None: objective.target) and its
    own load path (None: the configuration's ``[[load_steps]]``)."""

    name: str
    loads: Loads
    target: Target | None
    steps: tuple[LoadStep, ...] | None

    @classmethod
    def from_dict(cls, d: dict) -> "LoadCase":
        return cls(d["name"], Loads.from_dict(d), Target.from_dict(d["target"]) if "target" in d else None,
                   tuple(LoadStep.from_dict(s) for s in d["steps"]) if "steps" in d else None)


@dataclass(frozen=True)
class ContactPair:
    """One of several contact pairs on the face body: its face ``contact`` (a part of the body),
    its Coulomb coefficient ``friction`` and its counterpart: a body (a ``[foundation]``) or a rigid
    ``obstacle`` (``foundation`` None)."""

    contact: Any
    friction: float
    foundation: Foundation | None
    obstacle: Obstacle | None = None

    @property
    def rigid(self) -> bool:
        """Whether the counterpart is rigid (an ``[obstacle]``'s table)."""
        return self.obstacle is not None


@dataclass(frozen=True)
class DesignFace:
    """A designed face after the first (``[[designs]]`` with more than one entry): its ``face`` (a
    part of the face body, or of the counterpart body ``body``) and its ``design``, a [design] of
    its own."""

    face: Any
    design: Design
    body: str | None = None        # a counterpart body's design (fem.cpdesigns); None: the face body's
