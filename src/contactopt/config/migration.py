"""Migration of former keys: read as the keys that replaced them, with a warning naming those."""

from __future__ import annotations

import logging

log = logging.getLogger("contactopt.config")

# the former [linear_solver] backend: its value as (path, library); None keeps the key's own value
LEGACY_BACKEND = {"auto": (None, None), "pardiso": ("condensation", "pardiso"),
                  "scipy": ("condensation", "scipy"), "delassus": ("delassus", None),
                  "amg": ("fullspace", None)}


def _legacy_backend(raw: dict, source: str, problems: list) -> dict:
    """``[linear_solver] backend`` (deprecated) read as the keys ``path`` and ``library`` that
    replaced it, with a warning naming them; it overrides them when both are given."""
    ls = raw.get("linear_solver")
    if not isinstance(ls, dict) or "backend" not in ls:
        return raw
    value = ls["backend"]
    new = {k: v for k, v in ls.items() if k != "backend"}
    if value not in LEGACY_BACKEND:
        problems.append(f"linear_solver.backend = {value!r}: must be one of "
                        f"{', '.join(repr(v) for v in LEGACY_BACKEND)} (a deprecated key: write "
                        "linear_solver.path and linear_solver.library instead)")
        return {**raw, "linear_solver": new}
    path, library = LEGACY_BACKEND[value]
    new.update({k: v for k, v in (("path", path), ("library", library)) if v is not None})
    spelled = ", ".join(f"{k} = {new[k]!r}" for k in ("path", "library") if k in new) or "path = 'auto'"
    log.warning("%s: [linear_solver] backend = %r is deprecated; write %s instead", source, value, spelled)
    return {**raw, "linear_solver": new}
