"""MCAP recordings of ROS 2 topics that Foxglove and ``ros2 bag`` open.

:class:`TopicRecorder` subscribes a node to a table of topics and writes
every message, as the CDR bytes the middleware delivered (``raw=True``
subscriptions, no Python round trip), to an MCAP file with the ``ros2``
profile: one schema per message type, encoded ``ros2msg`` (the ``.msg``
definition with every nested type appended, as rosbag2 writes it), and one
channel per topic with message encoding ``cdr``. The MCAP container is
written by the ``mcap`` library; ``mcap-ros2-support`` reads it back.

The definitions come from the ``.msg`` files of the installed interface
packages (``share/<package>/msg/<Type>.msg`` under ``AMENT_PREFIX_PATH``, or
the Python prefix for the pip-installed ROS 2 wheels).

References
----------
rosbag2, ``docs/message_definition_encoding.md`` (the ``ros2msg`` format);
the MCAP specification, "ros2" profile.
"""

import os
import pathlib
import re
import sys
import threading

#: Separator line before each nested definition in a ``ros2msg`` schema.
DEFINITION_SEPARATOR = '=' * 80
#: Field types of ``.msg`` files that are not messages.
PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'})
#: Size of an uncompressed MCAP chunk [bytes].
CHUNK_SIZE = 1024 * 1024


class DefinitionNotFound(LookupError):
    """A message type whose ``.msg`` file is in no searched share folder."""


def type_name_of(msg_class):
    """The ROS 2 name ``package/msg/Type`` of a generated message class.

    Examples
    --------
    >>> from nav_msgs.msg import Odometry  # doctest: +SKIP
    >>> type_name_of(Odometry)  # doctest: +SKIP
    'nav_msgs/msg/Odometry'
    """
    return f"{msg_class.__module__.split('.')[0]}/msg/{msg_class.__name__}"


def share_folders():
    """Folders searched for ``<package>/msg/<Type>.msg``, in order.

    Returns
    -------
    list of pathlib.Path
        ``<prefix>/share`` of every entry of ``AMENT_PREFIX_PATH`` (a sourced
        ROS 2 install or colcon workspace), then of the Python prefix (the
        ROS 2 wheels of the ``ros`` extra).
    """
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    return [pathlib.Path(prefix) / 'share' for prefix in dict.fromkeys(prefixes)]


def msg_file(type_name, folders):
    """The ``.msg`` file of ``package/msg/Type`` in the first folder that has it.

    Raises
    ------
    DefinitionNotFound
        If no folder has it.
    """
    package, _, name = type_name.split('/')
    for folder in folders:
        path = folder / package / 'msg' / f'{name}.msg'
        if path.is_file():
            return path
    raise DefinitionNotFound(
        f'no definition of {type_name}: {package}/msg/{name}.msg is in none of '
        f'{", ".join(str(f) for f in folders)}')


def nested_types(text, package):
    """Message types of the fields of a ``.msg`` text, in order, each once.

    Parameters
    ----------
    text : str
        A ``.msg`` definition.
    package : str
        Its package: a bare type name (``MeshFile``) is of the same package.

    Returns
    -------
    list of str
        ``package/msg/Type`` names; primitives and constants are skipped.

    Examples
    --------
    >>> nested_types('std_msgs/Header header  # stamp\\nint32 X=1\\nPoint[] pts\\nstring<=8 s',
    ...              'geometry_msgs')
    ['std_msgs/msg/Header', 'geometry_msgs/msg/Point']
    """
    found = []
    for line in text.splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) < 2 or '=' in words[1]:
            continue  # blank, comment, or a constant (``int32 X=1``)
        base = re.sub(r'(<=\d+)?(\[.*\])?$', '', words[0])
        if base in PRIMITIVE_TYPES:
            continue
        parts = base.split('/')
        full = f'{package}/msg/{base}' if len(parts) == 1 else f'{parts[0]}/msg/{parts[-1]}'
        if full not in found:
            found.append(full)
    return found


