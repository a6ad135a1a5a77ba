"""One topic table (issue 27: topic names and types lived in bag/topics.py, in
``messages.OUTPUT_TYPES`` and as literals in the node): every name and type of a crawler_sim
topic is spelt in ``crawler_sim.bag.topics`` only, and the node records what the table says."""
from __future__ import annotations

import ast
from pathlib import Path

from crawler_sim.bag import topics as T

PACKAGE = Path(__file__).resolve().parents[2] / 'crawler_sim'


def spelt_elsewhere() -> list[str]:
    """``file:line 'literal'`` of every string constant outside topics.py that is a type of
    the table, or a topic name that is private (``~/x``), global (``/x``) or namespaced."""
    watched = set()
    for t in T.ALL_TOPICS:
        watched |= {t.type, t.name()}
        watched |= {name for name in (t.declared, t.suffix) if '/' in name}
    found = []
    for path in sorted(PACKAGE.rglob('*.py')):
        if path.name == 'topics.py' and path.parent.name == 'bag':
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Constant) and node.value in watched:
                found.append(f'{path.relative_to(PACKAGE)}:{node.lineno} {node.value!r}')
    return found


def test_topic_names_and_types_are_spelt_in_the_table_only():
    assert spelt_elsewhere() == []


def test_the_checker_would_see_a_literal(tmp_path, monkeypatch):
    (tmp_path / 'node.py').write_text("pub = create_publisher(Clock, '/clock', 10)\n")
    monkeypatch.setitem(globals(), 'PACKAGE', tmp_path)
    assert spelt_elsewhere() == ["node.py:1 '/clock'"]


def test_names_resolve_as_ros_resolves_them():
    assert T.BODY_STATES.name('/r1') == '/r1/body_states'
    assert T.BODY_STATES.name('') == '/body_states'
    assert T.CLOCK.name('/r1') == '/clock' and T.DIAGNOSTICS.name('r2/') == '/diagnostics'
    # a private topic of the default node name, matched by its leaf
    assert T.APPLIED_COMMAND.name('/r1') == '/r1/crawler_sim/applied_command'
    assert T.APPLIED_COMMAND.node_name == '~/applied_command'
    assert T.PLANT_INPUTS.leaf == 'plant_inputs'
    assert len({t.name() for t in T.ALL_TOPICS}) == len(T.ALL_TOPICS)
