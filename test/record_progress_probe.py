"""Prints how far a recorder got, for a test that cannot join the recorder's DDS network itself.

Run as a script (e.g. inside a network namespace); it prints ``recorder ready`` once a recorder
publishes record_progress, then ``recorded T`` whenever the newest /clock stamp the recorder has
written (T, s) changes. SIGINT or SIGTERM ends it. The same view ``wallbot-sim run`` has
(its Monitor).
"""

from __future__ import annotations

import math
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wallbot_sim.graph_monitor import Monitor  # noqa: E402


def main() -> int:
    stop: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, _frame: stop.append(signum))
    signal.signal(signal.SIGTERM, lambda signum, _frame: stop.append(signum))
    monitor = Monitor()
    ready, shown = False, -math.inf
    try:
        while not stop:
            monitor.spin(0.05)
            if not ready and monitor.recorder_ready():
                ready = True
                print('recorder ready', flush=True)
            if monitor.recorded > shown:
                shown = monitor.recorded
                print(f'recorded {shown:.3f}', flush=True)
    finally:
        monitor.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
