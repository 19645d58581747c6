"""Making ``wait_for_all_acked`` back-pressure cheap with Fast DDS (the Jazzy default RMW).

Measured (docs/bags.md): a reliable Fast DDS writer learns that a reader has its samples only
from the reader's ACKNACK, which answers the writer's periodic heartbeat, 3 s by default. So
``publisher.wait_for_all_acked()`` takes up to 3 s per call. With the profile below (heartbeat
every 2 ms) it takes ~5 ms, so a publisher can wait every N steps (N x messages per step well
below the history depth) for ~50 us per step and never overrun a KEEP_ALL reader (the recorder).

Fast DDS reads the profile when the process creates its first participant: put the variable in
the environment of the publishing process (``fast_heartbeat_env``), or call
``install_fast_heartbeat()`` before ``rclpy.init()``. An existing setting is never overridden.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

PROFILES_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'
HEARTBEAT_NS = 2_000_000

PROFILE_XML = f"""<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_writer profile_name="wallbot_fast_heartbeat" is_default_profile="true">
      <times>
        <heartbeatPeriod><sec>0</sec><nanosec>{HEARTBEAT_NS}</nanosec></heartbeatPeriod>
      </times>
    </data_writer>
  </profiles>
</dds>
"""


def profile_path(directory: Path | str | None = None) -> Path:
    """Write the profile (once) into ``directory`` (default: the temp dir) and return its path."""
    path = Path(directory or tempfile.gettempdir()) / 'wallbot_fastdds_heartbeat.xml'
    if not path.is_file() or path.read_text() != PROFILE_XML:
        tmp = path.with_name(f'.{path.name}.{os.getpid()}')
        tmp.write_text(PROFILE_XML)
        tmp.replace(path)
    return path


def fast_heartbeat_env(directory: Path | str | None = None) -> dict[str, str]:
    """Environment entries giving a process the fast-heartbeat profile (unless it has one)."""
    if os.environ.get(PROFILES_ENV):
        return {}
    return {PROFILES_ENV: str(profile_path(directory))}


def install_fast_heartbeat(directory: Path | str | None = None) -> None:
    """Set the profile in this process's environment; call before ``rclpy.init()``."""
    os.environ.update(fast_heartbeat_env(directory))
