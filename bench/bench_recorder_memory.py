"""Recorder resident memory at 1 kHz: after 10 s vs after a long run.

Feeds recorder_node the graph's real message mix (odom, wheel_states, constraint_wrench,
drive_forces, reference, /clock at 1 kHz, /diagnostics at 10 Hz) by playing a headless
`simulate --bag` of the circle at real-time factor 1, and samples the recorder's VmRSS.

    python bench/bench_recorder_memory.py --duration 600     # the issue's 10-minute figure
    python bench/bench_recorder_memory.py --duration 60      # a quicker check
    (--write-docs [FILE]: the figures into docs/performance.md)

Runs in its own ROS domain (claim_domain_id) on localhost discovery; kills what it starts.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from report import Report, add_write_docs_option
from wallbot_sim.domain import claim_domain_id, isolated_ros_env
from wallbot_sim.graph import ChildProcesses, resident_mib


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=60.0, help='seconds of 1 kHz recording (default 60)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('recorder-memory')
    work = Path(tempfile.mkdtemp(prefix='wallbot_bench_rec_'))
    source = work / 'source'
    subprocess.run([sys.executable, '-m', 'wallbot_sim.cli.main', 'simulate', '--scenario', 'circle',
                    '--duration', str(args.duration), '--bag', str(source), '--quiet'], check=True)
    with claim_domain_id() as claim:
        processes = ChildProcesses(work / 'logs', isolated_ros_env(claim.domain_id), stop_timeout=30.0)
        recorder = processes.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args',
                                    '-p', f'output:={work / "recorded"}'], 'recorder')
        try:
            time.sleep(2.0)
            idle = resident_mib(recorder.pid)
            player = processes.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'play', str(source), '--quiet',
                                      '--delay', '2'], 'play')
            started = time.monotonic()
            samples = []
            while player.poll() is None:
                time.sleep(1.0)
                samples.append((time.monotonic() - started - 2.0, resident_mib(recorder.pid)))
            at_10 = next((r for t, r in samples if t >= 10.0), float('nan'))
            final = samples[-1][1] if samples else float('nan')
            peak = max((r for _, r in samples), default=float('nan'))
        finally:
            processes.stop_all()  # the recorder's bag closes at its SIGTERM
    out = subprocess.run([sys.executable, '-m', 'wallbot_sim.cli.main', 'info', str(work / 'recorded')],
                         capture_output=True, text=True)
    print(out.stdout)
    print(f'recorder RSS: idle {idle:.1f} MiB, after 10 s {at_10:.1f} MiB, at the end ({args.duration:.0f} s) '
          f'{final:.1f} MiB, peak {peak:.1f} MiB, growth after 10 s {final - at_10:+.1f} MiB')
    print(f'bags under {work}')
    report.table(('idle', 'after 10 s', f'at the end ({args.duration:.0f} s)', 'peak', 'growth after 10 s'),
                 [(f'{idle:.1f} MiB', f'{at_10:.1f} MiB', f'{final:.1f} MiB', f'{peak:.1f} MiB',
                   f'**{final - at_10:+.1f} MiB**')],
                 "recorder_node's resident memory, fed the graph's message mix at 1 kHz from a played headless bag:")
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
