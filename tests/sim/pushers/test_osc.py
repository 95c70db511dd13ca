import math

import numpy as np
import pytest

from masspush.sim.pushers.osc import (
    KD,
    KP,
    desired_acceleration,
    osc_torque,
    rotation_error,
    task_inertia,
)


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


@pytest.mark.parametrize("angle", [1e-4, 0.3, 2.0, math.pi - 1e-3])
def test_rotation_error_is_the_rotation_vector_between_orientations(angle):
    r = rot([1, 2, 0.5], 0.7)
    axis = np.array([0.2, -1.0, 0.4]) / np.linalg.norm([0.2, -1.0, 0.4])
    r_des = rot(axis, angle) @ r
    np.testing.assert_allclose(rotation_error(r_des, r), angle * axis, atol=1e-6)
    np.testing.assert_allclose(rotation_error(r, r), 0.0, atol=1e-12)


def test_half_turn_has_the_right_angle():
    err = rotation_error(rot([0, 0, 1], math.pi), np.eye(3))
    assert np.linalg.norm(err) == pytest.approx(math.pi)
    assert abs(err[2]) == pytest.approx(math.pi)


def test_papers_gains_and_pd_rule():
    assert (KP, KD) == (3000.0, 152.0)
    xdd = desired_acceleration(
        np.array([0.01, 0, 0]), np.array([0, 0.1, 0]), np.zeros(6), np.array([1.0, 0, 0, 0, 0, 0])
    )
    np.testing.assert_allclose(xdd, [30 + 152, 0, 0, 0, 300, 0])


def test_task_inertia_and_torque():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    mass = a @ a.T + 6 * np.eye(6)
    jac = rng.normal(size=(6, 6))
    lam = task_inertia(jac, mass, damping=0.0)
    np.testing.assert_allclose(lam, np.linalg.inv(jac @ np.linalg.inv(mass) @ jac.T), rtol=1e-8)
    # With J = I the law reduces to tau = M xdd.
    xdd = rng.normal(size=6)
    np.testing.assert_allclose(osc_torque(np.eye(6), mass, xdd), mass @ xdd, rtol=1e-4)


def test_scaling_to_limits_keeps_direction_and_respects_every_limit():
    from masspush.sim.pushers.osc import scale_to_limits

    tau = np.array([300.0, -50.0, 10.0])
    headroom = np.array([150.0, 100.0, 100.0])
    scaled = scale_to_limits(tau, headroom)
    np.testing.assert_allclose(scaled, tau / 2)  # direction kept, joint 0 exactly at its limit
    assert np.all(np.abs(scaled) <= headroom + 1e-12)
    np.testing.assert_array_equal(scale_to_limits(tau / 10, headroom), tau / 10)  # untouched
    assert np.all(scale_to_limits(tau, np.array([-1.0, 5.0, 5.0])) == 0)  # no headroom: no push
