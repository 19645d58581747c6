"""The Fast DDS profile of the package's processes (``wallbot_sim.heartbeat``): the writers' heartbeat, and a
participant that keeps announcing itself while the graph around it starts.

A participant already in DDS answers a newcomer's first announcement once, and Fast DDS 2.14 sends that first
announcement before the newcomer receives anything: the answer is often lost, and the newcomer then finds the older
participant only at its periodic announcement, every 3 s. The behaviour test listens where such a newcomer would,
on the port of the last participant id a localhost participant announces itself to, and counts the monitor's
(``wallbot-sim run``'s own participant) announcements.
"""
from __future__ import annotations

import os
import socket
import sys
import time
from pathlib import Path
from xml.etree import ElementTree

import pytest

from wallbot_sim.domain import claim_domain_id
from wallbot_sim.graph import ChildProcesses
from wallbot_sim.heartbeat import (ANNOUNCEMENT_PERIOD, ANNOUNCEMENT_WINDOW, ANNOUNCEMENTS, NODE_HEARTBEAT,
                                   PROFILES_ENVS, profile_xml)

NAMESPACE = {'dds': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
FAST_DDS_INITIAL_ANNOUNCEMENTS = 5
"""How many announcements Fast DDS sends, 0.1 s apart, before its periodic one every 3 s (its defaults)."""
LAST_PEER_ID = 31
"""The highest participant id a participant with localhost discovery announces itself to (ids 0..31)."""
STALL = 30.0
"""Wall seconds after which the announcements counted count as a stall: with the profile they take about 2 s; with
Fast DDS's defaults the 20th would come after 45 s."""
MONITOR = ('import signal, sys; from wallbot_sim.graph_monitor import Monitor; '
           'monitor = Monitor(domain_id=int(sys.argv[1])); signal.pause()')
"""A process whose only participant is the monitor, until it is stopped."""


def seconds(element: ElementTree.Element) -> float:
    return int(element.find('dds:sec', NAMESPACE).text) + int(element.find('dds:nanosec', NAMESPACE).text) * 1e-9


def test_the_profile_sets_the_writer_heartbeat_and_the_participants_announcements():
    profiles = ElementTree.fromstring(profile_xml(NODE_HEARTBEAT).encode()).find('dds:profiles', NAMESPACE)
    writer = profiles.find('dds:data_writer', NAMESPACE)
    assert writer.get('is_default_profile') == 'true'
    assert seconds(writer.find('dds:times/dds:heartbeatPeriod', NAMESPACE)) == pytest.approx(NODE_HEARTBEAT)
    participant = profiles.find('dds:participant', NAMESPACE)
    assert participant.get('is_default_profile') == 'true'
    initial = participant.find('dds:rtps/dds:builtin/dds:discovery_config/dds:initialAnnouncements', NAMESPACE)
    assert int(initial.find('dds:count', NAMESPACE).text) == ANNOUNCEMENTS
    assert seconds(initial.find('dds:period', NAMESPACE)) == pytest.approx(ANNOUNCEMENT_PERIOD)
    assert ANNOUNCEMENTS * ANNOUNCEMENT_PERIOD == pytest.approx(ANNOUNCEMENT_WINDOW)


def announcer(packet: bytes) -> bytes | None:
    """The GUID prefix of the participant whose announcement (an RTPS DATA of the SPDP writer) ``packet`` is."""
    spdp_writer = bytes.fromhex('000100c2')
    if packet[:4] != b'RTPS' or spdp_writer not in packet[20:]:
        return None
    return packet[8:20]


def test_the_monitor_keeps_announcing_itself_while_the_nodes_join(tmp_path: Path):
    """``wallbot-sim run`` makes its monitor before it starts the nodes: each node that joins after Fast DDS's first
    five announcements must still hear one within a fraction of a second. Counted where a node with the last
    participant id would listen: more than Fast DDS alone would send for 45 s, well within a stall's time."""
    pytest.importorskip('rclpy')
    wanted = 4 * FAST_DDS_INITIAL_ANNOUNCEMENTS
    with claim_domain_id() as claim:
        port = 7400 + 250 * claim.domain_id + 10 + 2 * LAST_PEER_ID  # the RTPS metatraffic unicast port
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as listener:
            listener.bind(('127.0.0.1', port))
            listener.settimeout(0.5)
            env = {name: value for name, value in claim.env().items() if name not in PROFILES_ENVS}
            processes = ChildProcesses(tmp_path / 'logs', env, stop_timeout=5.0)
            try:
                monitor = processes.start([sys.executable, '-c', MONITOR, claim.domain_id], 'monitor')
                counts: dict[bytes, int] = {}
                deadline = time.monotonic() + STALL
                while max(counts.values(), default=0) < wanted:
                    assert monitor.poll() is None, processes.output('monitor')
                    assert time.monotonic() < deadline, (f'{counts} announcements in {STALL:.0f} s: the monitor '
                                                         'announces itself as Fast DDS does by default')
                    try:
                        sender = announcer(listener.recv(65536))
                    except TimeoutError:
                        continue
                    if sender is not None:
                        counts[sender] = counts.get(sender, 0) + 1
                assert len(counts) == 1, f'announcements from {len(counts)} participants in a domain of one'
            finally:
                processes.stop_all()


def test_the_monitor_leaves_a_profile_the_user_set_and_the_environment_as_it_was(monkeypatch):
    from wallbot_sim.graph_monitor import participant_environment
    for name in PROFILES_ENVS:
        monkeypatch.delenv(name, raising=False)
    before = dict(os.environ)
    assert Path(participant_environment()[PROFILES_ENVS[0]]).read_text() == profile_xml(NODE_HEARTBEAT)
    assert dict(os.environ) == before
    monkeypatch.setenv(PROFILES_ENVS[1], '/somewhere/theirs.xml')
    assert not set(PROFILES_ENVS) & set(participant_environment())
