"""Sampled futures of tracked people: where a person who may turn could be.

A tracked obstacle's constant-velocity prediction is one future among many:
people turn. This module draws a fixed set of plausible futures for each
tracked obstacle, its speed kept and its heading a Wiener process (the
heading changes by ``turn_std * sqrt(dt) * N(0, 1)`` per step, ``turn_std``
the obstacle's own: a person walking straight along a corridor turns less
than one wandering in a hall; a future that would walk into a wall stops
there), and scores robot rollouts by the share of futures that touch them,
each weighted by how soon. The draws are a
fixed table (one seed, antithetic pairs), so the same inputs give the same
score: the closed loop stays deterministic.

Frames and units: map frame, metres, seconds, radians.
"""

import functools

import numpy as np
from scipy.spatial import cKDTree

from fusion_planner.core.local_planning.local_geometry import held_before

#: Number of sampled futures per tracked obstacle (even: antithetic pairs).
SAMPLES = 32

#: Seed of the fixed table of heading increments.
TABLE_SEED = 20261128


@functools.lru_cache(maxsize=8)
def _unit_walks(steps):
    """Standard Wiener increments ``(SAMPLES, steps)`` summed over time, antithetic pairs."""
    half = np.random.default_rng(TABLE_SEED).standard_normal((SAMPLES // 2, steps))
    walks = np.cumsum(np.vstack([half, -half]), axis=1)
    walks.setflags(write=False)
    return walks


def sample_futures(tracked, times, turn_stds, walls=None):
    """Positions ``(SAMPLES, T, K, 2)`` [m] of each tracked obstacle in each sampled future.

    Parameters
    ----------
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m].
    times : ndarray, shape (T,)
        Evenly spaced look-ahead times [s], the first one step after now.
    turn_stds : ndarray, shape (K,)
        Heading diffusion [rad / sqrt(s)] of each obstacle.
    walls : ndarray, shape (M, 2), optional
        Static obstacle points [m]. A future that would take an obstacle
        closer to one than its radius (or than it is now) stops before:
        a person in a narrow corridor cannot turn across it.
    """
    dt = float(times[0])
    headings = np.arctan2(tracked[:, 3], tracked[:, 2])                       # (K,)
    speeds = np.hypot(tracked[:, 2], tracked[:, 3])
    walks = _unit_walks(len(times))[..., None] * (np.asarray(turn_stds) * np.sqrt(dt))  # (S, T, K)
    # the heading over each step is the one at its start: the first step goes straight
    turned = headings + np.concatenate([np.zeros_like(walks[:, :1]), walks[:, :-1]], axis=1)
    step = speeds * dt                                                         # (K,)
    x = tracked[:, 0] + np.cumsum(step * np.cos(turned), axis=1)             # (S, T, K)
    y = tracked[:, 1] + np.cumsum(step * np.sin(turned), axis=1)
    futures = np.stack([x, y], axis=-1)
    if walls is None or len(walls) == 0:
        return futures
    reach = speeds * times[-1] + tracked[:, 4]                                 # (K,)
    gaps = np.hypot(walls[:, None, 0] - tracked[:, 0], walls[:, None, 1] - tracked[:, 1])
    walls = walls[np.any(gaps <= reach, axis=1)]
    if len(walls) == 0:
        return futures
    tree = cKDTree(walls)
    now = tree.query(tracked[:, 0:2])[0]                                      # (K,)
    clearance = tree.query(futures.reshape(-1, 2))[0].reshape(futures.shape[:3])
    blocked = clearance < np.minimum(tracked[:, 4], now)                      # (S, T, K)
    first = np.where(blocked.any(axis=1), blocked.argmax(axis=1), len(times))  # (S, K)
    samples, steps, count = futures.shape[:3]
    paths = futures.transpose(0, 2, 1, 3).reshape(samples * count, steps, 2)   # (S K, T, 2)
    starts = np.tile(tracked[:, 0:2], (samples, 1))
    held = held_before(paths, starts, first.reshape(-1))
    return held.reshape(samples, count, steps, 2).transpose(0, 2, 1, 3)


def contact_risk(paths, futures, reach, weights):
    """Weighted share of the sampled futures in which each rollout touches an obstacle.

    Parameters
    ----------
    paths : ndarray, shape (C, T, 2)
        Robot rollouts [m].
    futures : ndarray, shape (S, T, K, 2)
        From :func:`sample_futures`.
    reach : ndarray, shape (K,)
        Centre distance [m] below which the robot touches each obstacle.
    weights : ndarray, shape (T,)
        Weight of a first contact at each time (a later one can still be
        evaded).

    Returns
    -------
    ndarray, shape (C,)
        Mean over the futures of the weight of the first contact (0: none).
    """
    samples, steps = futures.shape[:2]
    touching = np.zeros((len(paths), samples, steps), bool)                   # (C, S, T)
    # every future of an obstacle stays within the disc its samples span at each time
    centre = futures.mean(axis=0)                                             # (T, K, 2)
    spread = np.sqrt(np.max(np.sum((futures - centre) ** 2, axis=-1), axis=0))  # (T, K)
    near = np.hypot(*np.moveaxis(paths[:, :, None] - centre, -1, 0)) < reach + spread  # (C, T, K)
    for k in np.flatnonzero(near.any(axis=(0, 1))):
        rows = np.flatnonzero(near[:, :, k].any(axis=1))
        offset = paths[rows, None] - futures[None, :, :, k]                   # (R, S, T, 2)
        touching[rows] |= np.einsum('rstd,rstd->rst', offset, offset) < reach[k] ** 2
    first = np.where(touching.any(axis=2), touching.argmax(axis=2), -1)       # (C, S)
    score = np.where(first >= 0, weights[np.maximum(first, 0)], 0.0)
    return score.mean(axis=1)
