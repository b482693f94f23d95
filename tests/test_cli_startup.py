"""The command line starts without the solver's modules: ``contactopt --help``, every command's
``--help``, ``contactopt schema`` and the refusal of a bad configuration import neither matplotlib,
nor scipy, nor the FEM model, the problem, the runner or the file-format libraries (docs/measurements.md,
"Start-up of the command line"). Each check runs in a fresh interpreter, whose modules it lists."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

# what the solver, its figures and its file formats bring in (about a second of imports)
HEAVY = ("matplotlib", "scipy", "scipy.sparse", "scipy.optimize", "h5py", "meshio", "pyamg", "distributed",
         "contactopt.fem.model", "contactopt.problem", "contactopt.runner", "contactopt.paths",
         "contactopt.io.plots", "contactopt.io.statefiles", "contactopt.studies")

COMMANDS = ("run", "state", "export", "check-gradient", "sweep", "solve-fclib", "examples", "schema")

# runs main(argv) and prints, as its last line, the exit code and the heavy modules it imported
_PROBE = """
import json, sys
from contactopt.cli import main
argv = json.loads(sys.argv[1])
heavy = json.loads(sys.argv[2])
try:
    code = main(argv) if argv is not None else 0
except SystemExit as exc:
    code = exc.code
sys.stdout.flush()
print("\\nPROBE " + json.dumps({"code": code, "loaded": [m for m in heavy if m in sys.modules]}))
"""


def _probe(argv, cwd=None):
    """(exit code, heavy modules loaded, stdout before the probe's line, stderr) of
    ``contactopt <argv>`` in a fresh interpreter; ``argv=None`` only imports contactopt.cli."""
    proc = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(argv), json.dumps(HEAVY)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)
    out, _, last = proc.stdout.rstrip("\n").rpartition("\n")
    assert last.startswith("PROBE "), proc.stdout + proc.stderr
    res = json.loads(last[len("PROBE "):])
    return res["code"], res["loaded"], out, proc.stderr


def test_the_probe_sees_a_heavy_module(tmp_path):
    """The check can fail: solve-fclib imports h5py and scipy before it finds no file."""
    code, loaded, _, err = _probe(["solve-fclib", str(tmp_path / "missing.hdf5")])
    assert code == 2 and "missing.hdf5" in err, err
    assert {"h5py", "scipy", "scipy.sparse"} <= set(loaded), loaded


def test_importing_the_cli_imports_no_solver_module():
    code, loaded, _, err = _probe(None)
    assert (code, loaded) == (0, []), err


def test_help_imports_no_solver_module():
    code, loaded, out, err = _probe(["--help"])
    assert (code, loaded) == (0, []), err
    for command in COMMANDS:
        assert command in out


@pytest.mark.parametrize("command", COMMANDS)
def test_a_commands_help_imports_no_solver_module(command):
    code, loaded, out, err = _probe([command, "--help"])
    assert (code, loaded) == (0, []), err
    assert out.startswith(f"usage: contactopt {command}"), out


def test_the_schema_imports_no_solver_module():
    code, loaded, out, err = _probe(["schema"])
    assert (code, loaded) == (0, []), err
    schema = json.loads(out)
    assert "optimizer" in schema["properties"] and "mesh" in schema["properties"]


@pytest.mark.parametrize("command", ["run", "state", "check-gradient"])
def test_a_bad_configuration_is_refused_without_the_solver(tmp_path, config_file, command):
    """Exit 2, the error names the key, nothing is written, and no solver module was imported."""
    toml = config_file(optimizer={"max_iter": 0}, friction={"coefficient": -0.3})
    out = tmp_path / "out"
    argv = [command, str(toml)] + (["--out", str(out)] if command != "check-gradient" else [])
    code, loaded, _, err = _probe(argv, cwd=tmp_path)
    assert (code, loaded) == (2, []), err
    assert "invalid configuration" in err and "optimizer.max_iter" in err and "friction.coefficient" in err, err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [toml.name]     # no output directory


def test_run_says_a_deprecated_key_once_ahead_of_the_error(tmp_path, config_file):
    """``run`` checks the configuration before the optimizer loads, and a deprecation warning is
    printed once, before the error, as when the run itself rejects it."""
    toml = config_file(linear_solver={"backend": "pardiso"}, optimizer={"max_iter": 0})
    code, loaded, _, err = _probe(["run", str(toml), "--out", str(tmp_path / "out")])
    assert (code, loaded) == (2, []), err
    assert err.count("backend = 'pardiso' is deprecated") == 1, err
    assert err.index("is deprecated") < err.index("invalid configuration") and "optimizer.max_iter" in err
    assert not (tmp_path / "out").exists()
