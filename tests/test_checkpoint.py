"""The checkpoint format (contactopt.io.checkpoint): one version, parts as structured keys, the
number of load cases and steps stored, and a resume refused with a message that says why."""

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.errors import CheckpointError
from contactopt.io.checkpoint import VERSION, Checkpoint, SavedResult, flatten_config
from contactopt.optimize import minimize_bundle
from contactopt.optimize.constrained import PenaltyState
from contactopt.optimize.gallery import get_problem


@pytest.fixture(scope="module")
def bundle_state():
    prob = get_problem("CB2")
    return minimize_bundle(prob, prob.x0, max_iter=3).state


def a_checkpoint(state, **kw) -> Checkpoint:
    contexts = [[{"warm": np.arange(6.0).reshape(2, 3), "zone": np.array([0, 1])}, {"warm": np.ones((2, 3))}],
                [{"warm": np.zeros(0), "zone": np.array([1])}, {}]]
    args = dict(bundle=state, evaluations=7, elapsed=1.5, scale=2.0, eps=1e-5, max_iter=40,
                config={"friction.F": 0.3, "name": "x"}, contexts=contexts, alpha=np.linspace(0, 1, 4))
    return Checkpoint(**{**args, **kw})


def test_a_checkpoint_reads_back_what_was_written(tmp_path, bundle_state):
    pen = PenaltyState(3.0, outer=1, nit=2, nfev=4, at_x=(1.0, np.ones(2), np.array([0.1]), np.ones((1, 2))))
    ck = a_checkpoint(bundle_state, penalty=pen, result=SavedResult(4, "done", "f_change", 1e-9))
    ck.write(tmp_path / "c.npz")
    back = Checkpoint.read(tmp_path / "c.npz")
    assert back.arrays().keys() == ck.arrays().keys()
    for key, value in ck.arrays().items():
        assert np.array_equal(back.arrays()[key], value), key
    assert [len(c) for c in back.contexts] == [2, 2] and back.contexts[1][1] == {}
    assert back.iteration == bundle_state.nit + 2 and back.finished and back.result.criterion == "f_change"
    with np.load(tmp_path / "c.npz") as z:       # one version number, parts as <part>/<field>
        assert int(z["format/version"]) == VERSION
        assert not [k for k in z.files if k.endswith("version") and k != "format/version"]
        assert {k.split("/")[0] for k in z.files} == {"format", "run", "config", "bundle", "penalty", "result",
                                                     "case0", "case1"}


@pytest.mark.parametrize("cut", [0, 100, 0.5])
def test_a_truncated_checkpoint_names_the_file_and_overwrite(tmp_path, bundle_state, cut):
    path = tmp_path / "checkpoint.npz"
    a_checkpoint(bundle_state).write(path)
    data = path.read_bytes()
    path.write_bytes(data[:int(cut * len(data)) if isinstance(cut, float) else cut])
    with pytest.raises(CheckpointError) as info:
        Checkpoint.read(path)
    assert str(path) in str(info.value) and "--overwrite" in str(info.value)
    assert "truncated or corrupt" in str(info.value)


def test_an_older_checkpoint_is_refused(tmp_path, bundle_state):
    path = tmp_path / "checkpoint.npz"
    old = {f"bundle_{k}": np.asarray(v) for k, v in bundle_state.to_dict().items()}
    np.savez(path, meta_fingerprint=np.array("0123"), meta_evaluations=np.array(3), **old)
    with pytest.raises(CheckpointError, match="older contactopt.*--overwrite"):
        Checkpoint.read(path)


def test_another_configuration_is_named_key_by_key(bundle_state):
    ck = a_checkpoint(bundle_state)
    with pytest.raises(CheckpointError, match=r"friction\.F \(0\.3 → 0\.2\)"):
        ck.require_config({"friction.F": 0.2, "name": "x"}, "ckpt")
    with pytest.raises(CheckpointError, match=r"extra \(absent → 1\)"):
        ck.require_config({"friction.F": 0.3, "name": "x", "extra": 1}, "ckpt")
    ck.require_config({"friction.F": 0.3, "name": "x"}, "ckpt")


def test_the_cases_and_steps_are_stored_not_guessed(bundle_state):
    ck = a_checkpoint(bundle_state)
    ck.require_shape([2, 2], "ckpt")
    with pytest.raises(CheckpointError, match="2 load case"):
        ck.require_shape([2], "ckpt")
    with pytest.raises(CheckpointError, match="load steps per case"):
        ck.require_shape([2, 1], "ckpt")


def test_flattened_configuration_numbers_lists_of_tables():
    flat = flatten_config({"a": {"b": 1, "c": [1, 2]}, "constraints": [{"name": "x"}, {"name": "y"}]})
    assert flat == {"a.b": 1, "a.c": [1, 2], "constraints.0.name": "x", "constraints.1.name": "y"}


def test_a_resume_with_another_configuration_names_the_key(tmp_path, capsys, config_file):
    cfg = config_file()
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    (tmp_path / "other").mkdir()
    other = config_file(friction={"coefficient": 0.25}, directory=tmp_path / "other")
    assert main(["run", str(other), "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "another configuration" in err and "friction.coefficient (0.3 → 0.25)" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    assert "name (" not in err           # only the key that differs
