"""Sampled futures of tracked people and the contact risk of robot rollouts (no ROS)."""

import numpy as np
import pytest

from fusion_planner.core.local_planning import walker_futures

TIMES = 0.2 * np.arange(1, 13)                                  # 0.2 .. 2.4 s
WALKER = np.array([[0.0, 0.0, 0.5, 0.0, 0.25]])                 # x, y, vx, vy, radius


def test_without_turning_every_future_is_the_straight_prediction():
    futures = walker_futures.sample_futures(WALKER, TIMES, [0.0])
    assert futures.shape == (walker_futures.SAMPLES, len(TIMES), 1, 2)
    np.testing.assert_allclose(futures[:, :, 0, 0], np.broadcast_to(0.5 * TIMES, futures.shape[:2]))
    np.testing.assert_allclose(futures[..., 1], 0.0, atol=1e-12)


def test_futures_keep_the_speed_spread_with_time_and_are_symmetric():
    futures = walker_futures.sample_futures(WALKER, TIMES, [0.6])[:, :, 0]   # (S, T, 2)
    steps = np.diff(np.concatenate([np.zeros((len(futures), 1, 2)), futures], axis=1), axis=1)
    np.testing.assert_allclose(np.hypot(steps[..., 0], steps[..., 1]), 0.5 * 0.2)
    lateral = futures[..., 1]
    assert np.all(np.diff(lateral.std(axis=0)[1:]) > 0.0)         # wider the further ahead
    assert lateral.std(axis=0)[-1] > 0.2                          # a person may turn a lot in 2.4 s
    np.testing.assert_allclose(lateral.mean(axis=0), 0.0, atol=1e-12)   # antithetic pairs


def test_each_obstacle_spreads_by_its_own_turn_std():
    walkers = np.vstack([WALKER, WALKER])
    futures = walker_futures.sample_futures(walkers, TIMES, [0.0, 0.6])
    assert np.all(futures[:, -1, 0, 1] == 0.0) and futures[:, -1, 1, 1].std() > 0.2


def test_futures_are_the_same_for_the_same_inputs_and_a_standing_person_stays():
    walkers = np.vstack([WALKER, [[2.0, 1.0, 0.0, 0.0, 0.3]]])
    first = walker_futures.sample_futures(walkers, TIMES, [0.6, 0.6])
    np.testing.assert_array_equal(first, walker_futures.sample_futures(walkers, TIMES, [0.6, 0.6]))
    np.testing.assert_array_equal(first[:, :, 1], np.broadcast_to([2.0, 1.0], first[:, :, 1].shape))


@pytest.mark.parametrize('turn_std', [0.0, 0.6])
def test_risk_is_one_on_the_persons_way_none_far_off_and_between_beside_it(turn_std):
    futures = walker_futures.sample_futures(WALKER, TIMES, [turn_std])
    weights = np.ones(len(TIMES))
    reach = np.array([0.45])
    ahead, beside, far = (np.broadcast_to([x, y], (len(TIMES), 2)) for x, y in
                          [(0.5, 0.0), (0.8, 0.7), (0.8, 5.0)])
    risk = walker_futures.contact_risk(np.stack([ahead, beside, far]), futures, reach, weights)
    assert risk[0] == 1.0 and risk[2] == 0.0
    if turn_std == 0.0:
        assert risk[1] == 0.0
    else:
        assert 0.0 < risk[1] < 1.0                                # some turns reach the robot


def test_risk_weighs_the_first_contact_by_its_time():
    futures = walker_futures.sample_futures(WALKER, TIMES, [0.0])
    weights = np.linspace(1.0, 0.1, len(TIMES))
    standing = np.broadcast_to([1.0, 0.0], (1, len(TIMES), 2))    # reached at 1.0 - 0.45 m: step 6
    risk = walker_futures.contact_risk(standing, futures, np.array([0.45]), weights)
    first = int(np.argmax(0.5 * TIMES > 1.0 - 0.45))
    assert risk[0] == pytest.approx(weights[first])
