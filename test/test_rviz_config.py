"""config/fusion_planner.rviz: a valid rviz2 layout wired to the nodes' real topics.

The file is parsed as YAML; each display must subscribe to a topic one of the
three nodes publishes (created here, so a renamed topic fails the test), with
a QoS that matches the publisher's, and the goal tool must publish where the
global planner listens.
"""

import pathlib

import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from rclpy.qos import DurabilityPolicy, ReliabilityPolicy  # noqa: E402

from fusion_planner.cli import demo_command  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros import global_planner  # noqa: E402
from fusion_planner.ros.simulator import default_scenario_path  # noqa: E402

RVIZ = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'fusion_planner.rviz'
#: What the layout must show: (display class, topic).
EXPECTED_DISPLAYS = {
    ('rviz_default_plugins/Map', '/map'),
    ('rviz_default_plugins/Path', '/plan'),
    ('rviz_default_plugins/Path', '/local_plan'),
    ('rviz_default_plugins/LaserScan', '/scan'),
    ('rviz_default_plugins/MarkerArray', '/obstacles'),
    ('rviz_default_plugins/MarkerArray', '/tracks'),
    ('rviz_default_plugins/MarkerArray', '/plan_markers'),
    ('rviz_default_plugins/Odometry', '/ground_truth'),
    ('rviz_default_plugins/PoseWithCovariance', '/amcl_pose'),
}
#: rviz2's names of the QoS policies the layout sets.
RELIABILITY = {'Reliable': ReliabilityPolicy.RELIABLE,
               'Best Effort': ReliabilityPolicy.BEST_EFFORT}
DURABILITY = {'Volatile': DurabilityPolicy.VOLATILE,
              'Transient Local': DurabilityPolicy.TRANSIENT_LOCAL}


@pytest.fixture(scope='module')
def layout():
    return yaml.safe_load(RVIZ.read_text(encoding='utf-8'))


@pytest.fixture(scope='module')
def graph(context):
    """``(publishers, subscriptions)`` of the three nodes: ``{topic: [QoSProfile]}``."""
    path = default_scenario_path()
    params = demo_command.node_parameters(load_scenario(path), path, 1.0)
    nodes = demo_command.make_nodes(context, params)
    try:
        publishers, subscriptions = {}, {}
        for node in nodes:
            for pub in node.publishers:
                publishers.setdefault(pub.topic_name, []).append(pub.qos_profile)
            for sub in node.subscriptions:
                subscriptions.setdefault(sub.topic_name, []).append(sub.qos_profile)
        return publishers, subscriptions
    finally:
        for node in nodes:
            node.destroy_node()


def displays(layout):
    return layout['Visualization Manager']['Displays']


def test_layout_is_in_the_map_frame_with_the_expected_displays(layout):
    manager = layout['Visualization Manager']
    frame = next(s.default for s in global_planner.PARAMETER_SPECS if s.name == 'frame_id')
    assert manager['Global Options']['Fixed Frame'] == frame
    shown = {(d['Class'], d['Topic']['Value']) for d in displays(layout) if 'Topic' in d}
    assert shown == EXPECTED_DISPLAYS
    assert all(d['Enabled'] for d in displays(layout))


def test_every_display_topic_is_published_with_a_matching_qos(layout, graph):
    publishers, _ = graph
    for display in displays(layout):
        if 'Topic' not in display:
            continue
        topic = display['Topic']
        assert topic['Value'] in publishers, \
            f"{display['Name']}: nobody publishes {topic['Value']}"
        for offered in publishers[topic['Value']]:
            if RELIABILITY[topic['Reliability Policy']] == ReliabilityPolicy.RELIABLE:
                assert offered.reliability == ReliabilityPolicy.RELIABLE, display['Name']
            if DURABILITY[topic['Durability Policy']] == DurabilityPolicy.TRANSIENT_LOCAL:
                assert offered.durability == DurabilityPolicy.TRANSIENT_LOCAL, display['Name']


def test_goal_tool_publishes_where_the_global_planner_listens(layout, graph):
    _, subscriptions = graph
    tools = layout['Visualization Manager']['Tools']
    (goal_tool,) = [t for t in tools if t['Class'] == 'rviz_default_plugins/SetGoal']
    assert goal_tool['Topic']['Value'] == '/goal_pose'
    assert '/goal_pose' in subscriptions
    assert RELIABILITY[goal_tool['Topic']['Reliability Policy']] == ReliabilityPolicy.RELIABLE
