"""Local controllers: turn a global plan and what the robot senses into (v, omega).

Five controllers share one interface (:class:`Controller`), made by
:func:`make_controller`:

``'fusion'``
    The paper's section 3.3: the key nodes of the A* path are successive
    sub-goals; the improved APF (eqs. (15)-(17)) steers around the sensed
    obstacle points and around tracked moving obstacles **at their predicted
    positions** over a horizon (beyond the paper); the adaptive step of
    eq. (18) limits the speed for what lies in the braking path; a short
    look-ahead check replaces a command that would run into a tracked
    obstacle by an evasive one (beyond the paper). Beyond the paper too, the
    field is shaped by the global path it follows (the *route*: its carrot
    is centred in the free band about the path, walls beside the path do not
    hold it back), the speed is capped for the turn ahead, and people walking
    along the route are passed on one side. When stuck it first aims at the
    next key node (the paper's escape), then asks for a new global plan
    around what it has seen (when given a replanner; a plan that cannot be
    found ends in ``'no_path'``), then follows the blocking boundary.
``'apf'``
    The improved field straight to the final goal (no A*), with the same
    prediction and evasion; escape by boundary following.
``'classic-apf'``
    The classic field of eqs. (9)-(14) straight to the goal, no prediction,
    no evasion, no escape: it is expected to stop short of a goal beside an
    obstacle and to be caught by traps (the paper's Figure 5). Stuck means
    failed.
``'astar-track'``
    Pure-pursuit tracking of the global path with no avoidance at all, the
    baseline the paper improves on. Stuck (blocked) means failed.
``'dwa'``
    The dynamic window approach (Fox et al. 1997) on a carrot of the global
    path, a standard local planner from the field; no recovery: no progress
    means failed.

This module is the entry point; the controllers live in modules with one job
each, and their public names are re-exported here:

=========================================  ====================================================
module                                     what
=========================================  ====================================================
:mod:`~fusion_planner.core.local_planning.controller_base`  parameters, observation, command, limits, steering
:mod:`~fusion_planner.core.local_planning.field_follower`   the field controllers (scene, fields, sub-goals)
:mod:`~fusion_planner.core.local_planning.escape`           local minima: episodes, boundary following
:mod:`~fusion_planner.core.local_planning.replanning`       obstacle memory and the grid replanner
:mod:`~fusion_planner.core.local_planning.evasion`          look-ahead check against moving obstacles
:mod:`~fusion_planner.core.local_planning.path_tracker`     the ``'astar-track'`` baseline
:mod:`~fusion_planner.core.local_planning.route`            the global path as a route: station, carrot, offsets
:mod:`~fusion_planner.core.local_planning.speed_policy`     speed for the braking path and the turn ahead
:mod:`~fusion_planner.core.local_planning.progress`         time without progress toward the goal
:mod:`~fusion_planner.core.local_planning.yielding`         the side kept for people on the route
:mod:`~fusion_planner.core.local_planning.dwa`              the ``'dwa'`` baseline
:mod:`~fusion_planner.core.local_planning.local_geometry`   small geometry helpers
=========================================  ====================================================

The command pipeline of the field controllers (:class:`FollowerParams`
holds every number):

1. a desired direction: the total force (fields) or the boundary tangent
   (escape);
2. heading control: ``omega`` proportional to the heading error
   (``heading_gain``; ``route_heading_gain`` for fusion on its route), capped so
   the robot can stop turning in time; forward speed scaled by
   ``cos(error)^2`` (zero beyond 90 degrees: turn in place);
3. speed caps: approach (``v <= approach_gain * distance to goal``), the
   adaptive step of eq. (18), and a braking cap from the free distance
   straight ahead;
4. evasion (prediction on): the command is rolled out against the tracked
   obstacles' predicted motion and replaced if it comes too close; only an
   evasion reverses;
5. limits relative to the measured velocity: ``v <= max_speed``,
   ``|omega| <= max_omega``, ``|dv| <= max_accel * control_period``,
   ``|d omega| <= max_alpha * control_period``. Speed limits win over
   acceleration limits if the measured velocity is already out of range.

Arrival is only reported within ``goal_tolerance`` of the goal; a field
controller that makes no progress toward the goal for ``escape_time_limit``
ends in status ``'failed'`` with a reason, and fusion, once a replan has
proved the goal unreachable, brakes and reports ``'no_path'``; either stays
until ``reset`` or ``set_path``.

Examples
--------
>>> import numpy as np
>>> ctrl = make_controller('fusion', FollowerParams())
>>> ctrl.set_path(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[0.0, 0.0], [3.0, 0.0]]))
>>> obs = Observation(pose=np.array([0.0, 0.0, 0.0]), velocity=np.zeros(2),
...                   obstacle_points=np.zeros((0, 2)), tracked=np.zeros((0, 5)), time=0.0)
>>> cmd = ctrl.compute(obs)
>>> cmd.status, cmd.v > 0, abs(cmd.omega) < 1e-9
('moving', True, True)
"""

from fusion_planner.core.local_planning.controller_base import (
    STATUSES, Command, Controller, FollowerParams, Observation)
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.field_follower import FieldFollower
from fusion_planner.core.local_planning.local_geometry import thin_points, wrap_angle
from fusion_planner.core.local_planning.dwa import DynamicWindow
from fusion_planner.core.local_planning.path_tracker import PathTracker
from fusion_planner.core.local_planning.replanning import GridReplanner

__all__ = ['CONTROLLER_NAMES', 'STATUSES', 'Command', 'Controller', 'DynamicWindow',
           'FieldFollower', 'FollowerParams', 'GridReplanner', 'Observation', 'PathTracker', 'make_controller',
           'thin_points', 'wrap_angle']

#: Names accepted by :func:`make_controller`.
CONTROLLER_NAMES = ('fusion', 'apf', 'classic-apf', 'dwa', 'astar-track')


def make_controller(name, params, replan=None):
    """Build a controller by name.

    Parameters
    ----------
    name : str
        One of :data:`CONTROLLER_NAMES`.
    params : FollowerParams
    replan : callable, optional
        Global replanner for the ``'fusion'`` escape (see
        :class:`FieldFollower`, :class:`GridReplanner`); ignored by the
        other controllers.

    Returns
    -------
    Controller

    Raises
    ------
    InvalidInput
        If the name is unknown or ``params`` is not a FollowerParams.
    """
    if name == 'fusion':
        return FieldFollower(params, field='improved', use_key_nodes=True, escape=True,
                             replan=replan)
    if name == 'apf':
        return FieldFollower(params, field='improved', use_key_nodes=False, escape=True)
    if name == 'classic-apf':
        return FieldFollower(params, field='classic', use_key_nodes=False, escape=False,
                             predict=False)
    if name == 'astar-track':
        return PathTracker(params)
    if name == 'dwa':
        return DynamicWindow(params)
    raise InvalidInput(f'unknown controller {name!r}; choose one of {", ".join(CONTROLLER_NAMES)}')
