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


# ------------------------------------------------------------------ typed configuration
CONFIG_NAMES = {"cfg", "config", "conf", "configuration"}     # a name that holds a configuration
SECTIONS = {"body", "geometry", "mesh", "material", "friction", "loads", "design", "objective", "state",
            "linear_solver", "optimizer", "foundation", "obstacle", "load_cases", "load_steps"}


def _is_config(node, locals_: set) -> bool:
    """Whether ``node`` is a configuration or a part of one: cfg / config, anything.config
    (self.config, model.config, problem.config), their .data, a subscript, attribute or ``.get``
    of those, or a local that was assigned one (d = cfg["design"])."""
    if isinstance(node, ast.Name):
        return node.id in CONFIG_NAMES or node.id in locals_
    if isinstance(node, ast.Attribute):
        return node.attr == "config" or _is_config(node.value, locals_)
    if isinstance(node, ast.Subscript):
        return _is_config(node.value, locals_)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get":
        return _is_config(node.func.value, locals_)          # obst = cfg.data.get("obstacle", {})
    return False


def _string_lookups(tree) -> list:
    """(line, text) of every lookup of a configuration by string key in ``tree``: ``x["key"]``,
    ``x.get("key")``, ``"key" in x`` and any use of ``x.data``, for ``x`` as in :func:`_is_config`."""
    found = []
    scopes = [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))]
    for scope in [tree, *scopes]:
        locals_ = set()
        nodes = list(ast.walk(scope))
        for n in nodes:                     # section locals: d = cfg["design"]; d, s = cfg.design, x
            if isinstance(n, ast.Assign):
                pairs = [(t, n.value) for t in n.targets]
                pairs += [(t, v) for t in n.targets if isinstance(t, ast.Tuple) and isinstance(n.value, ast.Tuple)
                          for t, v in zip(t.elts, n.value.elts)]
                locals_ |= {t.id for t, v in pairs if isinstance(t, ast.Name) and _is_config(v, locals_)
                            and t.id not in CONFIG_NAMES}
        for n in nodes:
            if isinstance(n, ast.Subscript) and isinstance(n.slice, ast.Constant) and isinstance(n.slice.value, str) \
                    and _is_config(n.value, locals_):
                found.append((n.lineno, ast.unparse(n)))
            elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr == "get" \
                    and n.args and isinstance(n.args[0], ast.Constant) and isinstance(n.args[0].value, str) \
                    and _is_config(n.func.value, locals_):
                found.append((n.lineno, ast.unparse(n)))
            elif isinstance(n, ast.Compare) and isinstance(n.left, ast.Constant) and n.left.value in SECTIONS \
                    and any(isinstance(op, (ast.In, ast.NotIn)) for op in n.ops) \
                    and any(_is_config(c, locals_) for c in n.comparators):
                found.append((n.lineno, ast.unparse(n)))
            elif isinstance(n, ast.Attribute) and n.attr == "data" and _is_config(n.value, locals_):
                found.append((n.lineno, ast.unparse(n)))
    return sorted(set(found))


def config_lookups(src: Path) -> list:
    """Every lookup of a configuration by string key in the modules of ``src`` (the package
    directory) outside its configuration package."""
    out = []
    for f in sorted(src.rglob("*.py")):
        rel = f.relative_to(src).as_posix()
        if rel.startswith("config/") or rel == "config.py":
            continue
        out += [f"{rel}:{line} {text}" for line, text in _string_lookups(ast.parse(f.read_text()))]
    return out


def test_no_module_outside_config_indexes_a_configuration_by_string():
    """Code below the loader reads the typed sections (cfg.state.tol); only contactopt.config
    knows the TOML's keys. A configuration is copied or written through cfg.to_dict()."""
    found = config_lookups(SRC)
    assert not found, "configuration read by string key: " + "; ".join(found)


@pytest.mark.parametrize("snippet", [
    'cfg["state"]["tol"]', 'self.config["design"].get("lower", 0.0)', 'model.config.data.get("foundation")',
    '"foundation" in config.data', 'problem.config["objective"]',
    'def f(cfg):\n    d = cfg["design"]\n    return d["lower"]',
    'def f(self):\n    d, s = self.config.design, self.surface\n    return d["C0"]',
    'def f(cfg):\n    return "obstacle" in cfg'])
def test_the_lookup_detector_sees_a_string_lookup(snippet):
    """The check above is not vacuous: each of these reads a configuration by string key."""
    assert _string_lookups(ast.parse(snippet))


