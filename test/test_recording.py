"""MCAP recordings: ros2msg schemas, CDR messages, read back with the mcap readers.

The definitions are checked against mcap-ros2-support's parser; a live
recording of a publisher is decoded message by message; and the demo's
recording is opened as Foxglove or ``ros2 bag`` would: every demo topic is
there with its ROS 2 type, schema encoding ``ros2msg``, message encoding
``cdr`` and messages stamped with the simulated time.
"""

import math
import sys
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('mcap')
pytest.importorskip('mcap_ros2')

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2._dynamic import generate_dynamic  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
from nav_msgs.msg import OccupancyGrid, Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

from fusion_planner.cli import demo_command, recording  # noqa: E402
from fusion_planner.cli.main import main  # noqa: E402
from fusion_planner.core.grid import GridMap  # noqa: E402
from fusion_planner.core.map_files import save_map_server  # noqa: E402

#: Topics of the demo's recording and their ROS 2 types.
DEMO_TOPICS = {
    '/map': 'nav_msgs/msg/OccupancyGrid', '/plan': 'nav_msgs/msg/Path',
    '/plan_markers': 'visualization_msgs/msg/MarkerArray', '/local_plan': 'nav_msgs/msg/Path',
    '/odom': 'nav_msgs/msg/Odometry', '/ground_truth': 'nav_msgs/msg/Odometry',
    '/amcl_pose': 'geometry_msgs/msg/PoseWithCovarianceStamped', '/scan': 'sensor_msgs/msg/LaserScan',
    '/obstacles': 'visualization_msgs/msg/MarkerArray', '/tracks': 'visualization_msgs/msg/MarkerArray',
    '/cmd_vel': 'geometry_msgs/msg/TwistStamped',
    '/goal_pose': 'geometry_msgs/msg/PoseStamped', '/goal_outcome': 'std_msgs/msg/String',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}
#: Wall time allowed for a few messages to arrive [s].
DELIVERY_TIMEOUT_S = 10.0


def read_mcap(path):
    """(summary, {topic: [(log_time [ns], decoded message)]}) of an MCAP file."""
    messages = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        header = reader.get_header()
        for _, channel, message, decoded in reader.iter_decoded_messages():
            messages.setdefault(channel.topic, []).append((message.log_time, decoded))
    return header, summary, messages


# -- definitions --------------------------------------------------------------------

def test_nested_types_skip_primitives_constants_and_comments():
    text = ('# a comment naming std_msgs/Header\n'
            'int32 MODE=3\n'
            'string<=10 name\n'
            'std_msgs/Header header # trailing comment\n'
            'Marker[] markers\n'
            'geometry_msgs/Point[<=4] corners\n'
            'float64[36] covariance\n')
    assert recording.nested_types(text, 'visualization_msgs') == [
        'std_msgs/msg/Header', 'visualization_msgs/msg/Marker', 'geometry_msgs/msg/Point']


def test_definitions_carry_every_nested_type_once_and_parse():
    for _, msg_class, _ in demo_command.recorded_topics():
        name = recording.type_name_of(msg_class)
        text = recording.message_definition(name)
        nested = [line[5:] for line in text.splitlines() if line.startswith('MSG: ')]
        assert len(nested) == len(set(nested)) and name not in nested
        assert text.count(recording.DEFINITION_SEPARATOR + '\nMSG: ') == len(nested)
        assert name in generate_dynamic(name, text)  # mcap-ros2-support can decode with it
    odometry = recording.message_definition('nav_msgs/msg/Odometry')
    for nested in ('std_msgs/msg/Header', 'builtin_interfaces/msg/Time',
                   'geometry_msgs/msg/PoseWithCovariance', 'geometry_msgs/msg/Vector3'):
        assert f'MSG: {nested}\n' in odometry


def test_a_missing_definition_is_named(tmp_path):
    with pytest.raises(recording.DefinitionNotFound, match='nav_msgs/msg/Odometry.msg'):
        recording.message_definition('nav_msgs/msg/Odometry', folders=[tmp_path])


# -- a live recording -----------------------------------------------------------------

