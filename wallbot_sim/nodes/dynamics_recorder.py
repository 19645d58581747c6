"""``dynamics_recorder_node``: the dynamics node and the recorder in one process, one executor.

The recorder records where the per-step messages are made, as rosbag2's recorder loaded into the
publisher's component container with intra-process communication: the dynamics still publishes
every step's messages for live subscribers (controllers, RViz, ``ros2 topic echo``), but the
recorder does not subscribe them over DDS; it takes the same CDR bytes from an in-process tap
(``nodes.step_tap``), logged when the dynamics sent them. Every other recorded topic (reference,
diagnostics, commands, ...) is a DDS subscription as in ``recorder_node``.

Parameters: the dynamics node's (``nodes.dynamics``) and the recorder's ``output`` and ``topics``
(``nodes.recorder``), all on one command line. Back-pressure works as between the two processes:
the recorder publishes record_progress, the dynamics stays within its backpressure_window of it.

SIGINT/SIGTERM: the moment the signal is handled ends the recording, as for ``recorder_node``;
the dynamics' loop is stopped first, then every step logged up to the signal is written and later
ones are not, then the bag is closed (its metadata names the signal and its time) and the process
exits 0.

No snapshots are kept: a keeper in this process would die with the dynamics it should restart, so
``resume_wait`` and ``snapshot_period`` are fixed at 0 here (``settings.dynamics.COMPOSED``: read-only, and a
start value other than 0 is refused with that reason; a start never waits for a keeper, a state snapshot is
published only at events). After a SIGKILL, ``wallbot-sim bag reindex`` recovers
the bag up to its last flushed chunk, and a new run starts from t = 0.
"""

from __future__ import annotations

import sys

from rclpy.node import Node

from wallbot_sim.nodes.common import StopSignals, exit_process, run_nodes
from wallbot_sim.nodes.dynamics import SWITCH_INTERVAL, started_node
from wallbot_sim.nodes.recorder import Recorder
from wallbot_sim.nodes.state_publisher import STEP_TOPICS
from wallbot_sim.settings.dynamics import COMPOSED

PROGRAM = 'dynamics_recorder_node'


def composed_nodes(stop: StopSignals) -> list[Node]:
    """The dynamics node and the recorder taking its steps in process: the dynamics first, so that
    its loop has stopped when the recorder ends the recording (``common.run_nodes`` closes them in order)."""
    recorder = Recorder(stop, tappable=STEP_TOPICS, program=PROGRAM)
    try:
        dynamics = started_node(tap=recorder.tap, table=COMPOSED)
    except BaseException:
        recorder.writer.close()
        recorder.destroy_node()
        raise
    return [dynamics, recorder]


def main(args: list[str] | None = None) -> None:
    sys.setswitchinterval(SWITCH_INTERVAL)
    exit_process(run_nodes(composed_nodes, args, events=True))  # the recorder takes the graph's other topics


if __name__ == '__main__':
    main()