def test_the_lookup_detector_passes_attribute_reads():
    ok = ('def f(cfg, model):\n    d = cfg.design\n    t = cfg.objective.target\n    raw = cfg.to_dict()\n'
          '    raw["name"] = "x"\n    return d.lower, model.config.state.tol, t.kind, arrays.get("u")')
    assert not _string_lookups(ast.parse(ok))


# ------------------------------------------------------------------ typed State data
_MUTATORS = {"update", "setdefault", "pop", "popitem", "clear", "__setitem__"}


def _info_uses(tree) -> list:
    """(line, text) of every use of a state's dictionary ``info`` as a data channel in ``tree``:
    ``x.info[...]`` (read, write or delete), ``x.info.update(...)`` and the other mutators,
    ``x.info.get(...)``, ``"key" in x.info`` and ``x.info = ...``; ``self.info`` (a class's own
    attribute, e.g. an FCLIB problem's or a factorization's) excepted."""
    def is_info(node):
        return isinstance(node, ast.Attribute) and node.attr == "info" \
            and not (isinstance(node.value, ast.Name) and node.value.id == "self")
    found = []
    for n in ast.walk(tree):
        if isinstance(n, ast.Subscript) and is_info(n.value):
            found.append((n.lineno, ast.unparse(n)))
        elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and is_info(n.func.value) \
                and n.func.attr in _MUTATORS | {"get"}:
            found.append((n.lineno, ast.unparse(n)))
        elif isinstance(n, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in n.ops) \
                and any(is_info(c) for c in n.comparators):
            found.append((n.lineno, ast.unparse(n)))
        elif isinstance(n, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = n.targets if isinstance(n, ast.Assign) else [n.target]
            found += [(n.lineno, ast.unparse(t)) for t in targets if is_info(t)]
    return sorted(set(found))


def test_no_module_writes_or_reads_state_info():
    """State's data and statistics are named fields (st.step, st.obstacle.translation,
    st.stats.zone_nodes); ``State.info`` is only their read-only dictionary form for old code:
    nothing in the package writes into it or reads it by key."""
    found = []
    for f in sorted(SRC.rglob("*.py")):
        found += [f"{f.relative_to(SRC).as_posix()}:{line} {text}" for line, text in _info_uses(ast.parse(f.read_text()))]
    assert not found, "State.info used as a data channel: " + "; ".join(found)


@pytest.mark.parametrize("snippet", [
    'st.info["step"] = "load"', 'st.info["step"], st.info["substep"] = s.name, s.substep',
    'x = state.info["obstacle_translation"]', 'steps[j].info["objective"] = 1.0', 'st.info.update(a=1)',
    'st.info.get("zone_nodes")', '"sparse_solves" in st.info', 'st.info.setdefault("k", 0)',
    'res.state.info = {}', 'del st.info["slip"]'])
def test_the_info_detector_sees_a_use(snippet):
    """The check above is not vacuous: each of these uses ``info`` as a data channel."""
    assert _info_uses(ast.parse(snippet))


def test_the_info_detector_passes_named_fields_and_own_attributes():
    ok = ('st.step, st.substep = s.name, s.substep\nst.stats.adjoint_krylov = 3\nd = st.obstacle.translation\n'
          'self.info = 0\nt = self.info.get("title")\nfor k, v in problem.info.items():\n    pass\n'
          'view = dict(st.info)')
    assert not _info_uses(ast.parse(ok))


# ------------------------------------------------------------------ the run and the optimizer
MAX_FUNCTION_LINES = 60

SHORT_FUNCTIONS = [("runner.py", "run_optimization"), ("optimize/bundle.py", "minimize_bundle"),
                   ("optimize/constrained.py", "minimize_constrained")]


def _function(path: Path, name: str) -> ast.FunctionDef:
    return next(n for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.FunctionDef) and n.name == name)


def code_lines(fn: ast.FunctionDef) -> int:
    """Lines of a function from its signature to its end, its docstring left out (a numpydoc
    docstring is documentation, not the story the code tells)."""
    body = fn.body
    doc = body[0] if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
        and isinstance(body[0].value.value, str) else None
    total = fn.end_lineno - fn.lineno + 1
    return total - (doc.end_lineno - doc.lineno + 1 if doc is not None else 0)


