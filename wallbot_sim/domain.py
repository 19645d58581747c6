"""DDS isolation: give each concurrent run on this machine its own ROS_DOMAIN_ID.

A run claims a domain id by holding an exclusive ``fcntl.flock`` on
``<lock_dir>/<id>.lock``; the kernel drops the lock when the holder releases it
or dies, so stale claims never block. Pure stdlib (no ROS import).

    with claim_domain_id() as claim:
        env = isolated_ros_env(claim.domain_id)
        subprocess.run(cmd, env=env)

``claim_chosen_domain_id(n)`` claims one given id, refusing it when another claim holds it.
Domain 0 is never claimed: it is the domain of every ROS process nobody configured.

An id released less than ``RECENTLY_RELEASED`` seconds ago is chosen last: a process killed in it (SIGKILL, no
goodbye on DDS) stays in its peers' discovery until its lease runs out, and a run that claimed the id at once
would find that ghost (a controller that never answers, a recorder that never writes).
"""
from __future__ import annotations

import fcntl
import os
import random
import tempfile
import time
from pathlib import Path
from typing import IO, Mapping

MIN_DOMAIN_ID = 1
MAX_DOMAIN_ID = 101  # inclusive; ids above 101 collide with ephemeral ports on Linux
DEFAULT_LOCK_DIR = Path(tempfile.gettempdir()) / 'wallbot_sim_domains'
RECENTLY_RELEASED = 20.0
"""Seconds after its release during which an id is chosen only if no other is free: Fast DDS's default participant
lease duration, for which a participant that died without leaving stays discovered."""


class DomainUnavailable(RuntimeError):
    """A chosen ROS_DOMAIN_ID that cannot be claimed: outside the range, or held by another claim."""


class DomainClaim:
    """An exclusively held ROS_DOMAIN_ID; release() (or leaving ``with``) frees it."""

    def __init__(self, domain_id: int, lock_file: IO[str], lock_path: Path) -> None:
        self.domain_id = domain_id
        self.lock_path = lock_path
        self._lock_file: IO[str] | None = lock_file

    @property
    def held(self) -> bool:
        """True until release() is called."""
        return self._lock_file is not None

    def release(self) -> None:
        """Drop the lock so another run may claim this id. Idempotent."""
        if self._lock_file is None:
            return
        try:
            os.utime(self._lock_file.fileno())  # the release time, which claims read (RECENTLY_RELEASED)
            fcntl.flock(self._lock_file, fcntl.LOCK_UN)
        finally:
            self._lock_file.close()
            self._lock_file = None

    def env(self, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """Shortcut for ``isolated_ros_env(self.domain_id, base)``."""
        return isolated_ros_env(self.domain_id, base)

    def export_line(self) -> str:
        """The shell command that puts another terminal in this domain, e.g.
        ``export ROS_DOMAIN_ID=7 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``."""
        return 'export ' + ' '.join(f'{key}={value}' for key, value in self.env({}).items())

    def __enter__(self) -> 'DomainClaim':
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __del__(self) -> None:
        try:
            self.release()
        except Exception:
            pass

    def __repr__(self) -> str:
        return f'DomainClaim(domain_id={self.domain_id}, held={self.held})'


def claim_domain_id(lock_dir: Path | str | None = None,
                    rng: random.Random | None = None) -> DomainClaim:
    """Claim a ROS_DOMAIN_ID in 1..101 that no other live claim on this machine holds.

    Ids are tried in order starting from a random one, so concurrent runs spread
    out, those released within RECENTLY_RELEASED seconds last. Raises RuntimeError if every id is taken.
    """
    lock_dir = _lock_dir(lock_dir)
    ids = list(range(MIN_DOMAIN_ID, MAX_DOMAIN_ID + 1))
    start = (rng or random.SystemRandom()).randrange(len(ids))
    ids = ids[start:] + ids[:start]
    now = time.time()
    for domain_id in sorted(ids, key=lambda domain_id: _released_recently(lock_dir, domain_id, now)):
        claim = _try_claim(lock_dir, domain_id)
        if claim is not None:
            return claim
    raise RuntimeError(f'no free ROS_DOMAIN_ID in {MIN_DOMAIN_ID}..{MAX_DOMAIN_ID} '
                       f'(all locks in {lock_dir} are held)')


def claim_chosen_domain_id(domain_id: int, lock_dir: Path | str | None = None) -> DomainClaim:
    """Claim ``domain_id`` itself; DomainUnavailable (one line) if it is outside 1..101 or another
    claim on this machine holds it. A ROS process that claimed nothing is not seen."""
    if not MIN_DOMAIN_ID <= domain_id <= MAX_DOMAIN_ID:
        raise DomainUnavailable(f'ROS_DOMAIN_ID must be in {MIN_DOMAIN_ID}..{MAX_DOMAIN_ID}, got {domain_id}')
    lock_dir = _lock_dir(lock_dir)
    claim = _try_claim(lock_dir, domain_id)
    if claim is None:
        raise DomainUnavailable(f'ROS_DOMAIN_ID {domain_id} is in use by another run on this machine '
                                f'(its lock {lock_dir / f"{domain_id}.lock"} is held)')
    return claim


def _lock_dir(lock_dir: Path | str | None) -> Path:
    """The directory of the lock files, created and shared between users."""
    lock_dir = Path(lock_dir) if lock_dir is not None else DEFAULT_LOCK_DIR
    lock_dir.mkdir(parents=True, exist_ok=True)
    try:
        os.chmod(lock_dir, 0o1777)  # shared between users, like /tmp
    except OSError:
        pass
    return lock_dir


def _released_recently(lock_dir: Path, domain_id: int, now: float) -> bool:
    """Whether ``domain_id``'s lock file was last written (claimed or released) within RECENTLY_RELEASED of
    ``now``."""
    try:
        return now - (lock_dir / f'{domain_id}.lock').stat().st_mtime < RECENTLY_RELEASED
    except OSError:
        return False


def _try_claim(lock_dir: Path, domain_id: int) -> DomainClaim | None:
    """The claim of ``domain_id`` if its lock is free, else None."""
    path = lock_dir / f'{domain_id}.lock'
    try:
        f = open(path, 'a+')
    except OSError:
        return None  # e.g. owned by another user without write permission
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.close()
        return None
    f.seek(0)
    f.truncate()
    f.write(f'{os.getpid()}\n')
    f.flush()
    return DomainClaim(domain_id, f, path)


def isolated_ros_env(domain_id: int, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Copy of ``base`` (default os.environ) with ROS_DOMAIN_ID set and discovery limited to localhost."""
    if not MIN_DOMAIN_ID <= int(domain_id) <= MAX_DOMAIN_ID:
        raise ValueError(f'domain id {domain_id} outside {MIN_DOMAIN_ID}..{MAX_DOMAIN_ID}')
    env = dict(os.environ if base is None else base)
    env['ROS_DOMAIN_ID'] = str(int(domain_id))
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return env
