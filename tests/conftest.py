"""Fixtures shared by the test files: the small configurations most tests run on.

Example 1 on an 8 × 4 × 3 mesh is the workhorse: the paper's body, loads and friction at a size
whose state solves in milliseconds. ``small_config`` builds it (validated, with section updates);
``config_file`` writes a configuration to a TOML file, with raw updates written unvalidated so
that a test can hand the CLI a bad value.
"""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from contactopt.config import Config, load_config

SMALL_MESH = {"nx": 8, "ny": 4, "nz": 3}
DATA = Path(__file__).parent / "data"


def _small_config(name: str = "small", mesh: dict | None = None, **sections) -> Config:
    """Example 1 on ``mesh`` (default 8 × 4 × 3) named ``name``, its sections updated by ``sections``."""
    return load_config("example1").with_updates({"mesh": dict(mesh or SMALL_MESH), "name": name, **sections})


@pytest.fixture
def small_config():
    """Factory: ``small_config(name="small", mesh=None, **sections)`` → a validated Config."""
    return _small_config


@pytest.fixture
def config_file(tmp_path):
    """Factory: ``config_file(config=None, name=None, directory=tmp_path, **raw)`` → the path of a TOML
    file holding ``config`` (a Config or a dict; default the small Example 1 named ``name``), each
    section of ``raw`` merged into it unvalidated (bad values allowed)."""
    def write(config=None, name: str | None = None, directory: Path | None = None, **raw) -> Path:
        if config is None:
            config = _small_config(name or "small")
        data = copy.deepcopy(config.data if isinstance(config, Config) else config)
        for sec, vals in raw.items():
            if isinstance(vals, dict) and isinstance(data.get(sec), dict):
                data[sec].update(vals)
            else:
                data[sec] = vals
        path = Path(directory or tmp_path) / f"{name or data.get('name', 'config')}.toml"
        path.write_text(tomli_w.dumps(data))
        return path
    return write


@pytest.fixture
def state_refused(tmp_path, capsys, config_file):
    """Factory: ``state_refused(config, *needles)``: ``contactopt state`` on ``config`` (a Config, a
    dict, or the path of a TOML file) exits 2, its error names every needle, and nothing is written."""
    from contactopt.cli import main

    def check(config, *needles):
        toml = config if isinstance(config, (str, Path)) else config_file(config, name="refused")
        out = tmp_path / "refused-out"
        assert main(["state", str(toml), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        for needle in needles:
            assert needle in err, err
        assert not out.exists()
    return check


@pytest.fixture
def small_toml(tmp_path):
    """Factory: ``small_toml(text="", drop=(), **sections)`` → the path of a TOML file holding Example 1
    on the 8 × 4 × 3 mesh with ``sections`` updated (validated), without the tables in ``drop``, and
    the raw TOML ``text`` appended (bad values allowed)."""
    def write(text: str = "", drop=(), **sections) -> Path:
        data = load_config("example1").with_updates({"mesh": dict(SMALL_MESH), **sections}).data
        for key in drop:
            data.pop(key)
        path = tmp_path / "bad.toml"
        path.write_text(tomli_w.dumps(data) + text)
        return path
    return write


@pytest.fixture
def refused_by_state_and_run(tmp_path, capsys):
    """Factory: ``refused_by_state_and_run(toml, message)``: ``contactopt state`` and ``contactopt run
    --max-iter 1`` on the file ``toml`` exit 2, name ``message`` on stderr and write nothing."""
    from contactopt.cli import main

    def check(toml, message):
        out = tmp_path / "out"
        for cmd in (["state"], ["run", "--max-iter", "1"]):
            code = main([cmd[0], str(toml), "--out", str(out), *cmd[1:]])
            err = capsys.readouterr().err
            assert code == 2, err
            assert message in err, err
            assert not out.exists()
    return check


@pytest.fixture
def tet_box_config(tmp_path):
    """Factory: ``tet_box_config(path="condensation", **sections)`` → a validated Config: the box of linear
    tetrahedra in tests/data/two_groups.msh clamped on top, its bottom in contact (F = 0.3), pressed
    by its weight and a pressure 0.05 on its end x1 = 1, a degree (3, 2) design, on the solver path
    ``path``, with ``sections`` updated."""
    def build(path: str = "condensation", **sections) -> Config:
        toml = tmp_path / "box.toml"
        toml.write_text(f'name = "box"\n[body]\nmesh = "{DATA / "two_groups.msh"}"\nclamped = "top"\n'
                        'contact = "bottom"\n[friction]\ncoefficient = 0.3\n'
                        '[loads]\nbody_force = [0.0, 0.0, -1.0]\n[[loads.pressure]]\non = { x1 = 1.0 }\nvalue = 0.05\n'
                        '[design]\ndegree = [3, 2]\nC0 = 0.05\nC2 = 0.002\ninitial = 0.002\n'
                        f'[linear_solver]\npath = "{path}"\n')
        return load_config(toml).with_updates(sections)
    return build


@pytest.fixture
def bundle_state_roundtrip(tmp_path):
    """Factory: ``roundtrip(state_dict, fmt)`` → the BundleState read back after writing
    ``state_dict`` as a checkpoint does, to an .npz file (``fmt = "npz"``) or as JSON."""
    import json

    import numpy as np

    from contactopt.optimize import BundleState

    def roundtrip(state: dict, fmt: str):
        if fmt == "npz":
            np.savez(tmp_path / "state.npz", **state)
            with np.load(tmp_path / "state.npz") as z:
                return BundleState.from_dict(dict(z))
        text = json.dumps({key: (v.tolist() if isinstance(v, np.ndarray) else v) for key, v in state.items()})
        return BundleState.from_dict(json.loads(text))
    return roundtrip


# instructions each OpenBLAS core type needs (a kernel this CPU lacks dies of an illegal instruction)
KERNEL_NEEDS = {"Prescott": (), "Haswell": ("avx2", "fma"), "SkylakeX": ("avx512f",), "Zen": ("avx2", "fma")}


def _cpu_flags() -> set:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


@pytest.fixture
def kernel_probe():
    """``kernel_probe(kernel, code)`` → the JSON that the Python ``code`` prints last, run in a
    subprocess with OPENBLAS_CORETYPE = ``kernel`` (one of KERNEL_NEEDS) and one BLAS thread;
    the test is skipped where this CPU cannot run that kernel."""
    return _run_under_kernel


def _run_under_kernel(kernel: str, code: str):
    if not _cpu_flags().issuperset(KERNEL_NEEDS[kernel]):
        pytest.skip(f"this CPU cannot run the {kernel} kernel")
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])