def message_definition(type_name, folders=None):
    """The complete ``ros2msg`` definition of a message type.

    Parameters
    ----------
    type_name : str
        ``package/msg/Type``, e.g. ``'nav_msgs/msg/Odometry'``.
    folders : sequence of pathlib.Path, optional
        Share folders to search; default :func:`share_folders`.

    Returns
    -------
    str
        The type's ``.msg`` text, then for every type nested in it (depth
        first, each once) a line of 80 ``=``, a line ``MSG: package/msg/Type``
        and that type's ``.msg`` text.

    Raises
    ------
    DefinitionNotFound
        If a ``.msg`` file of the type or of a nested type is missing.
    """
    folders = share_folders() if folders is None else list(folders)
    texts = {}
    pending = [type_name]
    while pending:
        name = pending.pop(0)
        if name in texts:
            continue
        texts[name] = msg_file(name, folders).read_text(encoding='utf-8').strip('\n')
        pending[:0] = [t for t in nested_types(texts[name], name.split('/')[0]) if t not in texts]
    parts = [texts[type_name]]
    for name, text in texts.items():
        if name != type_name:
            parts.append(f'{DEFINITION_SEPARATOR}\nMSG: {name}\n{text}')
    return '\n'.join(parts) + '\n'


class TopicRecorder:
    """Record topics of a running ROS 2 graph into an MCAP file.

    Parameters
    ----------
    node : rclpy.node.Node
        Subscribes; its clock stamps the messages (simulated time when the
        node has ``use_sim_time``).
    path : str or os.PathLike
        The ``.mcap`` file to write (its folder must exist).
    topics : sequence of (str, type, QoSProfile)
        Topic name (resolved like the node's other topics), message class,
        and the QoS to subscribe with (compatible with the publisher's:
        transient local for latched topics, best effort for sensor data).

    Raises
    ------
    DefinitionNotFound
        If a message definition is not installed.
    OSError
        If the file cannot be written.
    ImportError
        If the ``mcap`` library is missing (the ``record`` extra).

    Notes
    -----
    Messages arrive from executor threads; a lock orders the writes. The
    subscriptions live as long as the node; after :meth:`close`
    (idempotent) they drop what still arrives. The log and publish time of a
    message are the node's clock at its reception [ns].
    """

    def __init__(self, node, path, topics):
        from mcap.well_known import MessageEncoding, Profile, SchemaEncoding
        from mcap.writer import CompressionType, Writer

        definitions = {}
        for _, msg_class, _ in topics:
            name = type_name_of(msg_class)
            if name not in definitions:
                definitions[name] = message_definition(name)
        self.path = pathlib.Path(path)
        self.counts = {}
        self._node = node
        self._lock = threading.Lock()
        self._closed = False
        self._file = open(self.path, 'wb')
        self._writer = Writer(self._file, chunk_size=CHUNK_SIZE,
                              compression=CompressionType.ZSTD)
        self._writer.start(profile=Profile.ROS2, library='fusion_planner')
        schemas = {name: self._writer.register_schema(name, SchemaEncoding.ROS2, text.encode())
                   for name, text in definitions.items()}
        for topic, msg_class, qos in topics:
            resolved = node.resolve_topic_name(topic)
            channel = self._writer.register_channel(
                resolved, MessageEncoding.CDR, schemas[type_name_of(msg_class)])
            self.counts[resolved] = 0
            node.create_subscription(msg_class, topic, self._writer_of(resolved, channel), qos,
                                     raw=True)

    def _writer_of(self, topic, channel):
        """The raw-message callback of one topic."""
        def write(data):
            now = self._node.get_clock().now().nanoseconds
            with self._lock:
                if self._closed:
                    return
                self._writer.add_message(channel, log_time=now, publish_time=now,
                                         data=bytes(data), sequence=self.counts[topic])
                self.counts[topic] += 1
        return write

    def close(self):
        """Stop recording and finish the file (summary, index); returns the message counts."""
        with self._lock:
            if not self._closed:
                self._closed = True
                self._writer.finish()
                self._file.close()
        return dict(self.counts)
