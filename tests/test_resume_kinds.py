"""kill -9 at seeded random moments, then ``--resume``: every kind of run ends bit for bit as the
uninterrupted one, with the checkpoint format of contactopt.io.checkpoint.

The kinds: a run over two load cases (each case's warm start and zone in the checkpoint), a load
path (each step's context), a run with [[constraints]] (the penalty state beside the bundle's)
a force-controlled obstacle (the translation of its last solve rides in the warm start), a block on
two slabs along a load path and the same block with a design on each of its two contact faces.
Each is killed three times, a random delay of up to a third of one iteration's share of the wall time after
the progress line of a random iteration (so mostly mid-evaluation), and resumed as a user would
(no ``--max-iter``: the checkpoint's is kept). J, α, iterations.csv and the counts must equal the
uninterrupted run's; a run killed before its first checkpoint is refused by ``--resume`` and
started again with ``--overwrite``. ``pytest -m integration tests/test_resume_kinds.py -s`` prints
the moments.
"""

import random
from pathlib import Path

import pytest
import tomli_w

from contactopt.config import load_config
from contactopt.io.checkpoint import Checkpoint
from test_resume_paths import checkpoint_position, command, compare, environment, finish, kill_when, result

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[1]
SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
N_KILLS = 3


def load_cases():
    return load_config(ROOT / "examples" / "example1_two_cases.toml").with_updates(SMALL).to_dict()


def load_path():
    data = load_config(ROOT / "examples" / "preload_shear.toml").with_updates(SMALL).to_dict()
    return data


def constrained():
    return load_config("example1").with_updates({**SMALL, "constraints": [{"type": "max_pressure", "max": 0.02}]}
                                                ).to_dict()


def force_obstacle():
    """The block pressed by a sphere whose resultant force is given (tests/test_obstacles.py)."""
    return load_config("example1").with_updates({
        "friction": {"coefficient": 0.3}, "material": {"nu": 0.3}, "state": {"method": "newton", "tol": 1e-12},
        "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
        "design": {"degree": [3, 2], "initial": 0.01}, "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
        "mesh": {"nx": 8, "ny": 8, "nz": 3}, "body": {"clamped": "top"},
        "obstacle": {"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0, "control": "force",
                     "force": [0.0, 0.0, 1.2]}}).to_dict()


def assembly_path():
    """A block on two slabs, a pair each (friction 0.3 and 0.1), its face designed, pressed and
    then sheared along a load path (tests/test_assembly_pairs.py)."""
    import tomllib

    from test_assembly_pairs import DESIGN, TWO_SLABS
    text = TWO_SLABS.replace("friction = 0.3", "friction = 0.1", 1) + DESIGN + (
        '[[load_steps]]\nname = "press"\ntop_traction = [0.0, 0.0, -8.0e-2]\n'
        '[[load_steps]]\nname = "shear"\ntop_traction = [0.0, 0.0, -8.0e-2]\nright_traction = [4.0e-2, 0.01, 0.0]\n')
    data = tomllib.loads(text)
    data["loads"] = {}
    return data


