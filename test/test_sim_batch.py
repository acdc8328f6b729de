"""The generated-scenario claims in the suite: fusion reaches >= 98 % without contact.

The controllers get the default scan perception (the scan tracker's moving tracks).

A modest batch (the family tables of docs/ALGORITHM.md are made by hand with
``fusion-planner bench families``), plus the generated
scenarios on which a moving obstacle used to walk into the slowed or
wall-pinned robot before the evasion layer (fusion_planner.core.local_planning.evasion,
issue 3), and those where it turned into a person its tracker had not yet
confirmed as moving. Kept in its own file: it takes about a minute on one core.
"""

import pytest

from fusion_planner.core.simulation.scenario import random_scenario
from fusion_planner.core.simulation.episodes import generate, run_batch, run_episode

#: Size and seed of the in-suite random batch.
BATCH_SIZE = 30
BATCH_SEED = 2024

#: ``random_scenario`` seeds where fusion had a contact with a moving
#: obstacle before the evasion layer (one contact each).
FORMER_CONTACT_SEEDS = (119, 227, 327, 474, 488)

#: Generated scenarios where fusion turned into a slow person its scan tracker
#: had not yet confirmed as moving (one contact each): stepping out of a side
#: corridor in front of the robot (corridors), walking beside an unknown post
#: that merged with it into one object (mixed, also in the batch above).
UNCONFIRMED_WALKER_SCENARIOS = (('corridors', 2651666590), ('mixed', 2651666590))


@pytest.fixture(scope='module')
def fusion_batch():
    done = []
    batch = run_batch(BATCH_SIZE, BATCH_SEED, controllers=['fusion'], workers=1,
                      progress=lambda i, n: done.append(i))
    assert done[-1] == BATCH_SIZE
    return batch


def test_fusion_batch_reaches_98_percent(fusion_batch):
    fusion = fusion_batch.controllers['fusion']
    assert fusion.success_rate >= 0.98, fusion.failures


def test_fusion_batch_has_no_collisions(fusion_batch):
    assert fusion_batch.controllers['fusion'].collisions == 0, [
        e for e in fusion_batch.episodes if e['collisions']]


def test_fusion_batch_told_the_true_moving_obstacles_has_no_avoidable_contact():
    """With ideal perception a person may still walk into a robot that cannot get away.

    ``random-2651666590`` is the batch's close call: the robot, boxed between an
    unknown post and a wall, is caught up by a person behind it (two passive
    contacts with earlier codes, none now).
    """
    batch = run_batch(BATCH_SIZE, BATCH_SEED, controllers=['fusion'], workers=1,
                      perceptions=('ideal',))
    fusion = batch.controllers['fusion']
    assert fusion.avoidable_collisions == 0, [e for e in batch.episodes if e['collisions']]
    assert fusion.success_rate >= 0.98, fusion.failures


@pytest.mark.parametrize('seed', FORMER_CONTACT_SEEDS)
def test_fusion_keeps_clear_where_a_moving_obstacle_used_to_hit(seed):
    result = run_episode(random_scenario(seed), 'fusion', record=False)
    assert result.collisions == 0, result.summary()
    assert result.reached, result.failure


@pytest.mark.parametrize('family, seed', UNCONFIRMED_WALKER_SCENARIOS)
def test_fusion_does_not_turn_into_a_walker_not_yet_confirmed_as_moving(family, seed):
    result = run_episode(generate(family, seed), 'fusion', record=False, perception='scan')
    assert result.collisions == 0, result.summary()
    assert result.reached, result.failure


def test_a_robot_chased_off_by_a_person_has_the_chase_s_time_to_come_back():
    """``crowd-156382204``: 0.66 m from the goal at 18 s, a person chases the robot 6 m off.

    It drove back and was 0.93 m from the goal, closing in, when 30 s without
    progress ended the run; the chase no longer counts as time without progress.
    """
    result = run_episode(generate('crowd', 156382204), 'fusion', record=False,
                         perception='ideal')
    assert result.reached, result.failure
    assert result.collisions == 0, result.summary()
