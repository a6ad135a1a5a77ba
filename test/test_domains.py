"""The test sessions' ROS domain ids (test/support/domains.py): two sessions on one host never
hold the same id (issue 38 item 8: ``pid % 100 + 1`` let a fresh clone's session meet another's).
Real processes, real lock files."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from test.support import domains

REPO = Path(__file__).resolve().parents[1]


def _claim_in_another_process(start: int) -> int:
    """The id another process claims when it starts from ``start`` (as a session whose pid
    gives that start would)."""
    env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}
    code = f'from test.support import domains; print(domains.claim(start={start}))'
    out = subprocess.run([sys.executable, '-c', code], cwd=REPO, env=env, capture_output=True,
                         text=True, timeout=60, check=True)
    return int(out.stdout)


def test_a_second_session_starting_from_this_ones_domain_id_gets_another():
    ours = int(os.environ['ROS_DOMAIN_ID'])
    assert ours == domains.session_domain_id()
    mine = {ours} | {domains.next_domain_id() for _ in range(domains.POOL + 2)}
    assert len(mine) == domains.POOL + 1          # the session's id and a pool of its own
    for start in sorted(mine):
        other = _claim_in_another_process(start)
        assert other not in mine and domains.FIRST <= other <= domains.LAST
    # the other process has ended: its lock went with it, so its id is free again
    assert _claim_in_another_process(other) == other


def test_in_process_ids_differ_from_the_session_and_from_the_previous_one():
    ids = [domains.next_domain_id() for _ in range(3 * domains.POOL)]
    assert int(os.environ['ROS_DOMAIN_ID']) not in ids
    assert all(a != b for a, b in zip(ids, ids[1:]))
