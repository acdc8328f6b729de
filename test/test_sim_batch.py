"""The generated-scenario claim in the suite: fusion reaches >= 98 % without contact.

A modest batch (the 200-scenario batch of docs/ALGORITHM.md is run by hand with
``fusion-planner sim --random 200 --seed 1 --jobs 2``). Kept in its own file:
it takes about a minute on two cores.
"""

import pytest

from fusion_planner.core.simulation import run_batch

#: Size and seed of the in-suite random batch.
BATCH_SIZE = 30
BATCH_SEED = 2024


@pytest.mark.xfail(
    strict=False,
    reason='known gap of issue 3, still open: the fusion follower reaches 77 % of this '
           'batch (200-batch: 88.5 %, 10 collisions); its boundary-following escape '
           'wanders off and it does not yield to obstacles closing in from behind')
def test_fusion_batch_reaches_98_percent_without_collisions():
    done = []
    batch = run_batch(BATCH_SIZE, BATCH_SEED, controllers=['fusion'], workers=2,
                      progress=lambda i, n: done.append(i))
    fusion = batch.controllers['fusion']
    assert done[-1] == BATCH_SIZE
    assert fusion.success_rate >= 0.98, fusion.failures
    assert fusion.collisions == 0, [e for e in batch.episodes if e['collisions']]
