"""docs/solvers.md is a reference that says what the code does (issue 43): its Capabilities
table is the registry of ``core/solvers/base.py`` for every registered method, and every option
it lists is a keyword argument of ``simulate`` or ``Stepper``."""
from __future__ import annotations

from dataclasses import fields
import inspect
from pathlib import Path
import re

from crawler_sim.core.solvers.base import Capabilities, capabilities, method_names
from crawler_sim.core.stepper import Stepper, simulate

DOC = Path(__file__).resolve().parents[2] / 'docs' / 'solvers.md'


def _section(title: str) -> str:
    text = DOC.read_text(encoding='utf-8')
    return text.split(f'## {title}\n', 1)[1].split('\n## ', 1)[0]


def _table(title: str) -> list[list[str]]:
    rows = [line for line in _section(title).splitlines() if line.startswith('|')]
    return [[c.strip() for c in row.strip('|').split('|')] for row in rows if '---' not in row]


def expected_table() -> str:
    names = [f.name for f in fields(Capabilities)]
    lines = ['| method | ' + ' | '.join(names) + ' |', '| --- |' + ' --- |' * len(names)]
    for m in method_names():
        cap = capabilities(m)
        lines.append(f'| {m} | ' + ' | '.join('yes' if getattr(cap, n) else 'no'
                                             for n in names) + ' |')
    return '\n'.join(lines)


def test_the_capabilities_table_is_the_registry():
    header, *rows = _table('Capabilities')
    # on a mismatch the message is the table to paste into docs/solvers.md
    assert header[1:] == [f.name for f in fields(Capabilities)], expected_table()
    assert [r[0] for r in rows] == list(method_names()), expected_table()
    for row in rows:
        cap = capabilities(row[0])
        documented = dict(zip(header[1:], row[1:]))
        actual = {n: 'yes' if getattr(cap, n) else 'no' for n in header[1:]}
        assert documented == actual, expected_table()


def test_every_documented_option_is_a_keyword_of_simulate_or_stepper():
    known = (set(inspect.signature(simulate).parameters)
             | set(inspect.signature(Stepper).parameters))
    header, *rows = _table('Options')
    assert header[0] == 'option'
    documented = {name for row in rows for name in re.findall(r'`(\w+)`', row[0])}
    assert len(documented) >= 10
    assert documented <= known, documented - known
