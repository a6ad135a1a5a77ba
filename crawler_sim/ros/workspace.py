"""Where the colcon-installed package is, as ``ros2 run`` finds it (the ament index), and the
environment its executables need: for the demo, the benchmarks and the tests that start the
nodes as processes."""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ['executable', 'share', 'workspace_env']


def executable(name: str) -> Path:
    """What ``ros2 run crawler_sim <name>`` runs: <prefix>/lib/crawler_sim/<name>; SystemExit
    with the remedy when the package is not installed."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    try:
        prefix = Path(get_package_prefix('crawler_sim'))
    except PackageNotFoundError:
        raise SystemExit('crawler_sim is not in the ament index (AMENT_PREFIX_PATH): run '
                         '`make build` or `colcon build` and source install/setup.bash') from None
    path = prefix / 'lib' / 'crawler_sim' / name
    if not os.access(path, os.X_OK):
        raise SystemExit(f'{path} is missing: rebuild with colcon')
    return path


def workspace_env(env: dict[str, str]) -> dict[str, str]:
    """``env`` plus the PYTHONPATH entries ``source install/setup.bash`` would add for this
    package (its colcon ``.dsv`` hooks; a --symlink-install also points into build/)."""
    from ament_index_python.packages import get_package_prefix
    prefix = Path(get_package_prefix('crawler_sim'))
    entries: list[str] = []
    todo = [prefix / 'share' / 'crawler_sim' / 'package.dsv']
    while todo:
        dsv = todo.pop(0)
        if not dsv.is_file():
            continue
        for line in dsv.read_text().splitlines():
            kind, _, rest = line.partition(';')
            if kind == 'source' and rest.endswith('.dsv'):
                todo.append((prefix / rest).resolve())
            elif kind.startswith('prepend') and rest.startswith('PYTHONPATH;'):
                value = rest.split(';', 1)[1]
                path = value if os.path.isabs(value) else str(prefix / value)
                if path not in entries:
                    entries.append(path)
    old = [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p]
    out = dict(env)
    out['PYTHONPATH'] = os.pathsep.join(entries + [p for p in old if p not in entries])
    return out


def share() -> Path:
    """The package's share/ directory (config files, launch files)."""
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory('crawler_sim'))
