"""What the simulated robot knows of its pose: drifting wheel odometry, a noisy localizer.

Both are fed the true motion of
:class:`~fusion_planner.core.simulation.world.World`; neither changes it.
"""

import math

import numpy as np

from fusion_planner.core.simulation.world import integrate_unicycle


class DriftingOdometry:
    """Wheel odometry: the true velocities with a scale error and a heading drift.

    Parameters
    ----------
    scale_error : float
        Relative error of the travelled distance [1] (0.03: 3 cm per metre).
    yaw_drift : float
        Heading error gained per metre travelled [rad/m].

    Attributes
    ----------
    pose : ndarray, shape (3,)
        ``(x, y, yaw)`` [m, m, rad] in the odom frame; it starts at the
        origin, where the robot stood (REP-105).
    velocity : ndarray, shape (2,)
        The measured ``(v, omega)`` [m/s, rad/s].
    """

    def __init__(self, scale_error, yaw_drift):
        self.scale_error = float(scale_error)
        self.yaw_drift = float(yaw_drift)
        self.pose = np.zeros(3)
        self.velocity = np.zeros(2)

    def step(self, v, omega, dt):
        """Integrate one step of the true ``(v, omega)`` [m/s, rad/s] over ``dt`` [s]."""
        measured_v = v * (1.0 + self.scale_error)
        measured_omega = omega + self.yaw_drift * abs(v)
        self.velocity = np.array([measured_v, measured_omega])
        self.pose = integrate_unicycle(self.pose, measured_v, measured_omega, dt)


class NoisyLocalizer:
    """A localizer (AMCL-like): the true map pose plus Gaussian noise.

    Parameters
    ----------
    xy_noise : float
        Standard deviation of x and y [m].
    yaw_noise : float
        Standard deviation of the heading [rad].
    seed : int
    """

    def __init__(self, xy_noise, yaw_noise, seed):
        self.xy_noise = float(xy_noise)
        self.yaw_noise = float(yaw_noise)
        self._rng = np.random.default_rng(seed)

    def estimate(self, true_pose):
        """A noisy ``(x, y, yaw)`` [m, m, rad] of ``true_pose``, map frame."""
        noise = self._rng.normal(0.0, 1.0, 3) * (self.xy_noise, self.xy_noise, self.yaw_noise)
        x, y, yaw = np.asarray(true_pose, dtype=float) + noise
        return np.array([x, y, math.atan2(math.sin(yaw), math.cos(yaw))])

    def covariance(self):
        """The 6 x 6 row-major pose covariance (x, y, z, roll, pitch, yaw) it reports."""
        cov = np.zeros(36)
        cov[0] = cov[7] = max(self.xy_noise, 1e-3) ** 2
        cov[35] = max(self.yaw_noise, 1e-3) ** 2
        return cov
