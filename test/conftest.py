"""Shared pytest fixtures for wallbot_sim.

* ``ros_domain`` (session, autouse): claims a private ROS_DOMAIN_ID for the
  whole session and exports it (plus ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)
  in os.environ so every child process and in-process rclpy context is isolated
  from other concurrent test runs on this machine.
* ``process_runner`` (function): starts child processes with that environment,
  logs their output to files in tmp_path and always kills them at teardown.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Iterator, Mapping

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
if str(REPO_ROOT) not in sys.path:  # allow running the tests without installing
    sys.path.insert(0, str(REPO_ROOT))

from wallbot_sim.domain import DomainClaim, claim_domain_id, isolated_ros_env  # noqa: E402

_ENV_KEYS = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')


@pytest.fixture(scope='session', autouse=True)
def ros_domain() -> Iterator[DomainClaim]:
    """Claim a ROS_DOMAIN_ID for the test session and export it in os.environ."""
    saved = {k: os.environ.get(k) for k in _ENV_KEYS}
    claim = claim_domain_id()
    os.environ.update({k: v for k, v in isolated_ros_env(claim.domain_id).items()
                       if k in _ENV_KEYS})
    try:
        yield claim
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        claim.release()


class ProcessRunner:
    """Start child processes that are always terminated at fixture teardown."""

    def __init__(self, log_dir: Path, env: Mapping[str, str], stop_timeout: float = 5.0) -> None:
        self.log_dir = Path(log_dir)
        self.env = dict(env)
        self.stop_timeout = stop_timeout
        self._procs: list[tuple[str, subprocess.Popen, object]] = []

    def start(self, cmd: list[str], name: str, cwd: str | os.PathLike | None = None,
              env: Mapping[str, str] | None = None) -> subprocess.Popen:
        """Start ``cmd``; stdout+stderr go to ``<log_dir>/<name>.log`` (see log_path)."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log = open(self.log_path(name), 'wb')
        full_env = dict(self.env)
        if env:
            full_env.update(env)
        full_env.setdefault('PYTHONUNBUFFERED', '1')
        try:
            proc = subprocess.Popen([str(c) for c in cmd], stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, cwd=cwd, env=full_env,
                                    start_new_session=True)
        except BaseException:
            log.close()
            raise
        self._procs.append((name, proc, log))
        return proc

    def log_path(self, name: str) -> Path:
        """Log file of the process started as ``name``."""
        return self.log_dir / f'{name}.log'

    def output(self, name: str) -> str:
        """Everything the process ``name`` has written so far."""
        return self.log_path(name).read_text(errors='replace')

    def stop(self, proc: subprocess.Popen) -> int | None:
        """SIGTERM ``proc`` (by pid), SIGKILL after stop_timeout; return its exit code.

        Each child runs in its own session (process group id == its pid), so
        descendants it leaves behind (e.g. nodes spawned by ``wallbot-sim run``)
        are SIGKILLed through that group at the end.
        """
        if proc.poll() is None:
            self._signal(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=self.stop_timeout)
            except subprocess.TimeoutExpired:
                self._signal(proc.pid, signal.SIGKILL)
                try:
                    proc.wait(timeout=self.stop_timeout)
                except subprocess.TimeoutExpired:
                    pass
        try:  # leftovers of this child's own process group only
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        return proc.returncode

    @staticmethod
    def _signal(pid: int, sig: int) -> None:
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            pass

    def stop_all(self) -> None:
        """Stop every started process (newest first) and close the logs."""
        for _name, proc, log in reversed(self._procs):
            try:
                self.stop(proc)
            finally:
                log.close()
        self._procs.clear()


@pytest.fixture
def process_runner(tmp_path: Path, ros_domain: DomainClaim) -> Iterator[ProcessRunner]:
    """A ProcessRunner using the session's isolated ROS env; logs in ``tmp_path/logs``."""
    runner = ProcessRunner(tmp_path / 'logs', isolated_ros_env(ros_domain.domain_id))
    try:
        yield runner
    finally:
        runner.stop_all()
