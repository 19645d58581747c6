"""One codec per message family: every encoder and decoder of the graph's messages is registered in
``wallbot_msgs_py.cdr``, one of each per family, and nothing else in the project builds or reads CDR.

The source tree is read (``ast``), not imported, so a second codec is found wherever it is written:
a registration in the interface layer, struct packing, a ROS message object built or decoded in a node,
a subscription that hands its callback a decoded message, a general serializer called.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from wallbot_msgs_py import cdr, topics

ROOT = Path(__file__).resolve().parents[1]
CODEC = ROOT / 'wallbot_msgs_py'
PRODUCT = [path for folder in ('wallbot_sim', 'wallbot_msgs_py', 'bench', 'launch')
           for path in sorted((ROOT / folder).rglob('*.py'))]
ONE_WAY = {
    'markers': 'encoder', 'tf': 'encoder',  # the viewer's: RViz and Foxglove read them, nothing in the graph
    'cmd_vel': 'decoder', 'initialpose': 'decoder',  # a teleop tool's and RViz's: the graph only reads them
}
"""Families with one side only, and which."""
CONTAINER = {ROOT / 'wallbot_sim/bag/writer.py', ROOT / 'wallbot_sim/bag/reindex.py'}
"""Modules that pack and unpack the MCAP container around the messages, not messages."""
SERIALIZERS = {'serialize', 'deserialize', 'serialize_cdr', 'deserialize_cdr', 'deserialize_cdr_le',
               'deserialize_cdr_be', 'serialize_message', 'deserialize_message'}
"""General (de)serializers of message objects: only ``bagio``, the interface's bridge to rosbags, names them."""


def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding='utf-8'), str(path))


def where(path: Path, node: ast.AST) -> str:
    return f'{path.relative_to(ROOT)}:{node.lineno}'


def registrations() -> list[tuple[str, str, str]]:
    """(family, role, place) of every ``@cdr.encoder(...)`` / ``@cdr.decoder(...)`` in the interface layer."""
    found = []
    for path in sorted(CODEC.rglob('*.py')):
        for node in ast.walk(tree(path)):
            for decorator in getattr(node, 'decorator_list', ()):
                if (isinstance(decorator, ast.Call) and isinstance(decorator.func, ast.Attribute)
                        and decorator.func.attr in ('encoder', 'decoder')):
                    found.append((decorator.args[0].value, decorator.func.attr, where(path, node)))
    return found


def test_every_family_has_one_encoder_and_one_decoder_and_every_topic_a_family():
    for module in ('codec', 'snapshot', 'step_cdr', 'view_cdr'):  # importing them registers their codecs
        importlib.import_module(f'wallbot_msgs_py.{module}')
    places: dict[tuple[str, str], list[str]] = {}
    for family, role, place in registrations():
        places.setdefault((family, role), []).append(place)
    assert {key: found for key, found in places.items() if len(found) > 1} == {}
    assert {family for family, _role in places} == set(cdr.FAMILIES)
    for name, family in cdr.FAMILIES.items():
        roles = {role for role in ('encoder', 'decoder') if getattr(family, role) is not None}
        assert roles == ({ONE_WAY[name]} if name in ONE_WAY else {'encoder', 'decoder'}), name
    types = {family.type for family in cdr.FAMILIES.values()}
    declared = [value for value in vars(topics).values() if isinstance(value, topics.Topic)]
    assert {topic.name: topic.type for topic in declared if topic.type not in types} == {}


def test_a_second_codec_of_a_family_is_refused_at_import():
    with pytest.raises(cdr.CodecConflict, match='family odometry has a decoder already: '
                                                'wallbot_msgs_py.codec.odometry.decode_odometry'):
        cdr.decoder('odometry', 'nav_msgs/msg/Odometry')(lambda message: None)
    with pytest.raises(cdr.CodecConflict, match='family clock is rosgraph_msgs/msg/Clock, not std_msgs/msg/String'):
        cdr.encoder('clock', 'std_msgs/msg/String')(lambda: b'')


def uses_cdr(node: ast.AST) -> bool:
    """Whether a definition builds with the Writer or reads with the Reader."""
    return any(isinstance(inner, ast.Attribute) and inner.attr in ('Writer', 'Reader')
               and isinstance(inner.value, ast.Name) and inner.value.id == 'cdr' for inner in ast.walk(node))


def test_in_the_interface_layer_only_registered_codecs_and_their_helpers_write_or_read_cdr():
    """A public function or class of wallbot_msgs_py that writes or reads CDR is a family's registered
    encoder or decoder; private ones are their helpers."""
    unregistered = []
    for path in sorted(CODEC.rglob('*.py')):
        if path.name == 'cdr.py':
            continue
        for node in tree(path).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith('_') and uses_cdr(node):
                if not node.decorator_list:
                    unregistered.append(f'{where(path, node)} {node.name}')
    assert unregistered == []


def message_classes(module: ast.Module) -> set[str]:
    """Names a module imports from a ROS message package (``from nav_msgs.msg import Odometry``); not
    rcl_interfaces, whose objects are rclpy's parameter API (descriptors, results), not the graph's messages."""
    return {alias.asname or alias.name for node in ast.walk(module) if isinstance(node, ast.ImportFrom)
            and (node.module or '').endswith('.msg') and node.module != 'rcl_interfaces.msg' for alias in node.names}


def second_codecs(path: Path, module: ast.Module | None = None) -> list[str]:
    """What in ``path`` (parsed: ``module``) encodes or decodes messages outside the codec."""
    module, found = module or tree(path), []
    classes = message_classes(module)
    for node in ast.walk(module):
        if isinstance(node, (ast.Import, ast.ImportFrom)) and path not in CONTAINER and not path.is_relative_to(CODEC):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else [node.module]
            if 'struct' in names:
                found.append(f'{where(path, node)}: struct')
        if not isinstance(node, ast.Call):
            continue
        name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, 'id', '')
        if name in SERIALIZERS and path != CODEC / 'bagio.py':
            found.append(f'{where(path, node)}: {name}')
        if name in classes:
            found.append(f'{where(path, node)}: a {name} message built')
        if name == 'create_subscription' and not any(k.arg == 'raw' and getattr(k.value, 'value', None) is True
                                                     for k in node.keywords):
            found.append(f'{where(path, node)}: a subscription decoding its messages')
    return found


def test_nothing_outside_the_codec_builds_or_reads_a_message():
    """Nodes, tools, bench scripts and the launch file publish the codec's bytes and subscribe raw; the
    scan finds what this test was written against: struct packing, message objects built, subscriptions
    that decode, general serializers."""
    assert [found for path in PRODUCT for found in second_codecs(path)] == []


@pytest.mark.parametrize('source, found', [
    ('import struct\n', 'struct'),
    ('from rosgraph_msgs.msg import Clock\nmsg = Clock()\n', 'a Clock message built'),
    ('node.create_subscription(Clock, "clock", callback, 10)\n', 'a subscription decoding its messages'),
    ('from rclpy.serialization import deserialize_message\ndeserialize_message(data, Odometry)\n',
     'deserialize_message'),
    ('bagio.serialize(msg, "std_msgs/msg/String")\n', 'serialize'),
])
def test_the_scan_finds_each_kind_of_second_codec(source, found):
    reported = second_codecs(ROOT / 'wallbot_sim' / 'nodes' / 'scanned.py', ast.parse(source))  # as a node's
    assert len(reported) == 1 and reported[0].endswith(found)
