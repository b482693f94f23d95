"""The monotonic indentation of an elastic half-space by a rigid paraboloid, with and without
Coulomb friction, from the half-space's axisymmetric surface integral equations on rings
(contactopt.verification.spence.indent): the reference for the FE's frictional Hertz figures
(docs/obstacles.md, "Friction")."""

import math

import numpy as np
import pytest

from contactopt.verification.spence import indent, punch_load_ratio, punch_system, ring_system, stick_ratio

NU = 0.3


def rings(n, nu=NU):
    return ring_system(nu, np.linspace(0.0, 1.0, n + 1))


def test_frictionless_indentation_on_rings_is_hertz():
    """F = 0: P, δ, p0 at the last step's a against Hertz (4E*a³/(3R), a²/R, 2E*a/(πR)) to 1e-3 on 120
    rings, the error falling as 1/n (60 → 120 rings); the contact radius from P, (3PR/4E*)^(1/3), and
    the Hertz profile fitted to the ring pressures to 5e-4; the gap open outside the contact."""
    errors = {}
    for n in (60, 120):
        z = indent(rings(n), 0.0)
        errors[n] = {k: v - 1 for k, v in z.hertz().items()}
    assert all(abs(e) < 1e-3 for e in errors[120].values()), errors
    rate = math.log2(errors[60]["P"] / errors[120]["P"])
    assert 0.9 < rate < 1.1, rate
    e_star = z.system.e_star
    assert (3 * z.load[-1] / (4 * e_star)) ** (1 / 3) == pytest.approx(z.a[-1], rel=5e-4)
    assert z.min_gap > 0
    a_fit, p0_fit = z.fitted()
    assert a_fit == pytest.approx(1.0, rel=5e-4)
    assert p0_fit == pytest.approx(2 * e_star / math.pi, rel=5e-4)


def test_frictional_indentation_sticks_inside_the_flat_punchs_stick_radius():
    """F = 0.3, ν = 0.3, 120 rings, one ring per step: the last step's stick disc ends within one ring
    of the frictional flat punch's c/a (Spence's self-similarity, computed from the punch on its own
    rings), its slip annulus slides inward, the shear of the stick disc stays in the cone, the
    pressure is positive on the contact and the gap open outside it in every step, and
    P/(aδ) = (4/3)E* k with k the punch's P/(2aE*δ) (dP = 2aE*k dδ with δ ∝ a²) to 3e-4 of the
    frictionless run's own error."""
    s = rings(120)
    f, z = indent(s, 0.3), indent(s, 0.0)
    ps = punch_system(NU, 120)
    lo, hi = stick_ratio(ps, 0.3)
    assert f.c < hi and f.c + 1 / 120 > lo, (f.c, lo, hi)
    m = f.stick.size
    assert np.all(f.p[:m] > 0) and f.min_gap > 0
    assert np.all(f.q[:m][~f.stick] > 0)                       # q = +F p: the body moved inward
    assert np.all(np.abs(f.q[:m][f.stick]) <= 0.3 * f.p[:m][f.stick] * (1 + 1e-12))
    ratio = f.hertz()["P/(a delta)"] / z.hertz()["P/(a delta)"]
    assert ratio == pytest.approx(punch_load_ratio(ps, 0.3), rel=3e-4)
    assert ratio > 1.02                                         # friction stiffens: k = 1.024


@pytest.mark.slow
def test_monotonic_indentation_converges_and_the_bonded_one_is_mossakovskiis():
    """ν = 0.3: the bonded indentation's P/(aδ) over (4/3)E* tends to Mossakovskii's ln(3 − 4ν)/(2β),
    the error falling with the ring count (60, 120, 240) and below 1e-3 on 240; with F = 0.3 at the
    same P the centre pressure rises by 8.0–8.3 % and a Hertz profile fitted to the pressures by
    5.5–6.0 % (the FE's fitted figure, docs/obstacles.md), the same with 1 and 8 rings per step to
    0.01 points."""
    errors = []
    for n in (60, 120, 240):
        s = rings(n)
        z = indent(s, 0.0)
        b = indent(s, math.inf).hertz()["P/(a delta)"] / z.hertz()["P/(a delta)"]
        errors.append(abs(b / (math.log(3 - 4 * NU) / (2 * s.beta)) - 1))
    assert errors[0] > errors[1] > errors[2] and errors[2] < 1e-3, errors
    zh, (_, zp) = z.hertz(), z.fitted()
    rises = []
    for per_step in (1, 8):
        f = indent(s, 0.3, rings_per_step=per_step)
        fh, (_, fp) = f.hertz(), f.fitted()
        ar = (zh["P"] / fh["P"]) ** (1 / 3)
        rises.append((fh["p0"] / zh["p0"] * ar - 1, fp / zp * ar - 1))
    assert 0.080 < rises[0][0] < 0.083 and 0.055 < rises[0][1] < 0.060, rises
    assert abs(rises[0][0] - rises[1][0]) < 1e-4 and abs(rises[0][1] - rises[1][1]) < 1e-4, rises
