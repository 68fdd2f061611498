"""Fuzzy-adaptive PI: the rule base and its Mamdani surface are symmetric and monotone."""

import numpy as np
import pytest

from emasim.control.fuzzy import GRID, KI_RULES, KP_RULES, _bilinear, mamdani_surface


@pytest.fixture(scope="module")
def surfaces():
    return mamdani_surface(KP_RULES), mamdani_surface(KI_RULES)


def test_rule_tables_are_symmetric():
    for rules in (KP_RULES, KI_RULES):
        assert rules.shape == (7, 7)
        assert np.array_equal(rules, rules[::-1, ::-1])  # rule(e, ec) = rule(-e, -ec)


def test_surfaces_are_symmetric_and_bounded(surfaces):
    for surface in surfaces:
        assert surface.shape == (GRID, GRID)
        np.testing.assert_allclose(surface, surface[::-1, ::-1], atol=1e-12)
        assert np.all(np.abs(surface) <= 1.0)


def test_kp_grows_and_ki_falls_with_the_error(surfaces):
    kp, ki = surfaces
    centre = GRID // 2
    # along e >= 0 with ec = 0: Kp rises, Ki falls (monotone, as the rule base is designed)
    assert np.all(np.diff(kp[centre:, centre]) >= -1e-12)
    assert np.all(np.diff(ki[centre:, centre]) <= 1e-12)
    assert kp[-1, centre] - kp[centre, centre] > 1.0  # from small to large gain
    assert ki[centre, centre] - ki[-1, centre] > 1.0
    # an error that keeps growing (e, ec same sign) gets more Kp than one already closing
    quarter = GRID * 3 // 4
    assert kp[quarter, quarter] > kp[quarter, GRID - 1 - quarter]


def test_mamdani_reproduces_the_rule_at_its_own_centres(surfaces):
    """At a grid point on two set centres only one rule fires fully: the centroid of a
    clipped triangle at that level, inside the neighbouring level's half-interval."""
    kp, _ = surfaces
    idx = np.linspace(0, GRID - 1, 7).round().astype(int)
    levels = np.linspace(-1, 1, 7)
    for i, gi in enumerate(idx):
        for j, gj in enumerate(idx):
            assert abs(kp[gi, gj] - levels[int(KP_RULES[i, j]) + 3]) < 1 / 3


def test_bilinear_lookup_matches_numpy_interpolation(surfaces):
    kp, _ = surfaces
    axis = np.linspace(-1, 1, GRID)
    rng = np.random.default_rng(1)
    for x, y in rng.uniform(-1.2, 1.2, size=(50, 2)):
        cx, cy = np.clip([x, y], -1, 1)
        along_y = [np.interp(cy, axis, kp[i]) for i in range(GRID)]
        assert _bilinear(kp, x, y) == pytest.approx(np.interp(cx, axis, along_y), abs=1e-12)
