"""A validated configuration: frozen, one typed section per TOML section.

Code reads ``cfg.state.tol``, ``cfg.design.degree``, ``cfg.objective.terms`` …; an optional
section is None (``[foundation]``, ``[obstacle]``, and ``[geometry]``/``[mesh]`` of a body from
a file) or empty (``load_cases``, ``load_steps``). ``to_dict()`` gives the resolved nested dict
with every default filled in, to write the configuration back as TOML (``to_toml``) or to
derive a new one from it.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import tomli_w

from .assembly import Assembly
from .constraints import ResponseConstraint
from .sections import (
    Body,
    ContactPair,
    Design,
    DesignFace,
    Foundation,
    Friction,
    Geometry,
    LinearSolver,
    LoadCase,
    Loads,
    LoadStep,
    Material,
    Mesh,
    Objective,
    Obstacle,
    Optimizer,
    State,
)
from .validation import resolve


@dataclass(frozen=True)
class Config:
    """A validated configuration; ``source`` where it came from."""

    name: str
    description: str
    body: Body
    geometry: Geometry | None
    mesh: Mesh | None
    material: Material
    friction: Friction
    loads: Loads
    design: Design
    objective: Objective
    state: State
    linear_solver: LinearSolver
    optimizer: Optimizer
    foundation: Foundation | None
    obstacle: Obstacle | None
    load_cases: tuple[LoadCase, ...]
    load_steps: tuple[LoadStep, ...]
    constraints: tuple[ResponseConstraint, ...] = ()     # [[constraints]] (config/constraints.py)
    pairs: tuple[ContactPair, ...] = ()  # several [[contacts]] on one face body (config/assembly.py)
    assembly: Assembly | None = None     # the names of bodies, pairs and designs (config/assembly.py)
    more_designs: tuple[DesignFace, ...] = ()   # the designed faces after [design]'s (config/assembly.py)
    length_unit: str = ""                # the meshes' length unit, named on the figures' axes
    source: str = "<dict>"
    _data: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_data(cls, data: dict, source: str = "<dict>") -> "Config":
        """The typed configuration of a resolved (validated) nested dict."""
        def opt(key, kind):
            return kind.from_dict(data[key]) if key in data else None
        return cls(
            name=data["name"], description=data["description"], body=Body.from_dict(data["body"]),
            geometry=opt("geometry", Geometry), mesh=opt("mesh", Mesh),
            material=Material.from_dict(data["material"]), friction=Friction.from_dict(data["friction"]),
            loads=Loads.from_dict(data["loads"]), design=Design.from_dict(data["design"]),
            objective=Objective.from_dict(data["objective"]), state=State.from_dict(data["state"]),
            linear_solver=LinearSolver.from_dict(data["linear_solver"]),
            optimizer=Optimizer.from_dict(data["optimizer"]),
            foundation=opt("foundation", Foundation), obstacle=opt("obstacle", Obstacle),
            load_cases=tuple(LoadCase.from_dict(c) for c in data.get("load_cases", [])),
            load_steps=tuple(LoadStep.from_dict(s) for s in data.get("load_steps", [])),
            constraints=tuple(ResponseConstraint.from_dict(c) for c in data.get("constraints", [])),
            pairs=tuple(ContactPair(p["contact"], float(p["friction"]),
                                    Foundation.from_dict(p["foundation"]) if "foundation" in p else None,
                                    Obstacle.from_dict(p["obstacle"]) if "obstacle" in p else None)
                        for p in data.get("pairs", [])),
            more_designs=tuple(DesignFace(d["face"], Design.from_dict({k: v for k, v in d.items()
                                                                       if k not in ("face", "body")}), d.get("body"))
                               for d in data.get("more_designs", [])),
            assembly=Assembly.of(data), length_unit=data.get("length_unit", ""), source=source, _data=data)

    @property
    def data(self) -> dict:
        """The resolved nested dict (as validated; for writing it back, use :meth:`to_dict`)."""
        return self._data

    @property
    def designs(self) -> tuple[Design, ...]:
        """Every design of the model in ``[[designs]]`` order: ``[design]`` and those of ``more_designs``."""
        return (self.design,) + tuple(d.design for d in self.more_designs)

    @property
    def counterpart_designs(self) -> tuple:
        """(index in [[designs]], :class:`DesignFace`) of each design on a counterpart body
        (fem.cpdesigns); they follow the face body's designs."""
        return tuple((n, d) for n, d in enumerate(self.more_designs, start=1) if d.body is not None)

    @property
    def off_faces(self) -> dict:
        """{pair k: the body its face lies on} of the pairs whose face lies on a body other than the
        face body (a counterpart of another pair, fem.faces); empty for every other model."""
        asm = self.assembly
        if not self.pairs or asm is None:
            return {}
        out = {}
        for k, c in enumerate(asm.contacts):
            body = c.face.split(".", 1)[0]
            if body != asm.bodies[0]:
                out[k] = body
        return out

    def face_body_designs(self) -> "Config":
        """This configuration with the designs of the face body alone (its mesh, morph and
        admissible set are built from them; the counterparts' designs by fem.cpdesigns)."""
        if not self.counterpart_designs:
            return self
        return replace(self, more_designs=tuple(d for d in self.more_designs if d.body is None))

    @property
    def counterpart(self) -> str:
        """What the contact face meets, in the words of messages: the foundation plane (x3 = 0,
        the paper's rigid foundation), an elastic foundation's face, or a rigid obstacle's plane,
        sphere, cylinder or surface."""
        if self.foundation is not None or self.pairs:
            return "the elastic foundation's face"
        if self.obstacle is not None:
            return f"the obstacle's {self.obstacle.shape}"
        return "the foundation plane"

    def __getitem__(self, key):
        """A section of the resolved dict, as before the typed sections (for scripts and tests;
        the package reads attributes, tests/test_architecture.py)."""
        return self._data[key]

    def __eq__(self, other):
        return isinstance(other, Config) and self._data == other._data and self.source == other.source

    __hash__ = None

    def to_dict(self) -> dict:
        """A copy of the resolved nested dict, every default filled in: to write the configuration
        back, or to derive another from it (then validated again)."""
        return copy.deepcopy(self._data)

    def with_updates(self, updates: dict) -> "Config":
        """A new validated Config with nested keys of ``updates`` replaced."""
        merged = self.to_dict()
        for sec, vals in updates.items():
            if isinstance(vals, dict) and isinstance(merged.get(sec), dict):
                merged[sec].update(copy.deepcopy(vals))
            else:
                merged[sec] = copy.deepcopy(vals)
        return validate(merged, self.source)

    def to_toml(self) -> str:
        return tomli_w.dumps(self._data)


def validate(raw: dict, source: str = "<dict>") -> Config:
    """Fill defaults and check every key; raise ConfigError listing all problems at once."""
    return Config.from_data(resolve(raw, source), source)
