"""The morph weight above DIRECT_MAX_NODES free nodes: AMG-preconditioned CG, no direct solve (the
full-space path's set-up needs no factorization), and the same w as the direct solve."""

import numpy as np

import contactopt.fem.linsolve as linsolve
import contactopt.fem.weight as weight
from contactopt.config import load_config
from contactopt.fem.model import ElasticModel


def test_large_meshes_get_the_morph_weight_without_a_direct_solve(monkeypatch):
    cfg = load_config("example1").with_updates({"mesh": {"nx": 12, "ny": 6, "nz": 5}})
    direct = ElasticModel(cfg)
    monkeypatch.setattr(weight, "DIRECT_MAX_NODES", 10)

    def refuse(*a, **k):
        raise AssertionError("a direct solve in the morph weight above DIRECT_MAX_NODES")
    monkeypatch.setattr(linsolve, "factorize", refuse)
    calls = []
    amg_cg = weight._amg_cg
    monkeypatch.setattr(weight, "_amg_cg", lambda K, rhs: calls.append(K.shape) or amg_cg(K, rhs))
    amg = ElasticModel(cfg)
    assert calls and calls[0][0] > 10
    a = direct.initial_design() * 3.0
    x_direct, x_amg = direct.mesh.coordinates(a), amg.mesh.coordinates(a)
    assert np.abs(x_amg - x_direct).max() <= 1e-10 * np.abs(x_direct).max()
