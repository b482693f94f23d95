"""The repository's layout: the tests check the package alone. Code shared by tests and
benchmarks lives in the package (:mod:`contactopt.verification`), and benchmarks/ keeps its own
checks of the code that lives only there (benchmarks/test_*.py)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCH_MODULES = {f.stem for f in (ROOT / "benchmarks").glob("*.py")}


def _benchmark_imports(source: str) -> list[str]:
    """Imports of a module of benchmarks/, and sys.path entries naming benchmarks/, in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] in BENCH_MODULES | {"benchmarks"}]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            if node.module.split(".")[0] in BENCH_MODULES | {"benchmarks"}:
                found.append(node.module)
        elif isinstance(node, ast.Call) and ast.unparse(node.func).endswith("sys.path.insert"):
            if "benchmarks" in ast.unparse(node):
                found.append("sys.path: " + ast.unparse(node))
    return found


def test_the_detector_sees_a_benchmark_import():
    src = ('import sys\nsys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))\n'
           "from hertz import measure_sphere\nimport _iterative\n")
    assert len(_benchmark_imports(src)) == 3


def test_tests_do_not_import_benchmarks():
    found = [f"{f.name}: {imp}" for f in sorted((ROOT / "tests").glob("*.py"))
             for imp in _benchmark_imports(f.read_text())]
    assert not found, "tests importing benchmarks/: " + "; ".join(found)
