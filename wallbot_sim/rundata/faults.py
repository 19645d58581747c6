"""The fault events a run recorded (``faults``: what changed, when and why, every fault setting's value after it)."""

from __future__ import annotations

from pathlib import Path

from wallbot_msgs_py import codec, topics
from wallbot_sim.rundata.errors import RunDataError


def fault_events(path: Path | str) -> list[codec.FaultEvent]:
    """Every fault event of the bag at ``path``, in time order (none: a run without faults); RunDataError /
    BagError if it cannot be read."""
    from wallbot_sim.bag.reader import info, messages
    leaf = f'/{topics.FAULTS.name}'
    names = [topic.name for topic in info(path).topics if topic.name.endswith(leaf)]
    events = []
    for raw in messages(path, names) if names else ():
        try:
            events.append(codec.decode_fault_event(raw.data))
        except ValueError as error:
            raise RunDataError(f'{path}: {raw.topic}: {error}') from None
    return sorted(events, key=lambda event: event.stamp_ns)
