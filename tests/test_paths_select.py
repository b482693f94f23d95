"""How a configuration finds its solver path: what it needs (paths.needs), what each path declares
it takes (Capabilities), the refusal that names both, and the typed calls of the MPI ranks."""

from dataclasses import replace

import pytest

import contactopt.paths as paths
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.paths import Capabilities, needs, select_path
from contactopt.paths.protocol import Call, Command, Follower, Problem, Stop


def example1(**updates):
    return load_config("example1").with_updates(updates)


def test_the_papers_examples_need_nothing_beyond_the_rigid_plane():
    for name in ("example1", "example2", "example3"):
        assert needs(load_config(name)) == {}
    got = needs(example1(objective={"type": "peak_stress"}), pinned=4, ranks=3)
    assert got == {"pinned": "4", "whole_displacement": "peak_stress", "many_ranks": "3"}


def test_a_refusal_names_the_need_the_lack_and_the_paths_that_take_it():
    with pytest.raises(ConfigError) as err:
        select_path(example1(linear_solver={"path": "delassus"}, objective={"type": "compliance"}), 1000)
    assert err.value.problems == [
        "linear_solver.path = 'delassus': the compliance objective needs the condensed load on every contact "
        "DOF; use path 'condensation' or 'auto'",
        "linear_solver.path = 'delassus': this configuration needs the compliance objective; the 'delassus' "
        "path lacks the compliance objective; 'condensation' takes it all"]


def test_auto_refuses_what_no_path_takes_and_lists_every_path(monkeypatch):
    """Two MPI ranks and the compliance objective: the PETSc path takes the ranks, the
    condensation the objective, none both."""
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    with pytest.raises(ConfigError) as err:
        select_path(example1(objective={"type": "compliance"}), 1000)
    (msg,) = err.value.problems
    assert msg.startswith("linear_solver.path = 'auto': no solver path takes this configuration")
    for name in paths.NAMES:
        assert f"'{name}' lacks" in msg


@pytest.mark.parametrize("objective", [{"type": "peak_stress"}, {"type": "frictional_dissipation"},
                                       {"type": "sum", "terms": [{"type": "target_normal_force", "weight": 1.0},
                                                                 {"type": "peak_stress", "weight": 0.1}]}])
def test_every_path_takes_objectives_of_the_whole_displacement_and_the_petsc_path_under_mpiexec(objective,
                                                                                                monkeypatch):
    """Peak stress, friction work, a sum with one of them, and [[constraints]] of those types: every
    path declares them, and under mpiexec the PETSc path is the one that runs them."""
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    for cfg in (example1(objective=objective),
                example1(constraints=[{"type": objective["type"] if objective["type"] != "sum" else "peak_stress",
                                       "max": 1.0}])):
        need = needs(cfg, ranks=2)
        assert "whole_displacement" in need
        assert [n for n, cls in paths.PATHS.items() if not cls.capabilities.lacks(need)] == ["petsc"]
        assert paths._auto(list(paths.PATHS.values()), 1000, 10, 2, need).name == "petsc"


def test_a_new_capability_is_one_field_and_the_paths_that_declare_it(monkeypatch):
    """A path's declaration decides: with load steps taken away from every path but the
    condensation, "auto" on a large mesh falls back to it and "fullspace" is refused."""
    cfg = example1(load_steps=[{"name": "a"}], linear_solver={"crossover": 10})
    assert select_path(cfg, 1000)[0] == "fullspace"
    for name in ("delassus", "fullspace"):
        cls = paths.PATHS[name]
        monkeypatch.setattr(cls, "capabilities", replace(cls.capabilities, load_steps=False))
    assert select_path(cfg, 1000)[0] == "condensation"
    with pytest.raises(ConfigError, match="use linear_solver.path = 'condensation'"):
        select_path(cfg.with_updates({"linear_solver": {"path": "fullspace"}}), 1000)
    assert "load_steps" in Capabilities.features()


def test_the_ranks_calls_are_typed_messages_and_every_command_has_its_handler():
    from contactopt.paths.petsc import PetscPath
    assert set(PetscPath.handlers) == set(Command)

    class Served:
        handlers = {Command.SOLVE: lambda self, key, tol: (self, key, tol)}

    follower, path = Follower(), Served()
    follower.add("a1", path)
    assert follower.make(Call("a1", Command.SOLVE, (3, 1e-10))) == (path, 3, 1e-10)
    with pytest.raises(KeyError):
        follower.make(Call("other", Command.SOLVE, (3, 1e-10)))
    assert Problem("a1", None).path_id == "a1" and Stop() == Stop()


def test_the_feature_table_is_what_the_paths_linear_algebra_takes():
    """The features each path declares, as a table: every feature is taken by some path (a rule
    that no path takes belongs to the configuration's validation), and a force-controlled obstacle
    is an obstacle (the translation's search runs on whatever solves the obstacle)."""
    table = {f: [n for n, cls in paths.PATHS.items() if getattr(cls.capabilities, f)] for f in Capabilities.features()}
    every = ["condensation", "delassus", "fullspace", "petsc"]
    assert table == {"foundation": ["condensation", "fullspace", "petsc"], "pairs": ["condensation", "fullspace", "petsc"],
                     "counterpart_force": ["condensation", "fullspace", "petsc"], "obstacle": ["condensation", "delassus", "fullspace", "petsc"],
                     "obstacle_steps": ["condensation"], "held_by_contact": ["condensation", "fullspace", "petsc"], "pinned": every,
                     "compliance": ["condensation"], "whole_displacement": every, "load_steps": every,
                     "many_ranks": ["petsc"]}
    forced = example1(obstacle={"shape": "sphere", "center": [1.5, 0.5, -5.0], "radius": 5.0, "control": "force",
                                "force": [0.0, 0.0, 1.0]})
    assert needs(forced) == {"obstacle": "force-controlled sphere"}


def test_features_that_exclude_each_other_on_every_path_are_refused_by_the_configuration():
    from contactopt.config.validation import check_interactions
    on_foundation = example1(foundation={"block": {"size": [3.0, 2.0, 1.0], "cells": [6, 4, 2],
                                                   "origin": [-0.5, -0.5]}})
    check_interactions(on_foundation)
    check_interactions(example1(), pinned=4, rigid="the translation along x1")
    check_interactions(on_foundation, rigid="the translation along x1")     # held by the contact on it
    with pytest.raises(ConfigError) as err:
        check_interactions(on_foundation, pinned=4, rigid="the translation along x1")
    pinned, = err.value.problems
    assert pinned.startswith("body.clamped: 4 tangential component(s)") and "elastic [foundation] does not take" in pinned