@pytest.mark.parametrize("rel, name", SHORT_FUNCTIONS)
def test_the_run_and_the_optimizers_read_in_a_screen(rel, name):
    """The run and the two optimizers read top to bottom: each at most 60 lines of code."""
    n = code_lines(_function(SRC / rel, name))
    assert n <= MAX_FUNCTION_LINES, f"{rel}:{name} has {n} lines of code (at most {MAX_FUNCTION_LINES})"


def test_the_line_counter_leaves_out_only_the_docstring():
    fn = ast.parse('def f(x):\n    """Doc\n    string."""\n    y = x\n    return y\n').body[0]
    assert code_lines(fn) == 3


# numpy's archive functions: the calls that read or write an .npz/.npy file
_ARCHIVE_CALLS = {"load", "save", "savez", "savez_compressed", "atomic_savez", "atomic_savez_compressed"}
# the modules that read or write other archives: state files, arrays given on the command line,
# and the atomic writer itself
_OTHER_ARCHIVES = {"io/statefiles.py", "cli.py", "io/atomic.py"}


def archive_calls(tree) -> list:
    """(line, name) of every call of numpy's archive functions (and their atomic forms) in ``tree``."""
    found = []
    for n in ast.walk(tree):
        if not isinstance(n, ast.Call):
            continue
        f = n.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id in ("np", "numpy"):
            name = f.attr                                   # np.load, np.savez, ...
        else:
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
            name = name if name in ("atomic_savez", "atomic_savez_compressed") else None
        if name in _ARCHIVE_CALLS:
            found.append((n.lineno, name))
    return found


def test_one_module_writes_and_reads_checkpoints():
    """io/checkpoint.py alone writes and reads checkpoint.npz: every other call of np.load,
    np.savez or atomic_savez is in a module of another archive, and none of those speaks of
    checkpoints."""
    found = []
    for f in sorted(SRC.rglob("*.py")):
        rel = f.relative_to(SRC).as_posix()
        if rel == "io/checkpoint.py":
            continue
        text = f.read_text()
        calls = archive_calls(ast.parse(text))
        if calls and (rel not in _OTHER_ARCHIVES or "checkpoint.npz" in text or "CHECKPOINT_NAME" in text):
            found += [f"{rel}:{line} {name}" for line, name in calls]
    assert not found, "checkpoint archives read or written outside io/checkpoint.py: " + ", ".join(found)
    assert archive_calls(ast.parse((SRC / "io" / "checkpoint.py").read_text()))


@pytest.mark.parametrize("snippet", ["np.load(path)", "with numpy.load(p) as z:\n    pass",
                                     "atomic_savez(path, **arrays)", "np.savez(f, a=a)"])
def test_the_archive_detector_sees_a_call(snippet):
    assert archive_calls(ast.parse(snippet))


def test_the_archive_detector_passes_other_saves():
    assert not archive_calls(ast.parse("oracle.save(state)\nself.load(x)\npickle.load(f)"))


# ---------------------------------------------------------------- the evaluation as values
SIDE_CHANNELS = {"last_terms", "prepare_objectives", "_as_objective", "_responding"}


def _class_lines(path: Path, name: str) -> int:
    (node,) = [n for n in ast.parse(path.read_text()).body if isinstance(n, ast.ClassDef) and n.name == name]
    return node.end_lineno - node.lineno + 1


def test_the_shape_problem_is_short():
    """ShapeProblem builds the parts and keeps the last design: what it computes lives in
    contactopt.sensitivity (solution, responses, subgradient) and the reports in contactopt.io."""
    assert _class_lines(SRC / "problem.py", "ShapeProblem") <= 250


def _side_channels(tree) -> list:
    """Names of the former side channels (attributes written by one object for another to read)."""
    found = []
    for n in ast.walk(tree):
        name = n.attr if isinstance(n, ast.Attribute) else n.name if isinstance(n, (ast.FunctionDef, ast.ClassDef)) \
            else n.value if isinstance(n, ast.Constant) and isinstance(n.value, str) else None
        if name in SIDE_CHANNELS:
            found.append((n.lineno, name))
    return found


def test_no_side_channel_between_objectives_and_the_problem():
    """An objective returns its terms' values in its Partials record; nothing stores them on the
    objective for another object to read, and no objective is swapped in for another."""
    found = []
    for f in sorted(SRC.rglob("*.py")):
        found += [f"{f.relative_to(SRC).as_posix()}:{line} {name}" for line, name in _side_channels(ast.parse(f.read_text()))]
    assert not found, "side channels: " + "; ".join(found)