def foundation_fullspace():
    """Example 1 on an elastic slab on the full-space path (both bodies' DOFs in its Newton
    system and in the checkpoint), pressed and then sheared along a load path."""
    data = load_config("example1").with_updates({
        **SMALL, "linear_solver": {"path": "fullspace"}, "friction": {"coefficient": 0.2},
        "foundation": {"block": {"size": [3.0, 2.0, 1.0], "cells": [6, 4, 2], "origin": [-0.5, -0.5]},
                       "material": {"E": 2.0}},
        "load_steps": [{"name": "press", "top_traction": [0.0, 0.0, -8.0e-2]},
                       {"name": "shear", "top_traction": [0.0, 0.0, -8.0e-2], "right_traction": [4.0e-2, 0.01, 0.0]}],
        "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]}}).to_dict()
    return data


def two_designs():
    """The block on two slabs with a design on each of its two contact faces
    (tests/test_several_designs.py), pressed and then sheared along a load path: α of two
    designs and each step's context in the checkpoint."""
    import tomllib

    from test_assembly_pairs import TWO_SLABS
    from test_several_designs import FIRST, SECOND
    data = tomllib.loads(TWO_SLABS + FIRST + SECOND + (
        '[[load_steps]]\nname = "press"\ntop_traction = [0.0, 0.0, -8.0e-2]\n'
        '[[load_steps]]\nname = "shear"\ntop_traction = [0.0, 0.0, -8.0e-2]\nright_traction = [4.0e-2, 0.01, 0.0]\n'))
    data["loads"] = {}
    return data


def floating_face_fullspace():
    """The dovetail (examples/dovetail.toml: its blade held only by its two flanks, two designs)
    on the full-space path: the blade's anchor rebuilt with the hierarchy at a resume."""
    return load_config(ROOT / "examples" / "dovetail.toml").with_updates(
        {"linear_solver": {"path": "fullspace"}}).to_dict()


def chain_fullspace():
    """The bolted stack (examples/bolted_stack.toml: three pairs in a chain, a face on a counterpart
    body of another pair, the head held along the bolt by its contact alone) on the full-space path."""
    return load_config(ROOT / "examples" / "bolted_stack.toml").with_updates(
        {"linear_solver": {"path": "fullspace"}}).to_dict()


KINDS = {"load_cases": (load_cases, 14), "load_path": (load_path, 12), "constrained": (constrained, 14),
         "force_obstacle": (force_obstacle, 12), "assembly_path": (assembly_path, 12),
         "foundation_fullspace": (foundation_fullspace, 12), "two_designs": (two_designs, 14),
         "floating_face_fullspace": (floating_face_fullspace, 8), "chain_fullspace": (chain_fullspace, 6)}


def what_the_checkpoint_holds(ckpt: Checkpoint) -> dict:
    return {"cases": len(ckpt.contexts), "steps": [len(c) for c in ckpt.contexts],
            "penalty": ckpt.penalty is not None}


@pytest.mark.parametrize("kind", list(KINDS))
def test_a_run_killed_at_random_moments_resumes_bit_for_bit(tmp_path, kind):
    build, max_iter = KINDS[kind]
    data = {**build(), "name": f"kill-{kind}"}
    data["optimizer"] = {**data.get("optimizer", {}), "ftol": 0.0, "eps": 1e-8}    # on to --max-iter
    cfg_file = tmp_path / f"{kind}.toml"
    cfg_file.write_text(tomli_w.dumps(load_config(data).to_dict()))
    env = environment()
    ref_dir = tmp_path / "uninterrupted"
    code, text, ref_wall = finish(command(cfg_file, ref_dir, "--max-iter", max_iter), env, tmp_path / "ref.log")
    assert code == 0 and "Traceback" not in text, text
    ref = result(ref_dir)
    holds = what_the_checkpoint_holds(Checkpoint.read(ref_dir / "checkpoint.npz"))
    assert {"load_cases": holds["cases"] == 2, "load_path": len(holds["steps"]) == 1 and holds["steps"][0] >= 2,
            "constrained": holds["penalty"], "force_obstacle": holds["steps"] == [1],
            "assembly_path": holds["steps"] == [2], "foundation_fullspace": holds["steps"] == [2],
            "two_designs": holds["steps"] == [2], "floating_face_fullspace": holds["steps"] == [1],
            "chain_fullspace": holds["steps"] == [1]}[kind], holds
    print(f"\n[{kind}] uninterrupted: {ref['iterations']} iterations, {ref['evaluations']} evaluations, "
          f"{ref_wall:.1f} s; the checkpoint holds {holds}")
    rng = random.Random(f"kill -9 a {kind} run")
    # the wall time holds the set-up and the outputs too: a third of its share per iteration
    per_iteration = ref_wall / max(3 * ref["iterations"], 1)
    failures = []
    for n in range(N_KILLS):
        when = (rng.randint(1, max(ref["iterations"] - 2, 1)), round(rng.uniform(0.0, per_iteration), 3))
        out = tmp_path / f"kill{n}"
        start = command(cfg_file, out, "--max-iter", max_iter)
        what = kill_when(start, env, tmp_path / f"kill{n}.log", iteration=when[0], delay=when[1])
        position = checkpoint_position(out)
        code, text, _ = finish(command(cfg_file, out, "--resume"), env, tmp_path / f"resume{n}.log")
        assert "Traceback" not in text, text
        if position is None:
            assert code == 2 and "no checkpoint" in text, text
            code, text, _ = finish(start + ["--overwrite"], env, tmp_path / f"restart{n}.log")
        assert code == 0, text
        bad = compare(ref, result(out))
        print(f"[{kind}] {what} after iteration {when[0]} + {when[1]} s; checkpoint {position}: "
              f"{'bit for bit' if not bad else bad}")
        if bad:
            failures.append(f"kill {n} ({when}): {bad}")
    assert not failures, failures
