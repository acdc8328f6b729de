"""The global_planner node over real DDS (launch-free, rclpy executors).

Each test builds a fresh planner node and a tester node under their own
namespace in one rclpy Context per module, spins a SingleThreadedExecutor
in bounded spin_once loops, and checks properties of what comes back:
collision-free plans that end at the goal, latched delivery to late joiners,
get_plan successes and outcome codes, replanning on a blocking map, survival
of bad messages, and parameter validation.
"""

import itertools
import math
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetPlan
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from fusion_planner.core import raster
from fusion_planner.core.grid import GridMap
from fusion_planner.core.global_planning.planner import GlobalPlanner
from fusion_planner.ros import conversions as conv
from fusion_planner.ros import fuzz
from fusion_planner.ros.goal_outcome import controller_outcome_msg
from fusion_planner.ros.global_planner import (
    LATCHED_QOS, PARAMETER_SPECS, GlobalPlannerNode, nearest_free_goal)

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'params.yaml'
RESOLUTION = 0.1  # [m]
ROBOT_RADIUS = 0.2  # [m]
START = (1.0, 3.0)
GOAL = (7.0, 3.0)
WALL_COL = 40  # the wall at x in [4.0, 4.1) m
TIMEOUT_S = 10.0
#: Fuzzed bad messages per input sent over DDS [1] (1,000 each go in process:
#: test_fuzz_inputs.py).
DDS_BAD_MESSAGES = 100
#: Map-size limit of the fuzzed planner [cells] (the wall map has 4,800).
FUZZ_MAX_CELLS = 10_000
_namespaces = itertools.count()


def wall_map(block_low=False, block_high=False, extra=None):
    """8 m x 6 m; a wall at x = 4 m from y = 1 m to 5 m, gaps below and above."""
    occ = np.zeros((60, 80), bool)
    occ[10:50, WALL_COL] = True
    if block_low:
        occ[0:10, WALL_COL] = True
    if block_high:
        occ[50:60, WALL_COL] = True
    if extra is not None:
        occ[extra] = True
    return GridMap(occ, RESOLUTION)


def map_msg(grid, frame='map'):
    return conv.grid_map_to_occupancy_grid(grid, frame, conv.seconds_to_stamp(0.0))


def pose_msg(x, y, frame='map'):
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x = float(x)
    msg.pose.position.y = float(y)
    msg.pose.orientation.w = 1.0
    return msg


def odom_msg(x, y, frame='map'):
    msg = Odometry()
    msg.header.frame_id = frame
    msg.child_frame_id = 'base_link'
    msg.pose.pose = pose_msg(x, y).pose
    return msg


def assert_collision_free(grid, path, radius=ROBOT_RADIUS):
    """Every cell the polyline touches is in the map and clear of obstacles by ``radius``."""
    cells = raster.path_cells(grid, path)
    assert grid.contains(cells).all()
    assert grid.clearance[cells[:, 0], cells[:, 1]].min() >= radius - 1e-6


def assert_ends_at(path, point):
    assert math.dist(path[-1], point) <= RESOLUTION * math.sqrt(0.5) + 1e-6


