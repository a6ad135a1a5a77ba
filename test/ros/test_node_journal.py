"""The plant journal's format has one owner, ``crawler_sim.bag.journal`` (issue 42): sim_node
writes its entries with it and the bag's reader checks them with its table."""
from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from crawler_sim.bag import inputs, journal
from crawler_sim.core.plant.replay import KINDS


def test_the_reader_checks_with_the_writers_table():
    assert inputs._FIELDS is journal.FIELDS


@pytest.mark.parametrize('kind', KINDS)
def test_every_kind_the_node_writes_is_read_back_as_written(kind):
    payload = {'command': [0.1, 0.12], 'trajectory': 3,
               'configure': SimpleNamespace(values={'masses': (1.0, 2.0), 'mu': 0.3}),
               'reset': SimpleNamespace(values={'masses': [1.0, 2.0]})}.get(kind)
    text = journal.encode(7, kind, payload)
    entry = inputs._entry('bag', 'message #0', _string_cdr(text))
    assert entry == json.loads(text) and entry['seq'] == 7 and entry['kind'] == kind
    if kind in journal.FIELDS:
        field = journal.FIELDS[kind][0]
        assert field in entry
    assert set(entry) <= {'seq', 'kind', *(f for f, _, _ in journal.FIELDS.values())}


def test_a_trajectory_not_recorded_is_named_so():
    entry = json.loads(journal.encode(1, 'trajectory', journal.NOT_RECORDED))
    assert entry['points'] == -1


def _string_cdr(text: str) -> bytes:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String
    return serialize_message(String(data=text))
