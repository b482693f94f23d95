"""Maps and plots of a contact face are labelled in its chart's coordinates
(contactopt.design.chart.ChartAxes): on the bore of Lamé's quarter hub (a cylinder) the arc length ρθ
and the axial position, on a plane chart its in-plane axes, on the paper's block x1, x2 as before;
state.json and summary.json name the coordinates their x1, x2 hold."""

import json

import numpy as np
import pytest

from contactopt.config import load_config, validate
from contactopt.design.chart import fit_plane
from contactopt.fem.model import ElasticModel
from contactopt.io import forked, plots
from contactopt.io.statefiles import write_state
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization
from contactopt.verification import lame

# the bore of radius 1.5 around x3, its chart's names
ARC = "$\\xi_1 = \\rho\\theta$, arc length ($\\rho$ = 1.5)"
AXIAL = "$\\xi_2$, axial position along (0, 0, 1)"
MAPS = ("lambda.png", "pressure.png", "classes.png", "contact.png")


@pytest.fixture
def figures(monkeypatch):
    """{file name: Figure} of every figure saved while the test runs, drawn in this process."""
    drawn, save = {}, plots._save

    def keep(fig, path):
        drawn[path.name if hasattr(path, "name") else str(path)] = fig
        return save(fig, path)
    monkeypatch.setattr(plots, "_save", keep)
    monkeypatch.setattr(forked, "can_fork", lambda: False)     # a run's figures drawn here, not in a child
    return drawn


def map_labels(fig) -> list[tuple[str, str]]:
    """(x label, y label) of every axes of ``fig`` but its colour bars."""
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes if ax.get_label() != "<colorbar>"]


@pytest.fixture(scope="module")
def bore(tmp_path_factory):
    """The quarter hub b = 1.5, c = 3 on its rigid shaft, friction 0.3, the bore on its cylindrical chart."""
    tmp = tmp_path_factory.mktemp("hub")
    mesh = lame.quarter_hub_mesh(tmp / "hub.msh", 2, 6, 2, b=1.5, c=3.0, length=0.25)
    return validate(lame.shrink_fit_config(mesh, b=1.5, length=0.25, degree=(2, 1), friction=0.3,
                                           objective={"type": "pressure_uniformity"}), "hub")


def test_the_state_of_a_bore_is_mapped_in_arc_length_and_axial_position(bore, tmp_path, figures):
    problem = ShapeProblem(bore)
    model = problem.model
    write_state(tmp_path / "state", model, problem.solve_state(model.initial_design()))
    for name in MAPS:
        labels = map_labels(figures[name])
        assert labels and all(pair == (ARC, AXIAL) for pair in labels), (name, labels)
    # the peak stress is drawn in the body's own coordinates
    assert ("$x_1$", "$x_2$") in map_labels(figures["von_mises.png"])
    doc = json.loads((tmp_path / "state" / "state.json").read_text())
    xi1, xi2 = doc["chart"]["axes"]
    assert xi1.startswith("xi1 = rho*theta: arc length on the cylinder of radius rho = 1.5, ")
    assert xi1.endswith("from the direction (0.707107, 0.707107, 0)")      # θ = 0 in the middle of the quarter
    assert xi2 == "xi2 = (x - o).a: axial position along a = (0, 0, 1) from o = (0, 0, 0.125)"
    # the keys x1, x2 stay; they hold ξ: the arc length spans the quarter ρπ/2, the axial position ±L/2
    c = doc["contact"]
    assert np.ptp(c["x1"]) == pytest.approx(1.5 * np.pi / 2, rel=1e-12)
    assert np.min(c["x2"]) == pytest.approx(-0.125, abs=1e-12) and np.max(c["x2"]) == pytest.approx(0.125, abs=1e-12)


def test_the_run_on_a_bore_labels_its_maps_and_its_surface_in_the_charts_coordinates(bore, tmp_path, figures):
    run_optimization(bore, tmp_path / "run", max_iter=1)
    for name in ("pressure.png", "stress.png", "contact.png", "classes.png"):
        labels = map_labels(figures[name])
        assert labels and all(pair == (ARC, AXIAL) for pair in labels), (name, labels)
    surface = figures["surface.png"].axes[0]
    assert (surface.get_xlabel(), surface.get_ylabel()) == (ARC, AXIAL)
    assert surface.get_zlabel() == "$\\vartheta_\\alpha$ along the inward normal"     # motion = "normal"
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["chart"]["axes"][1] == "xi2 = (x - o).a: axial position along a = (0, 0, 1) from o = (0, 0, 0.125)"


