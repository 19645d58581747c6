"""Tests for wallbot_sim.domain (per-run ROS_DOMAIN_ID claims)."""
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import pytest

from wallbot_sim.domain import (MAX_DOMAIN_ID, MIN_DOMAIN_ID, RECENTLY_RELEASED, DomainUnavailable,
                                claim_chosen_domain_id, claim_domain_id, isolated_ros_env)


def test_concurrent_claims_get_distinct_ids(tmp_path):
    # Same starting point for every claim: each must still skip held ids.
    claims = [claim_domain_id(tmp_path, rng=random.Random(0)) for _ in range(10)]
    try:
        ids = [c.domain_id for c in claims]
        assert len(set(ids)) == len(ids)
        assert all(MIN_DOMAIN_ID <= i <= MAX_DOMAIN_ID for i in ids)
    finally:
        for c in claims:
            c.release()


def test_claim_held_by_other_process_is_skipped(tmp_path):
    code = ('import sys, random\n'
            'from wallbot_sim.domain import claim_domain_id\n'
            'c = claim_domain_id(sys.argv[1], rng=random.Random(0))\n'
            'print(c.domain_id, flush=True)\n'
            'sys.stdin.read()\n')
    repo = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=repo + os.pathsep + os.environ.get('PYTHONPATH', ''))
    child = subprocess.Popen([sys.executable, '-c', code, str(tmp_path)], env=env,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        child_id = int(child.stdout.readline())
        with claim_domain_id(tmp_path, rng=random.Random(0)) as mine:
            assert mine.domain_id != child_id
    finally:
        child.stdin.close()
        child.wait(timeout=10)
    # the child's lock died with it: its id is free again
    with claim_chosen_domain_id(child_id, tmp_path) as again:
        assert again.held


def test_release_frees_the_id(tmp_path):
    with claim_domain_id(tmp_path, rng=random.Random(3)) as claim:
        first = claim.domain_id
        assert claim.held
    assert not claim.held
    claim.release()  # idempotent
    with claim_chosen_domain_id(first, tmp_path) as second:
        assert second.domain_id == first


def test_an_id_just_released_is_chosen_last(tmp_path):
    """A process killed in a domain stays in DDS discovery for its lease: the next claim takes another id while
    there is one, and the recent one rather than none."""
    with claim_domain_id(tmp_path, rng=random.Random(3)) as claim:
        recent = claim.domain_id
    with claim_domain_id(tmp_path, rng=random.Random(3)) as again:
        assert again.domain_id != recent
    others = [claim_chosen_domain_id(i, tmp_path) for i in range(MIN_DOMAIN_ID, MAX_DOMAIN_ID + 1) if i != recent]
    try:
        with claim_domain_id(tmp_path, rng=random.Random(3)) as last:
            assert last.domain_id == recent
    finally:
        for other in others:
            other.release()
    stale = time.time() - RECENTLY_RELEASED - 1.0
    for path in tmp_path.glob('*.lock'):
        os.utime(path, (stale, stale))
    with claim_domain_id(tmp_path, rng=random.Random(3)) as after_the_lease:
        assert after_the_lease.domain_id == recent


def test_all_ids_taken_raises(tmp_path):
    claims = [claim_domain_id(tmp_path) for _ in range(MAX_DOMAIN_ID - MIN_DOMAIN_ID + 1)]
    try:
        assert len({c.domain_id for c in claims}) == len(claims)
        with pytest.raises(RuntimeError):
            claim_domain_id(tmp_path)
    finally:
        for c in claims:
            c.release()


def test_isolated_env_sets_both_variables():
    env = isolated_ros_env(42, base={'PATH': '/bin', 'ROS_DOMAIN_ID': '7'})
    assert env == {'PATH': '/bin', 'ROS_DOMAIN_ID': '42',
                   'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    full = isolated_ros_env(5)
    assert full['ROS_DOMAIN_ID'] == '5' and full['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert full['PATH'] == os.environ['PATH']
    with pytest.raises(ValueError):
        isolated_ros_env(0)


def test_each_test_exports_a_domain_of_its_own(ros_domain, session_domain):
    assert ros_domain.held and session_domain.held
    assert ros_domain.domain_id != session_domain.domain_id
    assert os.environ['ROS_DOMAIN_ID'] == str(ros_domain.domain_id)
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'


def test_process_runner_inherits_env_and_kills(process_runner, ros_domain):
    proc = process_runner.start(
        [sys.executable, '-c',
         'import os, time; print(os.environ["ROS_DOMAIN_ID"], flush=True); time.sleep(60)'],
        name='sleeper')
    deadline = time.monotonic() + 10
    while not process_runner.output('sleeper').strip() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert process_runner.output('sleeper').strip() == str(ros_domain.domain_id)
    assert process_runner.stop(proc) is not None
    assert proc.poll() is not None


def test_process_runner_sigkills_a_child_ignoring_sigterm(process_runner):
    process_runner.stop_timeout = 0.5
    proc = process_runner.start(
        [sys.executable, '-c',
         'import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); '
         'print("ready", flush=True); time.sleep(60)'],
        name='stubborn')
    deadline = time.monotonic() + 10
    while 'ready' not in process_runner.output('stubborn') and time.monotonic() < deadline:
        time.sleep(0.05)
    assert process_runner.stop(proc) == -9


def test_a_chosen_id_is_claimed_unless_held_or_out_of_range(tmp_path):
    with claim_chosen_domain_id(17, tmp_path) as chosen:
        assert chosen.domain_id == 17 and chosen.held
        with pytest.raises(DomainUnavailable, match=r'ROS_DOMAIN_ID 17 is in use by another run .*17\.lock'):
            claim_chosen_domain_id(17, tmp_path)
        # an automatic claim passes it by
        claims = [claim_domain_id(tmp_path) for _ in range(MAX_DOMAIN_ID - MIN_DOMAIN_ID)]
        try:
            assert 17 not in {c.domain_id for c in claims}
        finally:
            for c in claims:
                c.release()
    with claim_chosen_domain_id(17, tmp_path) as again:  # released: free again
        assert again.domain_id == 17
    for outside in (0, MAX_DOMAIN_ID + 1, -1):
        with pytest.raises(DomainUnavailable, match=f'must be in 1..101, got {outside}'):
            claim_chosen_domain_id(outside, tmp_path)


def test_export_line_sets_exactly_the_isolating_variables(tmp_path):
    with claim_chosen_domain_id(42, tmp_path) as claim:
        line = claim.export_line()
    assert line == 'export ROS_DOMAIN_ID=42 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST'
    shown = subprocess.run(['bash', '-c', f'{line}; env'], capture_output=True, text=True, env={'PATH': '/usr/bin:/bin'},
                           check=True).stdout.splitlines()
    assert {k: v for k, v in (entry.split('=', 1) for entry in shown) if k.startswith('ROS_')} == \
        isolated_ros_env(42, {})
