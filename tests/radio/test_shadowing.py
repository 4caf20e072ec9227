"""radio/shadowing.py: seeded, spatially correlated log-normal shadowing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rescuemesh.radio.shadowing import ShadowField


def _pairs(rng, n, span=400.0):
    """n pairs of places far apart (more than two lattice spacings), in m."""
    a = rng.uniform(-span, span, size=(n, 2))
    b = rng.uniform(-span, span, size=(n, 2))
    return a, b


def test_symmetric_and_deterministic_per_seed():
    f, again = ShadowField(11, 4.0, 4.0), ShadowField(11, 4.0, 4.0)
    for a, b in [((1.0, 2.0), (7.5, 3.25)), ((-3.3, 0.1), (0.0, 0.0)), ((100.2, -50.0), (1e3, 2e3))]:
        assert f.link_db(a, b) == f.link_db(b, a)
        assert f.link_db(a, b) == again.link_db(a, b)


def test_seeds_give_different_fields():
    a, b = (1.0, 2.0), (7.5, 3.25)
    values = {round(ShadowField(seed, 4.0, 4.0).link_db(a, b), 9) for seed in range(20)}
    assert len(values) == 20
    # large and negative seeds are fine (the runtime hands down 63-bit seeds)
    assert ShadowField(2**63 - 1, 4.0, 4.0).link_db(a, b) != ShadowField(-1, 4.0, 4.0).link_db(a, b)


@pytest.mark.parametrize("sigma", [2.0, 4.0, 8.0])
def test_std_over_many_pairs_is_sigma(sigma):
    f = ShadowField(3, sigma, 4.0)
    a, b = _pairs(np.random.default_rng(0), 20_000)
    s = np.array([f.link_db(tuple(p), tuple(q)) for p, q in zip(a[:3000], b[:3000])])
    assert s.std() == pytest.approx(sigma, rel=0.06)
    assert abs(s.mean()) < 0.1 * sigma
    unit = f.unit_many(np.vstack([a, b]))
    assert unit.std() == pytest.approx(1.0, rel=0.03)


def test_sigma_zero_disables_shadowing():
    f = ShadowField(5, 0.0, 4.0)
    assert f.link_db((0.0, 0.0), (3.0, 4.0)) == 0.0
    assert np.all(f.link_db_many((0.0, 0.0), np.array([[1.0, 1.0], [9.0, 2.0]])) == 0.0)


def test_scalar_and_vectorised_agree():
    f = ShadowField(9, 4.0, 2.0)
    pts = np.random.default_rng(1).uniform(-30, 30, size=(500, 2))
    np.testing.assert_allclose(f.unit_many(pts), [f.unit(x, y) for x, y in pts], rtol=0, atol=1e-12)
    np.testing.assert_allclose(f.link_db_many((2.0, 3.0), pts), [f.link_db((2.0, 3.0), tuple(p)) for p in pts],
                               rtol=0, atol=1e-12)


def test_smooth_and_correlated_over_the_decorrelation_distance():
    spacing = 4.0
    f = ShadowField(21, 4.0, spacing)
    rng = np.random.default_rng(2)
    p = rng.uniform(-500, 500, size=(40_000, 2))
    angle = rng.uniform(0, 2 * math.pi, size=len(p))
    step = np.column_stack([np.cos(angle), np.sin(angle)])
    f0 = f.unit_many(p)

    def corr(distance):
        return np.corrcoef(f0, f.unit_many(p + distance * step))[0, 1]

    assert corr(0.05) > 0.99  # a robot moving 5 cm sees nearly the same shadow
    assert corr(0.9 * spacing) == pytest.approx(1 / math.e, abs=0.05)  # the module's stated 1/e point
    assert abs(corr(2.0 * spacing)) < 0.03
    # and the link shadow changes little when one end moves a few cm
    a = (1.0, 1.0)
    assert abs(f.link_db(a, (5.0, 5.0)) - f.link_db(a, (5.05, 5.0))) < 0.3


@pytest.mark.parametrize(("sigma", "spacing"), [(-1.0, 4.0), (4.0, 0.0), (4.0, -2.0), (math.nan, 4.0)])
def test_bad_parameters_are_refused(sigma, spacing):
    with pytest.raises(ValueError):
        ShadowField(0, sigma, spacing)
