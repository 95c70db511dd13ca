"""Operational-space control (Khatib 1987), as the paper drives its arm (Sec. 3.4).

    tau = J^T M_x xdd + g(q),   M_x = (J M^-1 J^T)^-1,
    xdd = kp [x_T_des - x_T ; x_R_des (-) x_R] + kd (xd_des - xd),

with Coriolis forces ignored (pushes start from rest) and kp = 3000, kd = 152 (the paper's
values). Gravity compensation g(q) is applied by MuJoCo itself (`gravcomp` on the arm's
bodies, routed through the actuators so that the torque limits apply to the total).
Everything here is pure NumPy on matrices, testable without a simulator.
"""

from __future__ import annotations

import math

import numpy as np

KP = 3000.0
"""Stiffness of the end-effector PD rule [paper Sec. 3.4]."""
KD = 152.0
"""Damping of the end-effector PD rule [paper Sec. 3.4]."""
TASK_DAMPING = 1e-6
"""Added to J M^-1 J^T before it is inverted, so M_x stays finite near singularities [ours]."""


def rotation_error(r_des: np.ndarray, r: np.ndarray) -> np.ndarray:
    """x_R_des (-) x_R: the rotation vector (world frame) that turns r into r_des."""
    err = r_des @ r.T
    # Scalar arithmetic: this runs at every control step, where NumPy's per-call overhead
    # on 3-vectors would cost more than the arithmetic.
    (a, b, c), (d, e, f), (g, h, i) = err.tolist()
    # Rotation vector from the quaternion of err: robust at small and large angles.
    w = math.sqrt(max(0.0, 1.0 + a + e + i)) / 2.0
    vx, vy, vz = h - f, c - g, d - b
    if w > 1e-6:
        vx, vy, vz = vx / (4.0 * w), vy / (4.0 * w), vz / (4.0 * w)
    else:  # a half-turn: take the axis from the diagonal
        axis = np.sqrt(np.clip((np.diag(err) + 1.0) / 2.0, 0.0, None))
        k = int(np.argmax(axis))
        axis = err[:, k] + np.eye(3)[k]
        return np.pi * axis / np.linalg.norm(axis)
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    if s < 1e-12:
        return np.zeros(3)
    scale = 2.0 * math.atan2(s, w) / s
    return np.array([vx * scale, vy * scale, vz * scale])


def desired_acceleration(
    pos_err: np.ndarray,
    rot_err: np.ndarray,
    vel: np.ndarray,
    vel_des: np.ndarray,
    kp: float = KP,
    kd: float = KD,
) -> np.ndarray:
    """xdd = kp [pos_err; rot_err] + kd (vel_des - vel), with 6-vectors (linear; angular)."""
    return kp * np.concatenate([pos_err, rot_err]) + kd * (vel_des - vel)


def task_inertia(
    jac: np.ndarray, mass_matrix: np.ndarray, damping: float = TASK_DAMPING
) -> np.ndarray:
    """M_x = (J M^-1 J^T)^-1, damped so that it stays finite near singularities."""
    inv_lambda = jac @ np.linalg.solve(mass_matrix, jac.T)
    return np.linalg.inv(inv_lambda + damping * np.eye(jac.shape[0]))


def osc_torque(jac: np.ndarray, mass_matrix: np.ndarray, xdd: np.ndarray) -> np.ndarray:
    """tau = J^T M_x xdd (gravity compensation is added by the simulator)."""
    return jac.T @ (task_inertia(jac, mass_matrix) @ xdd)


def scale_to_limits(tau: np.ndarray, headroom: np.ndarray) -> np.ndarray:
    """tau scaled down uniformly until every |tau_i| <= headroom_i.

    Clipping each joint separately would bend the end-effector's acceleration off its
    commanded direction whenever a limit is reached (a fast push then drifts off the
    line and can miss the link); a common scale keeps the direction and respects every
    limit. `headroom` is each joint's torque limit minus what gravity compensation uses.
    """
    headroom = np.maximum(headroom, 0.0)
    over = np.abs(tau) > headroom
    if not over.any():
        return tau
    return tau * float(np.min(headroom[over] / np.abs(tau[over])))