def test_the_papers_block_keeps_x1_x2(tmp_path, figures):
    model = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": 6, "ny": 3, "nz": 2}}))
    p = np.arange(model.n_contact, dtype=float)
    plots.plot_contact_field(tmp_path / "field.png", model, p, "p")
    plots.plot_stress_comparison(tmp_path / "bars.png", model, p, p, p)
    plots.plot_surface(tmp_path / "surface.png", model, model.initial_design())
    for name in ("field.png", "bars.png"):
        assert set(map_labels(figures[name])) == {("$x_1$", "$x_2$")}, name
    surface = figures["surface.png"].axes[0]
    assert (surface.get_xlabel(), surface.get_ylabel(), surface.get_zlabel()) == ("$x_1$", "$x_2$", "$x_3$")


def test_a_plane_chart_names_its_in_plane_axes():
    rng = np.random.default_rng(0)
    down = np.tile([0.0, 0.0, -1.0], (20, 1))
    # the plane x3 = 0, the body above it, through the origin (0.5, 0.25, 0): ξ = (x1 − 0.5, x2 − 0.25)
    flat, _ = fit_plane(np.c_[rng.random((20, 2)), np.zeros(20)], down, origin=[0.5, 0.25, 0.0])
    assert flat.axes.labels == ("$\\xi_1 = x_1 - 0.5$", "$\\xi_2 = x_2 - 0.25$")
    assert flat.axes.names == ("xi1 = x1 - 0.5", "xi2 = x2 - 0.25")
    # a flank x1 = x3 tan 30° with its outward normal (cos 30°, 0, −sin 30°): ξ1 up the slope, ξ2 along x2
    n = np.array([np.cos(np.pi / 6), 0.0, -0.5])
    x = np.c_[rng.random(20) * np.tan(np.pi / 6), rng.random(20) - 0.5, rng.random(20)]
    x[:, 0] = x[:, 2] * np.tan(np.pi / 6)
    flank, _ = fit_plane(x, np.tile(n, (20, 1)), origin=[0.0, 0.0, 0.0])
    assert flank.axes.labels == ("$\\xi_1$ along (0.5, 0, 0.866)", "$\\xi_2 = x_2$")
    assert np.allclose(flank.parameters(x)[:, 0], 2 * x[:, 2] / np.sqrt(3), atol=1e-12)     # the length up the slope


def test_a_run_without_a_target_compares_the_initial_and_the_optimal_design_alone(bore, tmp_path, figures):
    """An objective without a target (pressure uniformity) draws no empty "target" panel; Example 1's
    target stays the first of three."""
    run_optimization(bore, tmp_path / "run", max_iter=1)
    for name in ("pressure.png", "stress.png"):
        titles = [ax.get_title().split("\n")[0] for ax in figures[name].axes if ax.get_label() != "<colorbar>"]
        assert titles == ["initial design", "optimal design"], (name, titles)
    model = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": 6, "ny": 3, "nz": 2}}))
    p = np.arange(model.n_contact, dtype=float)
    plots.plot_stress_comparison(tmp_path / "bars.png", model, p, p, p)
    assert [ax.get_title().split("\n")[0] for ax in figures["bars.png"].axes] == ["target", "initial design",
                                                                                   "optimal design"]


def test_a_length_unit_is_written_on_every_length_axis(bore, tmp_path, figures):
    """``length_unit`` names the meshes' unit on the axes of the maps, the surface and the stress plot;
    a configuration without one resolves as before (no key) and its labels carry none."""
    hub = bore.with_updates({"length_unit": "mm"})
    assert hub.length_unit == "mm" and "length_unit" not in bore.data and bore.length_unit == ""
    problem = ShapeProblem(hub)
    model = problem.model
    write_state(tmp_path / "state", model, problem.solve_state(model.initial_design()))
    for name in MAPS:
        assert set(map_labels(figures[name])) == {(ARC + " [mm]", AXIAL + " [mm]")}, name
    assert ("$x_1$ [mm]", "$x_2$ [mm]") in map_labels(figures["von_mises.png"])
    plots.plot_surface(tmp_path / "surface.png", model, model.initial_design())
    surface = figures["surface.png"].axes[0]
    assert (surface.get_xlabel(), surface.get_zlabel()) == (ARC + " [mm]",
                                                          "$\\vartheta_\\alpha$ along the inward normal [mm]")
    with pytest.raises(Exception, match="length_unit"):
        bore.with_updates({"length_unit": " mm "})
