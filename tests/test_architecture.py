"""The layering of the package (docs/architecture.md), checked on the source itself: one place
decides and tests the solver path, the mesh layer is geometry only, and no two modules import
each other (directly or through others, at module level or inside functions)."""

import ast
from pathlib import Path

import pytest

import contactopt.paths as paths

SRC = Path(paths.__file__).resolve().parents[1]          # src/contactopt
PATH_NAMES = set(paths.NAMES) | {"schur", "amg"}         # today's names and the former ones


def _modules():
    for f in sorted(SRC.rglob("*.py")):
        rel = f.relative_to(SRC.parent).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        yield ".".join(parts), f, rel.name == "__init__"


def _imports(name: str, tree, is_package: bool, known: set):
    """Modules of the package imported anywhere in ``tree`` (module level or in functions)."""
    base = name.split(".") if is_package else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mod = ".".join(base[:len(base) - node.level + 1]) if node.level else ""
            mod = ".".join(p for p in (mod, node.module or "") if p)
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:       # import a.b.c of a module a.b: the module a.b
                t = t.rpartition(".")[0]
            if t and t != name:
                yield t


def _graph():
    mods = list(_modules())
    known = {m for m, _, _ in mods}
    return {m: set(_imports(m, ast.parse(f.read_text()), pkg, known)) for m, f, pkg in mods}


def test_no_module_outside_paths_tests_a_path_name():
    """Comparisons with a path's name (==, !=, in) appear in contactopt.paths and the
    configuration only: every other module asks the path object."""
    found = []
    for name, f, _ in _modules():
        if name.startswith("contactopt.paths") or name == "contactopt.config":
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Compare):
                consts = [n for n in ast.walk(node) if isinstance(n, ast.Constant) and n.value in PATH_NAMES]
                found += [f"{name}:{n.lineno} {n.value!r}" for n in consts]
    assert not found, "path names tested outside contactopt.paths: " + ", ".join(found)


def test_the_cycle_detector_sees_a_cycle():
    """The import graph finds the imports a cycle is made of, inside functions too."""
    tree = ast.parse("def f():\n    from .b import g\n")
    assert set(_imports("pkg.a", tree, False, {"pkg.a", "pkg.b"})) == {"pkg.b"}


def test_the_detector_sees_a_path_test():
    """The check above is not vacuous: it finds a comparison in a snippet."""
    tree = ast.parse("if system.path == 'fullspace':\n    pass\n")
    assert any(isinstance(n, ast.Constant) and n.value in PATH_NAMES for n in ast.walk(tree))


def test_mesh_imports_nothing_from_fem():
    graph = _graph()
    bad = {m: sorted(t for t in ts if t.startswith(("contactopt.fem", "contactopt.paths", "contactopt.problem")))
           for m, ts in graph.items() if m.startswith("contactopt.mesh")}
    assert not any(bad.values()), {m: t for m, t in bad.items() if t}


def test_no_import_cycles():
    graph = _graph()
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


@pytest.mark.parametrize("name", sorted(paths.NAMES))
def test_every_path_implements_the_interface(name):
    cls = paths.PATHS[name]
    for method in ("prepare", "for_load", "solve_state", "adjoint", "memory_estimate"):
        assert getattr(cls, method) is not getattr(paths.SolverPath, method), f"{name} lacks {method}"


# ---------------------------------------------------------------------- the path interface
PATHS_DIR = SRC / "paths"


@pytest.mark.parametrize("name", sorted(paths.NAMES))
def test_every_path_declares_its_capabilities(name):
    """Each path class has its own Capabilities record (not the base class's), with a rule for
    "auto" and every feature a boolean."""
    cls = paths.PATHS[name]
    assert "capabilities" in vars(cls), f"{name} does not declare its capabilities"
    caps = cls.capabilities
    assert isinstance(caps, paths.Capabilities)
    assert caps.auto in ("", "small", "large", "ranks")
    assert all(isinstance(getattr(caps, f), bool) for f in paths.Capabilities.features())


def _path_name_tests(tree) -> list:
    """Comparisons with a path's name and subscripts by one (``PATHS["petsc"]``) in ``tree``."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Compare, ast.Subscript, ast.Match)):
            found += [n.lineno for n in ast.walk(node) if isinstance(n, ast.Constant) and n.value in PATH_NAMES]
    return found


def test_select_path_has_no_per_path_branches():
    """select_path and its helpers (contactopt/paths/__init__.py) filter on the declared
    capabilities and never compare with a path's name; the check sees such a branch."""
    tree = ast.parse((PATHS_DIR / "__init__.py").read_text())
    assert not _path_name_tests(tree), "paths/__init__.py tests path names at lines " + str(_path_name_tests(tree))
    assert _path_name_tests(ast.parse("if name == 'petsc' or PATHS['fullspace']:\n    pass\n")) == [1, 1]


def _mutable_module_state(tree) -> list:
    """Module-level names bound to mutable containers or counters, names bound twice, and
    ``global`` statements anywhere in ``tree``."""
    found, bound = [], {}
    mutable_calls = {"list", "dict", "set", "defaultdict", "OrderedDict", "count", "deque", "Counter"}
    for node in tree.body:
        targets = []
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        elif isinstance(node, ast.AugAssign):
            found.append(f"{node.lineno}: augmented assignment at module level")
            continue
        else:
            continue
        for t in targets:
            for n in ast.walk(t):
                if isinstance(n, ast.Name):
                    bound[n.id] = bound.get(n.id, 0) + 1
                    if bound[n.id] > 1:
                        found.append(f"{node.lineno}: {n.id} bound again")
        if isinstance(value, (ast.List, ast.Dict, ast.Set, ast.ListComp, ast.DictComp, ast.SetComp)):
            found.append(f"{node.lineno}: a mutable container")
        if isinstance(value, ast.Call):
            f = value.func
            callee = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            if callee in mutable_calls:
                found.append(f"{node.lineno}: {callee}()")
    found += [f"{n.lineno}: global {', '.join(n.names)}" for n in ast.walk(tree) if isinstance(n, (ast.Global, ast.Nonlocal))]
    return found


def test_no_module_level_mutable_state_in_paths():
    """No module of contactopt/paths/ keeps state between calls at module level: no list, dict,
    set or counter bound there, no name bound twice, no ``global`` (the MPI ranks' bookkeeping is
    an object, contactopt.paths.protocol.Follower); the check sees each kind."""
    found = {f.name: _mutable_module_state(ast.parse(f.read_text())) for f in sorted(PATHS_DIR.glob("*.py"))}
    assert not any(found.values()), {k: v for k, v in found.items() if v}
    snippet = "import itertools\n_ids = itertools.count(1)\n_pending = [None]\n_served: dict = {}\ndef f():\n    global _x\n"
    assert len(_mutable_module_state(ast.parse(snippet))) == 4
