"""A short writer heartbeat and a participant that keeps announcing itself while a graph starts, for Fast DDS
(the Jazzy default RMW), as a default XML profile.

A reliable Fast DDS writer learns what a reader lacks only from the reader's ACKNACK, which answers
the writer's periodic heartbeat, every 3 s by default. So a sample lost in transit (a starved
reader's shared-memory queue or socket buffer overflowing) holds every later sample of that writer
back from the reader for up to 3 s, and is never repaired if the writer leaves DDS first; and
``publisher.wait_for_all_acked()`` takes up to 3 s. With a heartbeat every ``period`` seconds both
take about that period (docs/nodes.md, "Reliable delivery").

Fast DDS 2.14 sends a new participant's first announcement before the participant receives anything
(``RTPSParticipantImpl::enable`` starts the announcements, then registers the receivers). A participant
already running answers the first announcement of a newcomer at once, and only that one: the answer
often arrives before the newcomer listens and is lost, and the newcomer learns of the older participant
only from its next periodic announcement, every 3 s by default (seen: ``wallbot-sim run``'s nodes found
its monitor, made first, 3 s after they started, and the run ended that much later). Processes started
together find each other by their first announcements, five 0.1 s apart by default. With this profile
a participant announces itself every ``ANNOUNCEMENT_PERIOD`` for its first ``ANNOUNCEMENT_WINDOW``
seconds: the processes started meanwhile find it within that period.

Fast DDS reads the profile when the process creates its first participant: call
``install_heartbeat()`` before ``rclpy.init()``. A profile file the user set (either variable of
``PROFILES_ENVS``) is never overridden: it is theirs to give a heartbeat.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

PROFILES_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'
"""The variable Fast DDS 2 (Jazzy) reads."""
PROFILES_ENVS = (PROFILES_ENV, 'FASTDDS_DEFAULT_PROFILES_FILE')
"""Either names the user's own profile file (the second is Fast DDS 3's name)."""
NODE_HEARTBEAT = 0.1
"""Seconds between heartbeats of the nodes' writers: a sample lost to a starved reader is repaired
within about this, a lockstep dynamics waits about this for a lost command (its lockstep_timeout is
2 s). A writer that keeps publishing always has samples not yet acknowledged, so it sends a
heartbeat every period to each reader, which answers it: the period is long enough for that to
cost nothing measurable beside the graph's 1 kHz traffic (docs/nodes.md, "Reliable delivery")."""
FLOW_CONTROL_HEARTBEAT = 0.002
"""Seconds between heartbeats for a publisher paced by ``wait_for_all_acked`` (``play``): a wait
takes about 5 ms instead of up to 3 s (docs/bags.md)."""


ANNOUNCEMENT_PERIOD = 0.1
"""Seconds between a participant's announcements in its first ANNOUNCEMENT_WINDOW (Fast DDS's own period
for its first five)."""
ANNOUNCEMENT_WINDOW = 10.0
"""Seconds a participant keeps announcing itself every ANNOUNCEMENT_PERIOD after it joins DDS: the time the
other processes of a graph started with it (or after it, as ``wallbot-sim run``'s nodes after its monitor)
take to join on a loaded machine. A process joining later finds it at its periodic announcement (3 s)."""
ANNOUNCEMENTS = round(ANNOUNCEMENT_WINDOW / ANNOUNCEMENT_PERIOD)


def duration_xml(tag: str, seconds: float) -> str:
    """A Fast DDS XML duration element."""
    whole, nanoseconds = divmod(round(seconds * 1e9), 1_000_000_000)
    return f'<{tag}><sec>{whole}</sec><nanosec>{nanoseconds}</nanosec></{tag}>'


def profile_xml(period: float) -> str:
    """A Fast DDS profile file whose default data writer sends a heartbeat every ``period`` seconds, and whose
    default participant announces itself ANNOUNCEMENTS times, every ANNOUNCEMENT_PERIOD, as it starts."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <participant profile_name="wallbot_announcements" is_default_profile="true">
      <rtps>
        <builtin>
          <discovery_config>
            <initialAnnouncements>
              <count>{ANNOUNCEMENTS}</count>
              {duration_xml('period', ANNOUNCEMENT_PERIOD)}
            </initialAnnouncements>
          </discovery_config>
        </builtin>
      </rtps>
    </participant>
    <data_writer profile_name="wallbot_heartbeat" is_default_profile="true">
      <times>
        {duration_xml('heartbeatPeriod', period)}
      </times>
    </data_writer>
  </profiles>
</dds>
"""


def profile_path(period: float) -> Path:
    """Write the profile of ``period`` (once) into the temp directory; its path (named by its settings: processes
    of another checkout may write theirs meanwhile)."""
    text = profile_xml(period)
    path = Path(tempfile.gettempdir()) / (f'wallbot_fastdds_heartbeat_{round(period * 1e6)}us_announce_'
                                          f'{ANNOUNCEMENTS}x{round(ANNOUNCEMENT_PERIOD * 1e3)}ms.xml')
    if not path.is_file() or path.read_text() != text:
        tmp = path.with_name(f'.{path.name}.{os.getpid()}')
        tmp.write_text(text)
        tmp.replace(path)
    return path


def install_heartbeat(period: float) -> None:
    """Give this process the profile of ``period`` (not if it has a profile file); call before its first participant
    (``rclpy.init()`` and its first node)."""
    if not any(os.environ.get(name) for name in PROFILES_ENVS):
        os.environ[PROFILES_ENV] = str(profile_path(period))
