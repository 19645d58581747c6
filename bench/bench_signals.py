"""How long each process takes to stop after SIGINT / SIGTERM (a measurement).

Every process is started as a script starts a background job (``bash -c 'CMD & wait $!'``, so it
begins with SIGINT ignored), in a domain of its own. Per round and signal: the closed-loop graph
of ``wallbot-sim run --controller`` records for a second, then the recorder and each other node
get the signal one after another, and the time from ``kill`` to the job's exit is taken; then a
``wallbot-sim run`` gets SIGINT once it has simulated a second. For the recorder it also prints
how long after the kill it handled the signal (``wallbot.recorder.stop_time_ns`` in the bag) and
how far the bag's last receive time lies before that, and when it had written the last message
and began to close the bag (its log line).

    python bench/bench_signals.py [--rounds 3] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from report import Report, add_write_docs_option
from wallbot_sim.bag.reader import messages
from wallbot_sim.config import load_scenario
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.graph_description import describe_graph

NODES = ('recorder', 'controller', 'trajectory', 'constraint_config', 'dynamics')


def wait_for(predicate, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError
        time.sleep(0.02)


class Job:
    """``CMD &`` in a non-interactive bash, its output in ``log``."""

    def __init__(self, cmd: list[str], log: Path, env: dict[str, str]) -> None:
        pid_file = log.with_suffix('.pid')
        self.log = log
        with open(log, 'wb') as out:
            self.shell = subprocess.Popen(['bash', '-c', f'{shlex.join(map(str, cmd))} & echo $! > {pid_file}; wait $!'],
                                          stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        wait_for(lambda: pid_file.is_file() and pid_file.read_text().endswith('\n'), 30)
        self.pid = int(pid_file.read_text())

    def stop(self, sig: int, timeout: float = 30.0) -> tuple[float, int, int]:
        """(seconds to exit, exit status, time.time_ns() at the kill)."""
        sent_ns, sent = time.time_ns(), time.perf_counter()
        os.kill(self.pid, sig)
        status = self.shell.wait(timeout)
        return time.perf_counter() - sent, status, sent_ns

    def kill(self) -> None:
        try:
            os.killpg(self.shell.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def graph_round(sig: int, work: Path, env: dict[str, str]) -> dict[str, float]:
    bag = work / 'bag'
    specs = describe_graph(load_scenario('circle'), DRIVEN, duration=600.0, real_time_factor=1.0, bag=bag,
                           controller_mass_scale=1.0)
    jobs = {spec.name: Job(spec.command(), work / f'{spec.name}.log', env) for spec in specs}
    try:
        wait_for(lambda: sum(f.stat().st_size for f in bag.glob('*.mcap')) > 200_000, 90)
        times = {}
        for name in NODES:
            times[name], status, sent_ns = jobs[name].stop(sig)
            if status != 0:
                raise RuntimeError(f'{name} exited {status}: see {jobs[name].log}')
            if name == 'recorder':
                custom = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']['custom_data']
                stop_ns = int(custom['wallbot.recorder.stop_time_ns'])
                last_ns = max(raw.timestamp for raw in messages(bag))
                logged = re.search(r'\[(\d+\.\d+)\] \[wallbot\.recorder\]: stopped by', jobs[name].log.read_text())
                times['recorder: signal handled after'] = (stop_ns - sent_ns) * 1e-9
                times['recorder: last receive before that'] = (stop_ns - last_ns) * 1e-9
                times['recorder: bag complete, closing after'] = float(logged.group(1)) - sent_ns * 1e-9
        return times
    finally:
        for job in jobs.values():
            job.kill()


def run_round(work: Path, env: dict[str, str]) -> float:
    job = Job([sys.executable, '-m', 'wallbot_sim.cli.main', 'run', 'circle', '--duration', '600', '--no-plots',
               '--out', work / 'run'], work / 'run.log', env)
    try:
        def simulated() -> float:
            shown = re.findall(r't = +([0-9.]+) /', job.log.read_text(errors='replace'))
            return float(shown[-1]) if shown else 0.0
        wait_for(lambda: simulated() > 1.0, 120)
        seconds, status, _ = job.stop(signal.SIGINT)
        if status != 130:
            raise RuntimeError(f'run exited {status}: see {job.log}')
        return seconds
    finally:
        job.kill()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rounds', type=int, default=3)
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('signals')
    results: dict[tuple[str, str], list[float]] = {}
    with claim_domain_id() as claim, tempfile.TemporaryDirectory() as tmp:
        env = claim.env()
        for number in range(args.rounds):
            for sig in (signal.SIGINT, signal.SIGTERM):
                work = Path(tmp) / f'{number}-{sig.name}'
                work.mkdir()
                for name, seconds in graph_round(sig, work, env).items():
                    results.setdefault((name, sig.name), []).append(seconds)
            work = Path(tmp) / f'{number}-run'
            work.mkdir()
            results.setdefault(('wallbot-sim run', 'SIGINT'), []).append(run_round(work, env))
    print(f'{"process":36s} {"signal":8s} {"min":>7s} {"median":>7s} {"max":>7s}  (s, {args.rounds} rounds)')
    for (name, sig), values in results.items():
        print(f'{name:36s} {sig:8s} {min(values):7.3f} {statistics.median(values):7.3f} {max(values):7.3f}')
    report.table(('process', 'signal', 'seconds from kill to exit: min / median / max'),
                 [(name, sig, f'{min(values):.2f} / {statistics.median(values):.2f} / {max(values):.2f}')
                  for (name, sig), values in results.items()], f'{args.rounds} rounds:')
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
