"""The held-out rule's statistics: Student's t of paired differences and its one-sided p-value,
checked against the closed forms of Student's distribution on 1 and 2 degrees of freedom."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brakegym.statistics import conditional_information, paired_t, paired_t_p_value


@pytest.mark.parametrize("differences", [[0.3, 0.1], [0.05, 0.2], [-0.1, 0.4], [0.2, -0.5]])
def test_p_value_on_one_degree_of_freedom_is_the_cauchy_tail(differences):
    t = paired_t(np.array(differences))
    assert paired_t_p_value(np.array(differences)) == pytest.approx(0.5 - math.atan(t) / math.pi, rel=1e-12)


@pytest.mark.parametrize("differences", [[0.3, 0.1, 0.2], [0.01, 0.2, 0.05], [-0.1, 0.3, 0.1]])
def test_p_value_on_two_degrees_of_freedom(differences):
    t = paired_t(np.array(differences))
    assert paired_t_p_value(np.array(differences)) == pytest.approx(0.5 - t / (2 * math.sqrt(2 + t * t)), rel=1e-12)


def test_the_same_t_is_weaker_evidence_over_fewer_recordings():
    # Differences whose mean is 2 of their standard errors: t = 2 over 2, 4 and 8 recordings.
    p = {}
    for n in (2, 4, 8):
        spread = np.linspace(-1.0, 1.0, n)
        mean = 2.0 * np.std(spread, ddof=1) / math.sqrt(n)
        differences = mean + spread
        assert paired_t(differences) == pytest.approx(2.0)
        p[n] = paired_t_p_value(differences)
    assert p[2] > p[4] > p[8]
    assert p[2] == pytest.approx(0.5 - math.atan(2.0) / math.pi)  # 0.148
    assert 0.0228 < p[8] < 0.05  # above the normal's tail at 2 sigma


def test_degenerate_differences():
    assert math.isnan(paired_t_p_value(np.array([0.3])))
    assert math.isnan(paired_t_p_value(np.zeros(0)))
    assert paired_t_p_value(np.array([0.25, 0.25, 0.25])) == 0.0
    assert paired_t_p_value(np.array([-0.5, -0.5])) == 1.0


def test_conditional_information_of_a_regular_matrix_is_the_reciprocal_of_the_covariance_diagonal():
    rng = np.random.default_rng(3)
    jacobian = rng.normal(size=(40, 3))
    information = jacobian.T @ jacobian
    expected = 1.0 / np.diag(np.linalg.inv(information))
    np.testing.assert_allclose(conditional_information(information), expected, rtol=1e-10)


def test_conditional_information_is_zero_where_the_matrix_says_nothing_or_cannot_separate():
    # The third parameter moves no row; the first two move the rows only as their sum.
    jacobian = np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 0.0], [0.5, 0.5, 0.0]])
    assert conditional_information(jacobian.T @ jacobian) == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    # One more row holds them apart: the rows know the sum s by 1 + 4 + 0.25 = 5.25 and the
    # difference d by 1, and each parameter, (s +- d) / 2, by 4 / (1 / 5.25 + 1 / 1).
    jacobian = np.vstack([jacobian, [1.0, -1.0, 0.0]])
    information = conditional_information(jacobian.T @ jacobian)
    assert information[:2] == pytest.approx([4 / (1 / 5.25 + 1)] * 2, rel=1e-9)
    assert information[2] == 0.0
