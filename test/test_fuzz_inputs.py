"""Every input of every node fuzzed in process: 1,000 hypothesis messages per input.

The strategies, the harness and the promises checked after every message
(no bug reaches the callback guard, a defective message is refused with one
rate-limited log line and a diagnostics count, a valid one is used, outputs
stay finite and within limits) are in :mod:`fusion_planner.ros.fuzz`; after
its inputs, each node must still plan, drive or simulate correctly.
``python -m fusion_planner.ros.fuzz --messages N`` is the longer soak. The
same bad messages over real DDS are in the node tests
(``test_*_node.py``).
"""

import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('hypothesis')

from fusion_planner.ros import fuzz  # noqa: E402

#: Messages per input (the issue asks for at least 1,000).
MESSAGES = 1000
#: Seed of the messages: the suite sees the same ones every run.
SEED = 0
#: Bad messages drawn per strategy to check the strategies themselves [1].
STRATEGY_SAMPLE = 300


@pytest.mark.parametrize('name', sorted(fuzz.TARGETS))
def test_every_input_survives_fuzzing_and_the_node_still_works(context, name):
    reports = fuzz.fuzz_target(context, name, MESSAGES, SEED)
    assert reports, 'no input was fuzzed'
    for report in reports:
        assert report.messages == MESSAGES, report
        if report.input in fuzz.FIELDLESS_INPUTS:
            assert report.refused == 0, report  # nothing in it can be wrong
            continue
        # Both kinds were fed: refused (defective) and used (valid) messages.
        assert 0.2 * MESSAGES < report.refused < 0.9 * MESSAGES, report


def test_every_subscription_and_service_of_every_node_is_fuzzed(context):
    fuzzed = {}
    for name, (factory, inputs) in fuzz.TARGETS.items():
        target = factory(context)
        try:
            node = target.node.get_name()
            for input_name in inputs or target.inputs:
                target.strategy(input_name)  # KeyError: a new input type needs a strategy
                fuzzed.setdefault(node, set()).add(input_name)
        finally:
            target.close()
    assert fuzzed == {
        'global_planner': {'map', 'goal_pose', 'odom', 'amcl_pose', 'scan', 'get_plan',
                           'cancel_goal', 'controller_outcome'},
        'local_planner': {'plan', 'odom', 'scan', 'obstacles', 'map'},
        'simulator': {'cmd_vel', 'plan'},
    }


@pytest.mark.parametrize('strategy, defects', [
    (fuzz.occupancy_grids(bad_only=True), fuzz.MAP_DEFECTS),
    (fuzz.pose_stampeds(bad_only=True), fuzz.POSE_DEFECTS),
    (fuzz.poses_with_covariance(bad_only=True), fuzz.POSE_WITH_COVARIANCE_DEFECTS),
    (fuzz.odometries(bad_only=True), fuzz.ODOMETRY_DEFECTS),
    (fuzz.get_plan_requests(bad_only=True), fuzz.GET_PLAN_DEFECTS),
    (fuzz.paths(bad_only=True), fuzz.PATH_DEFECTS),
    (fuzz.laser_scans(bad_only=True), fuzz.SCAN_DEFECTS),
    (fuzz.marker_arrays(bad_only=True), fuzz.MARKER_DEFECTS),
    (fuzz.twists(1.0, 1.0, bad_only=True), fuzz.TWIST_DEFECTS),
    (fuzz.controller_outcomes(bad_only=True), fuzz.CONTROLLER_OUTCOME_DEFECTS),
], ids=['map', 'goal', 'amcl_pose', 'odom', 'get_plan', 'path', 'scan', 'markers', 'twist',
        'controller_outcome'])
def test_bad_only_strategies_put_every_kind_of_defect_in(strategy, defects):
    seen = set()
    for fuzzed in fuzz.generate(strategy, STRATEGY_SAMPLE, SEED):
        assert fuzzed.defects, fuzzed
        seen.update(fuzzed.defects)
    assert seen == set(defects)