@pytest.mark.parametrize("snippet", ['obj.last_terms = {}', 'x = getattr(o, "last_terms", {})',
                                     'def prepare_objectives(self):\n    pass', 'with p._as_objective(0):\n    pass'])
def test_the_side_channel_detector_sees_a_use(snippet):
    assert _side_channels(ast.parse(snippet))


def test_an_objective_says_on_which_dofs_its_derivative_lives():
    """∂J/∂u is on the contact DOFs or on every DOF as a field of the record, not by its length:
    no module of the evaluation compares an array's size to decide it (the paths' adjoints take
    arrays; the evaluation hands them a record's arrays)."""
    found = []
    for f in [SRC / "sensitivity" / f"{m}.py" for m in ("objectives", "partials", "responses", "steps", "subgradient")]:
        for n in ast.walk(ast.parse(f.read_text())):
            if isinstance(n, ast.Compare) and any(isinstance(x, ast.Attribute) and x.attr == "size"
                                                  for x in [n.left, *n.comparators]):
                found.append(f"{f.name}:{n.lineno} {ast.unparse(n)}")
    assert not [s for s in found if "y_u" in s or "du" in s or "carry" in s], found


MAX_FUNCTION_IMPORTS = 60


def function_imports(tree) -> list:
    """(line, statement) of the imports inside functions of ``tree``."""
    found = {}
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for n in ast.walk(fn):
                if isinstance(n, (ast.Import, ast.ImportFrom)):
                    found[n.lineno] = ast.unparse(n)
    return sorted(found.items())


def test_imports_sit_at_module_level():
    """Imports go at the top of a module; inside a function only what needs an optional
    dependency (petsc4py, mpi4py, gmsh, dask, bokeh, clarabel), probes of an installed library,
    the package's lazy attribute and what a test replaces at run time. The import graph has no
    cycle (test_no_import_cycles), so nothing else needs to wait."""
    found = [f"{f.relative_to(SRC).as_posix()}:{line} {text}" for f in sorted(SRC.rglob("*.py"))
             for line, text in function_imports(ast.parse(f.read_text()))]
    assert len(found) <= MAX_FUNCTION_IMPORTS, f"{len(found)} imports inside functions:\n" + "\n".join(found)


def test_the_import_counter_sees_imports_in_functions():
    tree = ast.parse("import os\ndef f():\n    import json\n    def g():\n        from .a import b\n")
    assert [t for _, t in function_imports(tree)] == ["import json", "from .a import b"]
# ------------------------------------------------------------------ typed model data
MAX_PROBES = 5


def _attribute_probes(tree) -> list:
    """(line, text) of every ``getattr(x, "name", None)`` in ``tree``: an attribute that may or may
    not exist, read as None where it does not."""
    return [(n.lineno, ast.unparse(n)) for n in ast.walk(tree)
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "getattr"
            and len(n.args) == 3 and isinstance(n.args[1], ast.Constant) and isinstance(n.args[2], ast.Constant)
            and n.args[2].value is None]


def test_optional_parts_are_declared_not_probed():
    """The model, the paths' systems and the objectives declare their optional parts (None where
    absent): at most a few ``getattr(x, "name", None)`` remain in the package, for objects of
    other libraries (a meshio mesh, the MKL runtime) and plain functions."""
    found = [f"{f.relative_to(SRC).as_posix()}:{line} {text}" for _, f, _ in _modules()
             for line, text in _attribute_probes(ast.parse(f.read_text()))]
    assert len(found) <= MAX_PROBES, f"{len(found)} attribute probes: " + "; ".join(found)


def test_the_probe_detector_sees_a_probe():
    snippet = 'f = getattr(model, "foundation", None)\ng = getattr(m, "x", 0)\nh = m.frames\n'
    assert _attribute_probes(ast.parse(snippet)) == [(1, "getattr(model, 'foundation', None)")]


def test_the_model_declares_its_optional_parts():
    """ElasticModel is a dataclass whose optional parts are typed ``… | None`` fields."""
    from dataclasses import fields, is_dataclass

    from contactopt.fem.model import ElasticModel
    assert is_dataclass(ElasticModel)
    types = {f.name: str(f.type) for f in fields(ElasticModel)}
    for name in ("obstacle", "frames", "slip_shift", "obstacle_force", "foundation"):
        assert types[name].endswith("| None"), (name, types[name])
