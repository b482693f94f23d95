"""Configuration: a TOML file (or a built-in example name) validated up front into a frozen,
typed :class:`Config`.

Modules: :mod:`.schema` (every section and key with its default, check and description),
:mod:`.validation` (every problem listed at once in a :class:`ConfigError`), :mod:`.migration`
(former keys), :mod:`.sections` and :mod:`.configuration` (the typed objects), :mod:`.loading`
(``load_config``), :mod:`.reference` (docs/configuration.md) and :mod:`.json_schema` (the JSON
Schema of ``contactopt schema``).
"""

from ..errors import ConfigError
from .configuration import Config, validate
from .json_schema import json_schema
from .loading import load_config
from .migration import LEGACY_BACKEND
from .reference import reference_markdown
from .schema import (
                     BLOCK_LOADS,
                     CASE_NAME,
                     EXAMPLES,
                     FOUNDATION,
                     FOUNDATION_LOADS,
                     OBJECTIVE_TYPES,
                     OBSTACLE,
                     SCHEMA,
                     SECTION_DOCS,
                     TERM_KEYS,
                     TOP_LEVEL,
)
from .sections import (
                     Body,
    Clamp,
                     Design,
                     Foundation,
                     FoundationBlock,
                     FoundationMaterial,
                     Friction,
                     Geometry,
                     LinearConstraint,
                     LinearSolver,
                     LoadCase,
                     Loads,
                     LoadStep,
                     Material,
                     Mesh,
                     Objective,
                     ObjectiveTerm,
                     Obstacle,
                     Optimizer,
                     PartLoad,
                     Region,
                     State,
                     Target,
)

__all__ = ["BLOCK_LOADS", "CASE_NAME", "EXAMPLES", "FOUNDATION", "FOUNDATION_LOADS", "LEGACY_BACKEND",
           "OBJECTIVE_TYPES", "OBSTACLE", "SCHEMA", "SECTION_DOCS", "TERM_KEYS", "TOP_LEVEL", "Body", "Clamp", "Config",
           "ConfigError", "Design", "Foundation", "FoundationBlock", "FoundationMaterial", "Friction", "Geometry",
           "LinearConstraint", "LinearSolver", "LoadCase", "LoadStep", "Loads", "Material", "Mesh", "Objective",
           "ObjectiveTerm", "Obstacle", "Optimizer", "PartLoad", "Region", "State", "Target", "json_schema",
           "load_config", "reference_markdown", "validate"]
