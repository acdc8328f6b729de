"""Whether a robot that a person walked into could have got out of the way.

The simulated people ignore the robot, so a person may walk into a robot
that stands still or backs away. Such a contact is only *passive* (not the
robot's to avoid) when no simple manoeuvre of the robot, begun early enough
and with the person in sight, would have kept it clear. This module answers
that counterfactual from a short record of the run:

- the robot starts from its recorded state :data:`ESCAPE_HORIZON_S` before
  the contact, or later, from the first recorded step in which it had a line
  of sight to the person who touched it (a person behind a wall cannot be
  dodged);
- one *escape* is: brake and turn in place (at ``max_accel`` and
  ``max_omega``) to face one of :data:`ESCAPE_HEADINGS` headings, forward or
  backward, then accelerate along it to ``max_speed``;
- it succeeds when, on the people's recorded paths (extrapolated at their
  last velocity for :data:`ESCAPE_COAST_S` after the contact), the robot
  overlaps no person and no static obstacle.

The people's paths do not depend on the robot, so the record is what they
would have done whatever the robot did. A :class:`ContactEvent` keeps one
contact and how it was judged. Everything is in the map frame, SI units.
"""

import math
from dataclasses import dataclass

import numpy as np

#: How long before a contact the robot may start its escape [s].
ESCAPE_HORIZON_S = 2.0
#: How long after the contact the escape must stay clear [s] (people
#: extrapolated at constant velocity).
ESCAPE_COAST_S = 1.0
#: Number of travel headings tried, evenly spaced; each forward and backward.
ESCAPE_HEADINGS = 16


@dataclass(frozen=True)
class ContactEvent:
    """One contact event of a run and how it was judged.

    Attributes
    ----------
    time_s : float
        Simulated time [s] at the end of the step it began in.
    position : tuple of float
        The robot's centre ``(x, y)`` [m] then.
    robot_speed_mps : float
        How fast the robot's centre moved over that step [m/s]; for a step
        refused at a static obstacle, the speed it drove at.
    person : int or None
        Index of the moving obstacle touched (the nearest to overlapping
        the robot); None for a static obstacle (a refused step).
    approach : float or None
        Cosine of the angle between the robot's motion over that step and
        the direction to the person: +1 driving straight at them, -1
        straight away; None when the robot stood or the contact was static.
    escape : bool or None
        Whether some escape begun up to :data:`ESCAPE_HORIZON_S` earlier
        would have kept the robot clear (:func:`could_escape`); None for a
        static contact.
    passive : bool
        Not the robot's to avoid: it stood or retreated, and no escape
        existed.
    """

    time_s: float
    position: tuple
    robot_speed_mps: float
    person: int = None
    approach: float = None
    escape: bool = None
    passive: bool = False

    def summary(self):
        """The JSON-ready fields, numbers rounded to three decimals."""
        return {
            'time_s': round(self.time_s, 3),
            'x_m': round(self.position[0], 3),
            'y_m': round(self.position[1], 3),
            'robot_speed_mps': round(self.robot_speed_mps, 3),
            'person': self.person,
            'approach': None if self.approach is None else round(self.approach, 3),
            'escape': self.escape,
            'passive': self.passive,
        }


@dataclass(frozen=True)
class Snapshot:
    """The state of a run after one simulation step.

    Attributes
    ----------
    time : float
        Simulated time [s].
    pose : ndarray, shape (3,)
        Robot ``(x, y, yaw)`` [m, m, rad].
    speed : float
        Robot linear speed [m/s] (negative backwards).
    people : ndarray, shape (K, 2)
        Centres of the moving obstacles [m].
    people_velocity : ndarray, shape (K, 2)
        Their velocities [m/s].
    """

    time: float
    pose: np.ndarray
    speed: float
    people: np.ndarray
    people_velocity: np.ndarray


def could_escape(static, robot, radii, history, touched):
    """Whether some escape from the recent past keeps the robot clear of everything.

    Parameters
    ----------
    static : StaticScene
        The static world (known map, unknown obstacles, map edge).
    robot : RobotSpec
        The robot's radius and limits.
    radii : ndarray, shape (K,)
        Radii of the moving obstacles [m].
    history : sequence of Snapshot
        Consecutive steps, oldest first, the last one the step the contact
        began in; at least :data:`ESCAPE_HORIZON_S` long when the run is.
    touched : int
        Index of the moving obstacle the contact is with.

    Returns
    -------
    bool
        True when an escape exists (the contact was avoidable).
    """
    start = _first_sighting(static, history[:-1], touched)
    if start is None:
        return False
    steps = history[start:]
    dts = np.diff([s.time for s in steps])
    if len(dts) == 0:
        return False
    dt = float(dts.mean())
    last = history[-1]
    coast = np.arange(1, int(round(ESCAPE_COAST_S / dt)) + 1)[:, None, None] * dt
    people = np.concatenate([np.stack([s.people for s in steps[1:]]),
                             last.people[None] + coast * last.people_velocity[None]])
    return _any_escape_clear(static, robot, radii, steps[0], people, dt)


def _first_sighting(static, history, touched):
    """Index of the first snapshot in which the robot centre sees the touched person's centre."""
    for i, snap in enumerate(history):
        offset = snap.people[touched] - snap.pose[:2]
        distance = math.hypot(offset[0], offset[1])
        if distance < 1e-9:
            return i
        reach = static.cast(snap.pose[:2], (offset / distance)[None], distance)[0]
        if reach >= distance:
            return i
    return None


def _any_escape_clear(static, robot, radii, start, people, dt):
    """Whether one escape from ``start`` stays clear of ``people`` (T, K, 2) [m] and the walls."""
    headings = start.pose[2] + np.linspace(0.0, 2 * math.pi, ESCAPE_HEADINGS, endpoint=False)
    senses = np.repeat([1.0, -1.0], ESCAPE_HEADINGS)
    yaw_goal = np.tile(headings, 2) + np.where(senses > 0, 0.0, math.pi)
    n = len(senses)
    x = np.full(n, start.pose[0])
    y = np.full(n, start.pose[1])
    yaw = np.full(n, start.pose[2])
    v = np.full(n, float(start.speed))
    alive = np.ones(n, bool)
    reach = robot.radius + np.asarray(radii, float)
    for step_people in people:
        error = np.angle(np.exp(1j * (yaw_goal - yaw)))
        aligned = np.abs(error) < 1e-6
        # turning to the heading first needs the robot stopped, unless it already faces it
        target = np.where(aligned, senses * robot.max_speed, 0.0)
        v = v + np.clip(target - v, -robot.max_accel * dt, robot.max_accel * dt)
        omega = np.clip(error / dt, -robot.max_omega, robot.max_omega)
        mid = yaw + 0.5 * omega * dt
        x = x + v * dt * np.cos(mid)
        y = y + v * dt * np.sin(mid)
        yaw = yaw + omega * dt
        gaps = np.hypot(x[:, None] - step_people[None, :, 0], y[:, None] - step_people[None, :, 1])
        alive &= ~np.any(gaps < reach[None, :], axis=1)
        for i in np.flatnonzero(alive):
            if static.disc_collides((x[i], y[i]), robot.radius):
                alive[i] = False
        if not alive.any():
            return False
    return True