class Harness:
    """A planner node, a tester node with publishers and recorders, one executor."""

    def __init__(self, ctx, overrides=()):
        self.ns = f'/gp_test_{next(_namespaces)}'
        self.ctx = ctx
        self.planner = GlobalPlannerNode(
            context=ctx, namespace=self.ns,
            # map-frame odometry as the pose source unless a test picks amcl_pose
            parameter_overrides=[Parameter('robot_radius', value=ROBOT_RADIUS),
                                 Parameter('pose_topic_type', value='odometry'), *overrides])
        self.tester = Node('tester', context=ctx, namespace=self.ns)
        self.plans, self.markers, self.statuses = [], [], []
        t = self.tester
        self.map_pub = t.create_publisher(OccupancyGrid, 'map', LATCHED_QOS)
        self.amcl = self.planner.get_parameter('pose_topic_type').value == 'pose_with_covariance'
        self.odom_pub = (t.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', 10) if self.amcl
                         else t.create_publisher(Odometry, 'odom', 10))
        self.goal_pub = t.create_publisher(PoseStamped, 'goal_pose', 10)
        t.create_subscription(Path, 'plan', self.plans.append, LATCHED_QOS)
        t.create_subscription(MarkerArray, 'plan_markers', self.markers.append, 10)
        t.create_subscription(DiagnosticArray, '/diagnostics',
                              lambda m: self.statuses.extend(m.status), 10)
        self.client = t.create_client(GetPlan, 'get_plan')
        self.goal_outcomes = []
        t.create_subscription(String, 'goal_outcome',
                              lambda m: self.goal_outcomes.append(m.data), 10)
        self.controller_outcome_pub = t.create_publisher(DiagnosticStatus, 'controller_outcome', 10)
        self.cancel_client = t.create_client(Trigger, 'cancel_goal')
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.planner)
        self.executor.add_node(t)
        assert self.spin_until(self._connected), 'discovery did not match every endpoint'

    def _connected(self):
        """Every publisher on either side has its subscriber (no message is lost)."""
        p = self.planner
        pubs = (self.map_pub, self.odom_pub, self.goal_pub, p._plan_pub, p._markers_pub,
                p._diagnostics._pub)
        return all(pub.get_subscription_count() > 0 for pub in pubs) and self.client.service_is_ready()

    def spin_until(self, predicate, timeout=TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
        return predicate()

    def spin_for(self, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)

    def setup_world(self, grid=None, start=START):
        self.map_pub.publish(map_msg(grid or wall_map()))
        assert self.spin_until(lambda: self.planner._map_msg is not None), 'map not received'
        if self.amcl:
            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = 'map'
            msg.pose.pose = pose_msg(*start).pose
            self.odom_pub.publish(msg)
        else:
            self.odom_pub.publish(odom_msg(*start))
        assert self.spin_until(lambda: self.planner._start is not None), 'odom not received'

    def call_cancel(self):
        assert self.cancel_client.wait_for_service(timeout_sec=TIMEOUT_S)
        future = self.cancel_client.call_async(Trigger.Request())
        assert self.spin_until(future.done)
        return future.result()

    def send_goal(self, x, y, frame='map'):
        count = len(self.plans)
        self.goal_pub.publish(pose_msg(x, y, frame))
        return self.spin_until(lambda: len(self.plans) > count)

    def diag_values(self):
        """Key values of the latest diagnostics status ({} before the first)."""
        return {kv.key: kv.value for kv in self.statuses[-1].values} if self.statuses else {}

    def outcomes(self):
        return [{kv.key: kv.value for kv in s.values}['last_outcome'] for s in self.statuses]

    def get_plan(self, start, goal, tolerance=0.0, start_frame='map'):
        assert self.client.wait_for_service(timeout_sec=TIMEOUT_S)
        request = GetPlan.Request()
        request.start = pose_msg(*start, frame=start_frame)
        request.goal = pose_msg(*goal)
        request.tolerance = float(tolerance)
        future = self.client.call_async(request)
        assert self.spin_until(future.done), 'get_plan did not answer'
        return future.result().plan

    def close(self):
        self.executor.shutdown()
        self.planner.destroy_node()
        self.tester.destroy_node()


@pytest.fixture
def harness(context):
    h = Harness(context)
    yield h
    h.close()


def test_goal_gives_collision_free_plan_to_goal_and_markers(harness):
    harness.setup_world()
    assert harness.send_goal(*GOAL)
    path = conv.path_from_msg(harness.plans[-1], 'map')
    assert math.dist(path[0], START) <= RESOLUTION
    assert_ends_at(path, GOAL)
    assert_collision_free(wall_map(), path)
    assert harness.spin_until(lambda: harness.markers)
    key_nodes = [m for m in harness.markers[-1].markers if m.ns == 'key_nodes']
    assert key_nodes and len(key_nodes[0].points) >= 2
    assert harness.spin_until(lambda: 'succeeded' in harness.outcomes())


def test_late_subscriber_receives_map_and_plan(harness, context):
    harness.setup_world()
    assert harness.send_goal(*GOAL)
    late = Node('late_joiner', context=context, namespace=harness.ns)
    got_map, got_plan = [], []
    late.create_subscription(OccupancyGrid, 'map', got_map.append, LATCHED_QOS)
    late.create_subscription(Path, 'plan', got_plan.append, LATCHED_QOS)
    harness.executor.add_node(late)
    try:
        assert harness.spin_until(lambda: got_map and got_plan)
        assert got_map[-1].info.width == 80
        assert len(got_plan[-1].poses) == len(harness.plans[-1].poses) > 0
    finally:
        harness.executor.remove_node(late)
        late.destroy_node()


def test_get_plan_success_and_clear_failures(harness):
    harness.setup_world()
    path = conv.path_from_msg(harness.get_plan(START, GOAL), 'map')
    assert math.dist(path[0], START) <= RESOLUTION
    assert_ends_at(path, GOAL)
    assert_collision_free(wall_map(), path)
    assert not harness.plans, 'get_plan must not publish on plan'

    in_wall = (4.05, 3.0)
    assert len(harness.get_plan(START, in_wall).poses) == 0
    assert harness.spin_until(lambda: harness.outcomes()[-1:] == ['goal_occupied'])
    assert len(harness.get_plan(START, (20.0, 3.0), tolerance=1.0).poses) == 0
    assert harness.spin_until(lambda: harness.outcomes()[-1:] == ['goal_outside_map'])
    assert len(harness.get_plan((-5.0, 3.0), GOAL).poses) == 0
    assert harness.spin_until(lambda: harness.outcomes()[-1:] == ['start_outside_map'])

    near = conv.path_from_msg(harness.get_plan(START, in_wall, tolerance=0.5), 'map')
    end = near[-1]
    assert math.dist(end, in_wall) <= 0.5
    assert end[0] < 4.0, 'the moved goal must be on the start side of the wall'
    assert_collision_free(wall_map(), near)
    assert harness.spin_until(lambda: float(harness.diag_values().get('goal_moved_m', 0)) > 0)


def test_new_map_blocking_the_plan_triggers_replan(harness):
    harness.setup_world()
    assert harness.send_goal(*GOAL)
    first = conv.path_from_msg(harness.plans[-1], 'map')
    went_low = first[:, 1].min() < 1.0

    # The same map again and a map with a far-away obstacle keep the plan.
    count = len(harness.plans)
    harness.map_pub.publish(map_msg(wall_map()))
    harness.map_pub.publish(map_msg(wall_map(extra=(slice(28, 32), slice(75, 78)))))
    harness.spin_for(1.0)
    assert len(harness.plans) == count

    blocked = wall_map(block_low=went_low, block_high=not went_low)
    harness.map_pub.publish(map_msg(blocked))
    assert harness.spin_until(lambda: len(harness.plans) > count), 'no replan'
    second = conv.path_from_msg(harness.plans[-1], 'map')
    assert (second[:, 1].min() < 1.0) != went_low, 'the new plan must use the other gap'
    assert_collision_free(blocked, second)
    assert_ends_at(second, GOAL)

    # Closing both gaps leaves no way: an empty plan (followers stop) and an outcome.
    harness.map_pub.publish(map_msg(wall_map(block_low=True, block_high=True)))
    assert harness.spin_until(lambda: len(harness.plans[-1].poses) == 0)
    assert harness.spin_until(lambda: 'no_valid_path' in harness.outcomes())
    assert harness.spin_until(lambda: harness.goal_outcomes == ['no_path'])
    # The goal ended: reopening the way resumes nothing.
    count = len(harness.plans)
    harness.map_pub.publish(map_msg(wall_map()))
    harness.spin_for(1.0)
    assert len(harness.plans) == count and harness.goal_outcomes == ['no_path']


def test_every_goal_ends_with_exactly_one_outcome(harness):
    harness.setup_world()
    assert harness.send_goal(*GOAL)
    assert harness.send_goal(GOAL[0], GOAL[1] - 0.5)  # replaces the first
    assert harness.spin_until(lambda: harness.goal_outcomes == ['preempted'])

    # The local planner's outcome of an older plan is ignored; of the current one, taken.
    plan_stamp = conv.stamp_to_nanoseconds(harness.plans[-1].header.stamp)
    harness.controller_outcome_pub.publish(
        controller_outcome_msg('reached', plan_stamp - 1, '', '/local_planner'))
    harness.spin_for(0.5)
    assert harness.goal_outcomes == ['preempted']
    count = len(harness.plans)
    harness.controller_outcome_pub.publish(
        controller_outcome_msg('reached', plan_stamp, '', '/local_planner'))
    assert harness.spin_until(lambda: harness.goal_outcomes == ['preempted', 'reached'])
    assert harness.spin_until(lambda: len(harness.plans) > count)
    assert len(harness.plans[-1].poses) == 0, 'a late follower must not drive the old plan'
    assert harness.diag_values()['goal_outcome'] == 'reached'

    # Cancel: the plan empties, the outcome is cancelled; a second cancel has nothing to end.
    assert harness.send_goal(*GOAL)
    assert harness.call_cancel().success
    assert harness.spin_until(lambda: harness.goal_outcomes[-1:] == ['cancelled'])
    assert harness.spin_until(lambda: len(harness.plans[-1].poses) == 0)
    again = harness.call_cancel()
    assert not again.success and 'no goal' in again.message
    # Nothing resumes the cancelled goal: not a new start pose, not a new map.
    count = len(harness.plans)
    harness.odom_pub.publish(odom_msg(START[0] + 0.1, START[1]))
    harness.map_pub.publish(map_msg(wall_map(extra=(slice(28, 32), slice(75, 78)))))
    harness.spin_for(1.0)
    assert len(harness.plans) == count
    assert harness.goal_outcomes == ['preempted', 'reached', 'cancelled']


def test_the_active_goal_sent_again_is_planned_anew_not_preempted(harness):
    harness.setup_world()
    assert harness.send_goal(*GOAL)
    assert harness.send_goal(*GOAL), 'no new plan'  # a retry, as a GoalSender makes one
    harness.spin_for(0.5)
    assert harness.goal_outcomes == [] and harness.plans[-1].poses
    assert harness.send_goal(GOAL[0], GOAL[1] - 0.5)  # another pose is another goal
    assert harness.spin_until(lambda: harness.goal_outcomes == ['preempted'])


def test_bad_messages_do_not_kill_the_node(harness):
    harness.setup_world()
    nan_goal = pose_msg(float('nan'), 3.0)
    harness.goal_pub.publish(nan_goal)
    harness.goal_pub.publish(pose_msg(*GOAL, frame='odom'))
    zero_q = pose_msg(*GOAL)
    zero_q.pose.orientation.w = 0.0
    harness.goal_pub.publish(zero_q)
    bad_map = map_msg(wall_map())
    bad_map.data = bad_map.data[:-7]
    harness.map_pub.publish(bad_map)
    harness.odom_pub.publish(odom_msg(float('inf'), 0.0))
    assert harness.spin_until(lambda: int(harness.diag_values().get('rejected', 0)) >= 5)
    assert not harness.plans
    assert {'invalid_input', 'invalid_map'} <= set(harness.outcomes())
    assert harness.planner._map_msg.info.width == 80, 'a bad map must not replace a good one'
    assert len(harness.get_plan((float('nan'), 0.0), GOAL).poses) == 0
    assert len(harness.get_plan(START, GOAL, start_frame='odom').poses) == 0

    assert harness.send_goal(*GOAL), 'the node must still plan after bad input'
    assert_ends_at(conv.path_from_msg(harness.plans[-1], 'map'), GOAL)


def test_hundreds_of_fuzzed_bad_messages_are_refused_quietly_and_planning_goes_on(
        context, capfd):
    h = Harness(context, [Parameter('max_map_cells', value=FUZZ_MAX_CELLS)])
    try:
        h.setup_world()
        scan_pub = h.tester.create_publisher(LaserScan, 'scan', qos_profile_sensor_data)
        assert h.spin_until(lambda: scan_pub.get_subscription_count() > 0)
        capfd.readouterr()  # only what the bad messages cause counts
        started = time.monotonic()
        inputs = [(h.map_pub, fuzz.occupancy_grids(max_cells=FUZZ_MAX_CELLS, bad_only=True)),
                  (h.goal_pub, fuzz.pose_stampeds(bad_only=True)),
                  (h.odom_pub, fuzz.odometries(bad_only=True)),
                  (scan_pub, fuzz.laser_scans(bad_only=True))]
        refused = fuzz.publish_all_refused(
            inputs, DDS_BAD_MESSAGES, lambda: h.planner._diagnostics.values['rejected'],
            h.spin_until)
        assert min(refused.values()) >= 0.95 * DDS_BAD_MESSAGES, refused
        requests = list(fuzz.generate(fuzz.get_plan_requests(bad_only=True), DDS_BAD_MESSAGES))
        for item in requests:
            future = h.client.call_async(item.msg)
            assert h.spin_until(future.done), 'get_plan did not answer'
            assert len(future.result().plan.poses) == 0, item.defects
        elapsed = time.monotonic() - started
        values = h.planner._diagnostics.values
        assert values['faults'] == 0, values['last_error']
        assert h.planner._map_msg.info.width == 80, 'a bad map must not replace a good one'

        # One rate-limited line per reason: five reasons here, no traceback.
        err = capfd.readouterr().err
        lines = fuzz.problem_lines(err, h.planner)
        assert 5 <= len(lines) <= fuzz.allowed_problem_lines(5, elapsed), lines
        assert 'Traceback' not in err

        assert h.send_goal(*GOAL), 'the node must still plan after the bad input'
        path = conv.path_from_msg(h.plans[-1], 'map')
        assert_ends_at(path, GOAL)
        assert_collision_free(wall_map(), path)
    finally:
        h.close()


def test_bug_in_a_callback_is_reported_not_fatal(harness, monkeypatch):
    harness.setup_world()

    def broken(*args, **kwargs):
        raise ZeroDivisionError('simulated bug')

    monkeypatch.setattr(GlobalPlanner, 'plan', broken)
    harness.goal_pub.publish(pose_msg(*GOAL))
    assert harness.spin_until(lambda: harness.statuses and harness.statuses[-1].level == DiagnosticStatus.ERROR)
    assert 'simulated bug' in harness.diag_values()['last_error']
    assert harness.spin_until(lambda: harness.plans and len(harness.plans[-1].poses) == 0), \
        'a failed planning must publish an empty plan so that followers stop'
    monkeypatch.undo()
    assert harness.send_goal(*GOAL)
    assert len(harness.plans[-1].poses) > 0


def test_start_pose_from_amcl_pose_by_parameter(context):
    h = Harness(context, [Parameter('pose_topic_type', value='pose_with_covariance')])
    try:
        h.setup_world(start=(1.5, 0.5))
        assert h.send_goal(*GOAL)
        path = conv.path_from_msg(h.plans[-1], 'map')
        assert math.dist(path[0], (1.5, 0.5)) <= RESOLUTION
        assert_ends_at(path, GOAL)
    finally:
        h.close()


def test_goal_before_map_and_start_is_planned_when_they_arrive(harness):
    harness.goal_pub.publish(pose_msg(*GOAL))
    assert harness.spin_until(lambda: 'no_map' in harness.outcomes())
    harness.map_pub.publish(map_msg(wall_map()))
    assert harness.spin_until(lambda: 'no_start_pose' in harness.outcomes())
    harness.odom_pub.publish(odom_msg(*START))
    assert harness.spin_until(lambda: harness.plans)
    assert_ends_at(conv.path_from_msg(harness.plans[-1], 'map'), GOAL)


def test_parameters_refused_with_reason_and_valid_change_applies(harness):
    harness.setup_world()
    client = AsyncParameterClient(harness.tester, f'{harness.ns}/global_planner')
    assert client.wait_for_services(timeout_sec=TIMEOUT_S)

    def set_remote(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        assert harness.spin_until(future.done)
        return future.result().results[0]

    for name, value, fragment in [('alpha', 500.0, 'out of range'),
                                  ('robot_radius', -0.1, 'out of range'),
                                  ('algorithm', 'rrt', 'one of'),
                                  ('neighbourhood', 12, 'neighbourhood'),
                                  ('frame_id', 'odom', 'read-only'),
                                  ('goal_tolerance', 1, 'type')]:
        result = set_remote(name, value)
        assert not result.successful, name
        assert fragment in result.reason, (name, result.reason)
    assert harness.planner.get_parameter('alpha').value == 1.0

    near_wall = (3.6, 3.0)  # 0.4 m from the wall's cell centres
    assert len(harness.get_plan(START, near_wall).poses) > 0
    assert set_remote('robot_radius', 0.6).successful
    assert harness.planner.get_parameter('robot_radius').value == 0.6
    assert len(harness.get_plan(START, near_wall).poses) == 0
    assert harness.spin_until(lambda: harness.outcomes()[-1:] == ['goal_occupied'])

    assert set_remote('publish_expanded', True).successful
    assert harness.send_goal(2.0, 3.0)
    assert harness.spin_until(lambda: any(
        m.ns == 'expanded' and m.points for a in harness.markers for m in a.markers))


def test_search_time_limit_gives_timeout_outcome(context):
    h = Harness(context, [Parameter('algorithm', value='dijkstra'),
                          Parameter('planning_time_limit', value=0.001)])
    try:
        occ = np.zeros((300, 300), bool)
        occ[20:300, 150] = True
        h.setup_world(GridMap(occ, RESOLUTION), start=(1.0, 29.0))
        assert len(h.get_plan((1.0, 29.0), (29.0, 29.0)).poses) == 0
        assert h.spin_until(lambda: h.outcomes()[-1:] == ['timeout'])
    finally:
        h.close()


def test_nearest_free_goal_prefers_the_start_component():
    occ = np.zeros((20, 20), bool)
    occ[:, 10] = True  # two halves
    grid = GridMap(occ, 1.0)
    free = grid.traversable(0.0)
    from scipy import ndimage
    labels = ndimage.label(free)[0]
    goal = (10.6, 5.5)  # in the wall, nearer the right half
    assert nearest_free_goal(grid, free, goal, 2.0).tolist() == [11.5, 5.5]
    assert nearest_free_goal(grid, free, goal, 2.0, labels, (5, 2)).tolist() == [9.5, 5.5]
    assert nearest_free_goal(grid, free, goal, 0.5, labels, (5, 2)) is None


def test_params_yaml_lists_exactly_the_declared_parameters(context):
    doc = yaml.safe_load(CONFIG.read_text())
    sections = [key for key in doc if key.split('/')[-1] == 'global_planner']
    assert len(sections) == 1, 'params.yaml needs exactly one global_planner section'
    listed = doc[sections[0]]['ros__parameters']
    assert listed.pop('use_sim_time') is True  # the bundled setup runs on the simulator's clock
    declared = {spec.name for spec in PARAMETER_SPECS}
    assert set(listed) == declared
    node = GlobalPlannerNode(context=context,
                             cli_args=['--ros-args', '--params-file', str(CONFIG)])
    try:
        plain = Node('plain', context=context)
        built_in = set(plain._parameters)  # use_sim_time and friends, declared by rclpy
        plain.destroy_node()
        node_declared = set(node._parameters) - built_in
        assert node_declared == declared
        for spec in PARAMETER_SPECS:
            assert node.get_parameter(spec.name).value == listed[spec.name] == spec.default, spec.name
            assert node.describe_parameter(spec.name).description
    finally:
        node.destroy_node()


def _run_node(*ros_args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(CONFIG.parent.parent), os.environ.get('PYTHONPATH', '')]))
    return subprocess.Popen(
        [sys.executable, '-m', 'fusion_planner.ros.global_planner', '--ros-args', *ros_args],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_executable_serves_and_stops_cleanly_on_sigint(context):
    ns = '/gp_process'
    proc = _run_node('--params-file', str(CONFIG), '-r', f'__ns:={ns}')
    probe = Node('probe', context=context, namespace=ns)
    try:
        client = probe.create_client(GetPlan, 'get_plan')
        assert client.wait_for_service(timeout_sec=30.0), 'the node process did not come up'
        proc.send_signal(signal.SIGINT)
        output, _ = proc.communicate(timeout=15.0)
        assert proc.returncode == 0, output
        assert 'Traceback' not in output
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        probe.destroy_node()


def test_executable_refuses_bad_parameters_with_one_line():
    proc = _run_node('-p', 'alpha:=500.0')
    output, _ = proc.communicate(timeout=30.0)
    assert proc.returncode == 1
    assert 'alpha' in output and 'out of range' in output and 'Traceback' not in output


def test_with_use_tf_the_start_and_the_laser_pose_come_from_a_tf_buffer(context):
    from test_local_planner_node import BufferStandIn

    buffer = BufferStandIn({('map', 'base_link'): (START[0], START[1], 0.0)})
    node = GlobalPlannerNode(context=context, namespace='/gp_tf', tf_buffer=buffer,
                             parameter_overrides=[Parameter('robot_radius', value=ROBOT_RADIUS),
                                                  Parameter('use_tf', value=True)])
    tester = Node('tf_tester', context=context, namespace='/gp_tf')
    plans = []
    tester.create_subscription(Path, 'plan', plans.append, LATCHED_QOS)
    map_pub = tester.create_publisher(OccupancyGrid, 'map', LATCHED_QOS)
    goal_pub = tester.create_publisher(PoseStamped, 'goal_pose', 10)
    scan_pub = tester.create_publisher(LaserScan, 'scan', qos_profile_sensor_data)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(tester)

    def spin_until(condition):
        deadline = time.monotonic() + TIMEOUT_S
        while not condition() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
        return condition()

    try:
        assert not any(name.endswith(('/odom', '/amcl_pose')) for name, _ in
                       node.get_subscriber_names_and_types_by_node('global_planner', '/gp_tf'))
        map_pub.publish(map_msg(wall_map()))
        assert spin_until(lambda: node._start is not None and goal_pub.get_subscription_count())
        goal_pub.publish(pose_msg(*GOAL))
        assert spin_until(lambda: plans and plans[-1].poses)
        path = conv.path_from_msg(plans[-1], 'map')
        assert math.dist(path[0], START) <= RESOLUTION and ('map', 'base_link') in buffer.asked
        # A scan whose frame TF does not know is refused, with the frame named.
        scan = LaserScan()
        scan.header.frame_id = 'camera'
        scan.angle_min, scan.angle_increment, scan.range_max = -1.0, 0.1, 5.0
        scan.ranges = [1.0] * 20
        assert spin_until(lambda: scan_pub.get_subscription_count() > 0)
        scan_pub.publish(scan)
        assert spin_until(lambda: 'camera' in node._diagnostics.values['last_error'])
        assert ('map', 'camera') in buffer.asked
    finally:
        executor.shutdown()
        tester.destroy_node()
        node.destroy_node()