def test_recorder_writes_what_was_published(context, tmp_path):
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    talker = Node('recording_talker', context=context)
    listener = Node('recording_listener', context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        map_pub = talker.create_publisher(OccupancyGrid, 'rec_map', latched)
        odom_pub = talker.create_publisher(Odometry, 'rec_odom', 10)
        grid = OccupancyGrid()
        grid.header.frame_id = 'map'
        grid.info.width, grid.info.height, grid.info.resolution = 3, 2, 0.5
        grid.data = [0, 100, -1, 0, 0, 100]
        map_pub.publish(grid)  # before the recorder exists: latched
        recorder = recording.TopicRecorder(
            listener, tmp_path / 'live.mcap',
            [('rec_map', OccupancyGrid, latched), ('rec_odom', Odometry, 10)])
        executor.add_node(talker)
        executor.add_node(listener)
        deadline = time.monotonic() + DELIVERY_TIMEOUT_S
        x = 0.0
        while time.monotonic() < deadline and \
                (recorder.counts['/rec_odom'] < 5 or recorder.counts['/rec_map'] < 1):
            odom = Odometry()
            odom.header.frame_id = 'map'
            odom.pose.pose.position.x = x
            odom_pub.publish(odom)
            x += 1.0
            executor.spin_once(timeout_sec=0.05)
        counts = recorder.close()
        assert recorder.close() == counts  # idempotent
    finally:
        executor.shutdown()
        talker.destroy_node()
        listener.destroy_node()
    assert counts['/rec_map'] == 1 and counts['/rec_odom'] >= 5
    header, summary, messages = read_mcap(tmp_path / 'live.mcap')
    assert header.profile == 'ros2'
    channels = {c.topic: c for c in summary.channels.values()}
    for topic, name in (('/rec_map', 'nav_msgs/msg/OccupancyGrid'),
                        ('/rec_odom', 'nav_msgs/msg/Odometry')):
        schema = summary.schemas[channels[topic].schema_id]
        assert (schema.name, schema.encoding, channels[topic].message_encoding) == \
            (name, 'ros2msg', 'cdr')
        assert summary.statistics.channel_message_counts[channels[topic].id] == counts[topic]
    (_, got_map), = messages['/rec_map']
    assert (got_map.info.width, got_map.info.height, got_map.info.resolution) == (3, 2, 0.5)
    assert list(got_map.data) == [0, 100, -1, 0, 0, 100] and got_map.header.frame_id == 'map'
    xs = [odom.pose.pose.position.x for _, odom in messages['/rec_odom']]
    assert xs == sorted(xs) and xs[0] == 0.0 and len(xs) == counts['/rec_odom']


def test_without_the_mcap_library_the_demo_refuses_before_it_starts(monkeypatch, tmp_path,
                                                                     capsys):
    monkeypatch.setitem(sys.modules, 'mcap', None)  # import fails
    status = main(['demo', '--plot', str(tmp_path / 'out' / 'run.png'), '--no-plot', '--no-gif'])
    out, err = capsys.readouterr()
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and "pip install 'fusion_planner[record]'" in err
    assert '--no-record' in err and not (tmp_path / 'out').exists()


# -- the demo's recording ----------------------------------------------------------------

def write_short_scenario(folder):
    """A 6 m x 3 m room, a 4 m drive, one person bouncing in a far corner."""
    save_map_server(GridMap(np.zeros((30, 60), bool), 0.1), folder / 'hall.yaml')
    doc = {'name': 'hall', 'map': 'hall.yaml', 'seed': 1,
           'robot': {'start': [0.75, 1.55, 0.0], 'radius': 0.2, 'max_speed': 0.8},
           'goal': [4.75, 1.55],
           'moving_obstacles': [{'radius': 0.2, 'model': 'bounce', 'position': [5.4, 2.5],
                                 'velocity': [0.1, 0.0]}],
           'limits': {'time_limit_s': 40.0, 'dt': 0.1}, 'scan': {'beams': 90, 'range_max': 5.0}}
    path = folder / 'hall_scenario.yaml'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    return path


@pytest.fixture(scope='module')
def demo_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp('demo_recording')
    code = main(['demo', '--scenario', str(write_short_scenario(folder)),
                 '--real-time-factor', '20', '--plot', str(folder / 'run.png')])
    return code, folder


def test_demo_writes_picture_animation_and_recording(demo_run):
    code, folder = demo_run
    assert code == 0
    assert (folder / 'run.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert (folder / 'run.gif').read_bytes()[:6] == b'GIF89a'
    assert (folder / 'run.mcap').read_bytes()[:8] == b'\x89MCAP0\r\n'


def test_demo_recording_has_every_topic_with_its_schema(demo_run):
    _, folder = demo_run
    header, summary, messages = read_mcap(folder / 'run.mcap')
    assert header.profile == 'ros2'
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == set(DEMO_TOPICS)
    for topic, type_name in DEMO_TOPICS.items():
        schema = summary.schemas[channels[topic].schema_id]
        assert (schema.name, schema.encoding) == (type_name, 'ros2msg'), topic
        assert channels[topic].message_encoding == 'cdr', topic
        assert summary.statistics.channel_message_counts.get(channels[topic].id, 0) > 0, topic
        assert len(messages[topic]) == \
            summary.statistics.channel_message_counts[channels[topic].id]


def test_demo_recording_decodes_to_the_run_on_simulated_time(demo_run):
    _, folder = demo_run
    _, _, messages = read_mcap(folder / 'run.mcap')
    (_, grid), = messages['/map']
    assert (grid.info.width, grid.info.height) == (60, 30) and grid.header.frame_id == 'map'
    times = [t for t, _ in messages['/odom']]
    stamps = [odom.header.stamp.sec + odom.header.stamp.nanosec * 1e-9
              for _, odom in messages['/odom']]
    assert times == sorted(times)
    # stamped on the simulated clock: log time follows the odometry stamps
    assert max(abs(t * 1e-9 - s) for t, s in zip(times, stamps)) < 1.0
    assert messages['/odom'][-1][1].header.frame_id == 'odom'
    last = messages['/ground_truth'][-1][1].pose.pose.position
    assert math.hypot(last.x - 4.75, last.y - 1.55) < 0.5
    plans = [plan for _, plan in messages['/plan']]
    # in lockstep an empty plan is in force until the first one is planned
    driven = [plan for plan in plans if plan.poses]
    assert driven and driven[0].header.frame_id == 'map'
    # The goal ended once, reached; then the plan emptied, so nothing drives it again.
    assert [msg.data for _, msg in messages['/goal_outcome']] == ['reached']
    assert not plans[-1].poses
    assert any(status.name.endswith('local_planner')
               for _, array in messages['/diagnostics'] for status in array.status)
