"""``crawler-sim``: the command line (simulate, replay, info, plot, recover; sweep, optimize and
export live in `sweep_commands`). The benchmarks are not user commands: they run from a source
checkout (``python -m benchmarks.solvers``, see benchmarks/).

Exit codes: 0 success; 1 the work failed (solver failure, unreadable or damaged bag, write
error, replay mismatch); 2 bad input (usage, missing file, invalid scene or YAML) or a refused
output (one of the command's inputs, inside an input bag folder, a directory, an existing bag:
`crawler_sim.bag.files`); 130 interrupted. Every error is one line on stderr,
``crawler-sim: error: ...`` (``--debug`` shows the traceback instead). Progress goes to
stderr, results to stdout.

Heavy modules (the bag, matplotlib) are imported inside the subcommands, so
``crawler-sim --help`` does not need ROS or matplotlib.

Module size: about 650 lines, over the ~400 guide: one argparse tree and one short function
per subcommand, each a thin wrapper over a library call; the sweep commands already live in
``sweep_commands.py``, and the next command group to grow should move out the same way.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Any, Callable, Sequence

PROG = 'crawler-sim'
METHODS = ('exact', 'implicit', 'penalty')   # crawler_sim.METHODS, without importing the core
RULES = ('incumbent', 'margin')     # core.friction.RULES, the same (test_cli_stiction checks)
EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
REPLAY_TOL = 1e-9      # default replay tolerance on positions [m] and velocities [m/s]
AS_NODE_MODES = ('preload', 'trajectory', 'command')    # how gait_node plays a gait


class UsageError(Exception):
    """Bad input from the user (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``crawler-sim: error: ... (see 'crawler-sim X --help')``."""

    def error(self, message: str) -> None:  # type: ignore[override]
        _say_error(f"{message} (see '{self.prog} --help')")
        raise SystemExit(EXIT_USAGE)


def _say_error(message: str) -> None:
    line = ' '.join(str(message).split())
    print(f'{PROG}: error: {line}', file=sys.stderr, flush=True)


def _info(message: str) -> None:
    print(f'{PROG}: {message}', file=sys.stderr, flush=True)


def _positive(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number > 0, got {text!r}') from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f'must be finite and > 0, got {text!r}')
    return x


def _int_at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``, else a message naming the range."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = None
        if n is None or n < low:
            raise argparse.ArgumentTypeError(f'must be an integer >= {low}, got {text!r}')
        return n
    return parse


_non_negative_int = _int_at_least(0)
_positive_int = _int_at_least(1)


def _existing(path: str, what: str = 'file') -> Path:
    """An input path that must exist (else a usage error, exit 2)."""
    p = Path(path)
    if not p.exists():
        raise UsageError(f'{path}: no such {what}')
    if what == 'file' and not p.is_file():
        raise UsageError(f'{path}: not a file')
    return p


class _Progress:
    """Shows that long work is alive: a line on stderr when it starts, then the elapsed wall
    time every ``every`` seconds (rewritten in place on a terminal)."""

    def __init__(self, label: str, every: float = 2.0) -> None:
        self.label = label
        self.tty = sys.stderr.isatty()
        self.every = 0.25 if self.tty else every
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True)
        self.start = 0.0
        self.elapsed = 0.0

    def _beat(self) -> None:
        while not self._stop.wait(self.every):
            dt = time.perf_counter() - self.start
            if self.tty:
                print(f'\r{PROG}: {self.label} ({dt:.1f} s)', end='', file=sys.stderr,
                      flush=True)
            else:
                _info(f'{self.label}: {dt:.0f} s elapsed')

    def __enter__(self) -> _Progress:
        if not self.tty:
            _info(self.label)
        self.start = time.perf_counter()
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join()
        self.elapsed = time.perf_counter() - self.start
        if self.tty:
            print('\r\033[K', end='', file=sys.stderr, flush=True)


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _print_table(rows: list[tuple[str, str]]) -> None:
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f'{key:<{width}}  {value}')


# ------------------------------------------------------------------------------- simulate

def _figures(scene: Any, tr: Any, wall: float) -> dict:
    """The run's figures as plain data (for the table and --json)."""
    from ..core.verify import verify

    report = verify(tr)
    t_end = float(tr.t[-1] - tr.t[0])
    period = scene.gait.period
    steady = tr.mean_speed(period) if period and period <= t_end else None
    return {
        'scene': scene.name, 'method': tr.method, 't_end': t_end, 'bodies': scene.crawler.p,
        'gait': scene.gait_spec['type'], 'period': period, 'samples': len(tr),
        'displacement': tr.displacement, 'mean_speed': tr.mean_speed(),
        'mean_speed_last_period': steady,
        'stick_fraction': [float(s) for s in tr.stick_fraction], 'events': len(tr.events),
        'dissipated_energy': tr.dissipated_energy, 'actuator_work': tr.actuator_work,
        'positive_actuator_work': tr.positive_actuator_work,
        'cost_of_transport': _finite_or_none(tr.cost_of_transport),
        'verify_worst': report.worst, 'verify_contact_errors': report.contact,
        'verify_ok': report.ok(1e-9), 'wall_time': wall,
        'real_time_factor': t_end / wall if wall > 0 else None,
        # with stiction: the rule, and the instants where more than one continuation was
        # consistent and it chose (the solver's count; None for a method that does not count)
        **({'stiction_rule': scene.run.stiction_rule,
            'stiction_choices': tr.info.get('choices')} if scene.crawler.has_stiction else {}),
    }


def _figure_rows(f: dict) -> list[tuple[str, str]]:
    period = f'{f["period"]:g} s' if f['period'] else 'not periodic'
    speed = f'{f["mean_speed"]:.6g} m/s over the run'
    if f['mean_speed_last_period'] is not None:
        speed += f', {f["mean_speed_last_period"]:.6g} m/s over the last period'
    stick = ', '.join(f'body_{i} {s:.3f}' for i, s in enumerate(f['stick_fraction']))
    cot = 'inf (no net motion)' if f['cost_of_transport'] is None else (
        f'{f["cost_of_transport"]:.4g}')
    verdict = 'ok' if f['verify_ok'] else 'VIOLATED'
    rtf = f['real_time_factor']
    rows = [
        ('scene', f'{f["scene"]} ({f["bodies"]} bodies, {f["gait"]} gait, period {period})'),
        ('method', f'{f["method"]}, t_end {f["t_end"]:g} s, {f["samples"]} samples'),
        ('displacement', f'{f["displacement"]:.6g} m'),
        ('mean speed', speed),
        ('stick fraction', stick),
        ('events', str(f['events'])),
        ('dissipated energy', f'{f["dissipated_energy"]:.6g} J'),
        ('actuator work', f'{f["actuator_work"]:.6g} J (positive part '
                          f'{f["positive_actuator_work"]:.6g} J)'),
        ('cost of transport', cot),
        *([('stiction', f'rule {f["stiction_rule"]}, '
                        + ('choices not counted by this method' if f['stiction_choices'] is None
                           else f'{f["stiction_choices"]} instants where it chose'))]
          if 'stiction_rule' in f else []),
        ('verify', f'worst relative violation {f["verify_worst"]:.3g}, '
                   f'{f["verify_contact_errors"]} contact errors ({verdict} at 1e-9)'),
        ('wall time', f'{f["wall_time"]:.3f} s'
                      + (f' (real-time factor {rtf:.4g})' if rtf else '')),
    ]
    for key in ('bag', 'plot'):
        if key in f:
            rows.append((key, f[key]))
    return rows


def _record(out: Path, scene: Any, tr: Any, as_node: dict | None = None) -> None:
    """Write the run (states, contact events, the scene, and how it was driven when it ran as
    the node runs it) as a bag with the node's topics."""
    from ..bag import BagError, record_trajectory
    from ..core.scene import scene_to_dict

    sc = scene_to_dict(scene)
    if as_node:
        sc['as_node'] = dict(as_node)
    writer = record_trajectory(out, tr, scene=sc)
    if getattr(writer, 'error', None):
        raise BagError(f'{out}: {writer.error}')


def _as_node(scene: Any, as_node: dict) -> Any:
    """The scene's run as sim_node runs it when gait_node plays the scene's gait with
    ``as_node`` (``mode``: preload, trajectory or command; ``rate`` [Hz]): the node's actuator
    and tick grid (default parameters, at rest at ``as_node['initial_lengths']`` [m] when
    given, as sim_node at its ``initial_lengths``, else at the gait's first lengths), then the
    core."""
    import numpy as np

    from ..core.plant import PlantConfig
    from ..core.plant.streams import Stream, simulate_as_node

    r = scene.run
    start = as_node.get('initial_lengths') or np.atleast_1d(scene.gait.length(0.0))
    plant = PlantConfig.for_crawler(scene.crawler, start, method=r.method,
                                    initial_position=r.x0, stiction_rule=r.stiction_rule)
    mode = as_node['mode']
    stream = Stream('command' if mode == 'command' else 'trajectory', float(as_node['rate']),
                    preload=mode == 'preload', duration=r.t_end + 1.0 if mode == 'preload'
                    else 0.0)
    kw: dict[str, Any] = {'dt': r.dt} if r.dt else {}
    from ..core.solvers.base import capabilities

    if not capabilities(r.method).fixed_step:     # the event-driven method's options
        kw.update(tol=r.tol, max_step=r.max_step)
    return simulate_as_node(plant, scene.gait, stream, r.t_end, **kw)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from ..bag.files import reading

    source = _existing(args.scene)
    with reading(source):
        return _simulate(args, source)


def _simulate(args: argparse.Namespace, source: Path) -> int:
    from ..bag.files import check_new_folder
    from ..core.scene import load_scene

    scene = load_scene(source)
    penalty = args.penalty
    if args.method == 'penalty' and penalty is None and scene.run.penalty is None:
        from ..core.plant.config import PARAMETERS
        penalty = PARAMETERS['penalty'][0][0]          # sim_node's default regularisation
        _info(f'method penalty: n = {penalty:g} N s/m (sim_node\'s default; --penalty N)')
    scene = scene.with_run(method=args.method, t_end=args.t_end, dt=args.dt, penalty=penalty,
                           stiction_rule=args.stiction_rule)
    # the outputs are checked before a long run, not after it
    if args.out:
        check_new_folder(args.out)
    if args.plot:
        from ..bag.plot import figure_output
        if args.out and _inside(Path(args.plot), Path(args.out)):
            raise UsageError(f'--plot {args.plot}: lies inside the bag folder --out '
                             f'{args.out}; a bag holds its recording only')
        figure_output(args.plot)
    r = scene.run
    as_node = None
    if args.initial_lengths and not args.as_node:
        raise UsageError('--initial-lengths: only with --as-node (an offline run starts at '
                         'rest at the gait\'s first lengths)')
    if args.as_node:
        as_node = {'mode': args.as_node, 'rate': args.rate}
        if args.initial_lengths:
            links = scene.crawler.p - 1
            if len(args.initial_lengths) not in (1, links):
                raise UsageError(f'--initial-lengths: one length for every linkage or one '
                                 f'each ({links}), got {len(args.initial_lengths)}')
            as_node['initial_lengths'] = list(args.initial_lengths)
        if r.v0:
            raise UsageError(f'--as-node starts at rest as sim_node does, but scene.run.v0 = '
                             f'{r.v0} m/s')
    what = f' as sim_node runs it ({args.as_node} at {args.rate:g} Hz)' if as_node else ''
    with _Progress(f'simulating {scene.name}{what}: {r.t_end:g} s with method '
                   f'{r.method}') as prog:
        tr = _as_node(scene, as_node) if as_node else scene.simulate()
    figures = _figures(scene, tr, prog.elapsed)
    if as_node:
        figures['as_node'] = f'{args.as_node} at {args.rate:g} Hz'
    if args.out:
        with _Progress(f'recording to {args.out}'):
            _record(Path(args.out), scene, tr, as_node)
        figures['bag'] = str(args.out)
    if args.plot:
        from ..bag.plot import figure, save
        save(figure(tr, f'{scene.name} ({r.method}): p = {tr.x.shape[1]}, {len(tr.t)} states'),
             args.plot)
        figures['plot'] = str(args.plot)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        _print_table(_figure_rows(figures))
    return EXIT_OK


# ------------------------------------------------------------------------------- bench, stress

# ------------------------------------------------------------------------------- replay

def _replay_node(run: Any, method: str | None) -> tuple[Any, Any, str]:
    """Re-run a sim_node bag through the plant's engine (``crawler_sim.core.plant.replay``):
    the recorded inputs (commands, trajectories, parameter changes, resets) at the ticks they
    took effect, so the arithmetic is the node's. Returns the states (x, v) at the recorded
    times and the inputs replayed, by kind."""
    from ..bag.inputs import load_inputs
    from ..core.plant.replay import replay

    recorded = load_inputs(run.path, run.namespace)
    if not recorded.journaled:
        _info('note: the bag has no plant_inputs journal (recorded before crawler_sim 0.4): '
              'replaying its linkage_cmd and linkage_trajectory messages only (parameter '
              'changes and resets are not repeated)')
    until = int(run.t_ns[-1]) if len(run.t_ns) else 0
    snaps = replay(run.scene, recorded.inputs, until, method=method,
                   from_ns=int(run.t_ns[0]) if len(run.t_ns) else None,
                   on_failure=lambda msg: _info(msg + '; continuing with method implicit, as '
                                                'the node does'))
    kinds: dict[str, int] = {}
    for item in recorded.inputs:
        kinds[item.kind] = kinds.get(item.kind, 0) + 1
    label = {'command': ('command', 'commands'), 'trajectory': ('trajectory', 'trajectories'),
             'configure': ('parameter change', 'parameter changes'),
             'reset': ('reset', 'resets'), 'pause': ('pause', 'pauses'),
             'resume': ('resume', 'resumes'), 'sync': ('cut off the grid', 'cuts off the grid')}
    what = ', '.join(f'{n} {label[kind][n != 1]}' for kind, n in kinds.items()) or 'no input'
    return (*snaps.at(run.t_ns, run.p), what)


def _replay_scene(run: Any, method: str | None) -> tuple[Any, Any, str]:
    """Re-simulate an offline run from its scene dict. When the recorded stamps are the default
    sample times of that run (rounded to ns), compare at those exact times; otherwise sample the
    re-simulation at the recorded times."""
    import numpy as np

    from ..core.scene import scene_from_dict
    from ..core.simtime import to_ns

    keys = ('name', 'description', 'crawler', 'gait', 'run', 'bench')   # not the recorder's
    scene = scene_from_dict({k: v for k, v in run.scene.items() if k in keys})
    scene = scene.with_run(method=method)
    t = np.asarray(run.t, dtype=float)
    as_node = _recorded_as_node(run)
    tr = _as_node(scene, as_node) if as_node else scene.simulate()
    # compare in the recorded ns base: every stamp a sample of the run (also a truncated bag)
    from ..bag.clock import rows_at_ns
    rows = rows_at_ns(tr.t, getattr(run, 't_ns', to_ns(t)))
    what = f'the scene {scene.name!r}' + (' as sim_node runs it' if as_node else '')
    if rows.size and np.all(rows >= 0):
        return tr.x[rows], tr.v[rows], what
    longer = scene.with_run(t_end=max(float(t[-1]), scene.run.t_end))
    if as_node:
        tr = _as_node(longer, as_node)
        p = tr.x.shape[1]
        return (np.column_stack([np.interp(t, tr.t, tr.x[:, i]) for i in range(p)]),
                np.column_stack([np.interp(t, tr.t, tr.v[:, i]) for i in range(p)]), what)
    tr = longer.simulate(t_eval=t)
    return tr.x, tr.v, what


def _recorded_as_node(run: Any) -> dict | None:
    """How an offline bag's run was driven (``simulate --as-node``: ``mode`` and ``rate``), or
    None; a malformed record is refused input (UsageError naming the bag and the field)."""
    as_node = run.scene.get('as_node')
    if as_node is None:
        return None
    where = f'{run.path}: scene.as_node'
    if not isinstance(as_node, dict):
        raise UsageError(f'{where}: must be a mapping with mode and rate, got '
                         f'{type(as_node).__name__}')
    mode, rate = as_node.get('mode'), as_node.get('rate')
    if not isinstance(mode, str) or mode not in AS_NODE_MODES:
        raise UsageError(f'{where}.mode: must be one of {", ".join(AS_NODE_MODES)}, got '
                         f'{mode!r}')
    if (isinstance(rate, bool) or not isinstance(rate, (int, float))
            or not (math.isfinite(rate) and rate > 0)):
        raise UsageError(f'{where}.rate: must be a finite number > 0 [Hz], got {rate!r}')
    start = as_node.get('initial_lengths')
    if start is None:
        return {'mode': mode, 'rate': float(rate)}
    if not (isinstance(start, list) and start and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            and x > 0 for x in start)):
        raise UsageError(f'{where}.initial_lengths: must be a list of finite numbers > 0 [m], '
                         f'got {start!r}')
    return {'mode': mode, 'rate': float(rate), 'initial_lengths': [float(x) for x in start]}


def _replay(run: Any, method: str | None, tol: float) -> dict:
    """Re-simulate a recorded run with the core and compare with the recorded states.

    Node bags (scene = the node's parameters) replay the recorded plant inputs tick by tick
    through the node's engine; offline bags (scene = a scene dict) re-run the scene.
    """
    import numpy as np

    sc = run.scene if isinstance(run.scene, dict) else {}
    node = 'integration_rate' in sc
    if not node and 'gait' not in sc:
        raise UsageError(f'{run.path}: the bag holds no scene (neither node parameters nor a '
                         'scene dict); it cannot be replayed')
    x, v, inputs = (_replay_node if node else _replay_scene)(run, method)
    rx, rv = np.asarray(run.x, dtype=float), np.asarray(run.v, dtype=float)
    if rx.shape != x.shape:
        raise ValueError(f'recorded states have shape {rx.shape}, the replay {x.shape}')
    # NaN in both (a body that did not exist then) is agreement; NaN in one is not
    dx = np.where(np.isnan(x) & np.isnan(rx), 0.0, np.abs(x - rx))
    dv = np.where(np.isnan(v) & np.isnan(rv), 0.0, np.abs(v - rv))
    bad_x, bad_v = np.nan_to_num(dx, nan=np.inf), np.nan_to_num(dv, nan=np.inf)
    ix = np.unravel_index(int(np.argmax(bad_x)), dx.shape) if dx.size else (0, 0)
    iv = np.unravel_index(int(np.argmax(bad_v)), dv.shape) if dv.size else (0, 0)
    max_dx = float(bad_x[ix]) if dx.size else 0.0
    max_dv = float(bad_v[iv]) if dv.size else 0.0
    return {'kind': 'node' if node else 'offline', 'method': method or sc.get('method') or
            sc.get('run', {}).get('method', 'exact'), 'samples': int(rx.shape[0]),
            'inputs': inputs,
            'max_position_error': max_dx, 'at_position': (float(run.t[ix[0]]), int(ix[1])),
            'max_velocity_error': max_dv, 'at_velocity': (float(run.t[iv[0]]), int(iv[1])),
            'tolerance': tol, 'match': max_dx <= tol and max_dv <= tol}


def _cmd_replay(args: argparse.Namespace) -> int:
    path = _existing(args.bag, 'bag')
    from ..bag import load

    run = load(path)
    with _Progress(f'replaying {args.bag}'):
        res = _replay(run, args.method, args.tol)
    t_x, body_x = res['at_position']
    t_v, body_v = res['at_velocity']
    _print_table([
        ('bag', f'{args.bag} ({res["kind"]} run, {res["samples"]} samples, '
                f'{res["inputs"]})'),
        ('method', res['method']),
        ('max |dx|', f'{res["max_position_error"]:.3g} m (body_{body_x} at t = {t_x:.9g} s)'),
        ('max |dv|', f'{res["max_velocity_error"]:.3g} m/s (body_{body_v} at t = {t_v:.9g} s)'),
        ('result', f'{"match" if res["match"] else "MISMATCH"} (tolerance {res["tolerance"]:g})'),
    ])
    if not res['match']:
        _say_error(f'replay differs from the recording by {res["max_position_error"]:.3g} m / '
                   f'{res["max_velocity_error"]:.3g} m/s (tolerance {res["tolerance"]:g})')
        return EXIT_FAILURE
    return EXIT_OK


# ------------------------------------------------------------------------------- bag tools

def _cmd_info(args: argparse.Namespace) -> int:
    path = _existing(args.bag, 'bag')
    from ..bag import info

    print(info(path))
    return EXIT_OK


def _inside(path: Path, folder: Path) -> bool:
    """True if ``path`` is ``folder`` or lies inside it (by name: ``folder`` need not exist)."""
    here, there = Path(os.path.abspath(path)), Path(os.path.abspath(folder))
    return here == there or there in here.parents


def _cmd_plot(args: argparse.Namespace) -> int:
    path = _existing(args.bag, 'bag')
    from ..bag import plot

    print(plot(path, args.output))        # the file written, exactly as named
    return EXIT_OK


def _cmd_recover(args: argparse.Namespace) -> int:
    source = _existing(args.source, 'bag or MCAP file')
    from ..bag import recover
    from ..bag.files import check_new_folder, reading
    from ..bag.recover import default_destination

    with reading(source):                 # before any reading: not the source, nor inside it
        check_new_folder(args.output or default_destination(source))
    with _Progress(f'recovering {args.source}'):
        res = recover(source, args.output)
    topics = ', '.join(f'{name} {n}' for name, n in res.topics.items()) or 'none'
    _print_table([('bag', str(res.bag)),
                  ('status', 'complete' if res.complete else 'source was damaged; readable part '
                   'recovered'),
                  ('messages', f'{res.messages} ({topics})')]
                 + [('problem', problem) for problem in res.problems])
    return EXIT_OK


# ------------------------------------------------------------------------------- parser

def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``crawler-sim`` (every subcommand has --help)."""
    parser = _Parser(
        prog=PROG, description='Simulate friction-based crawling robots; record, inspect, '
        'plot, replay and recover runs; sweep and optimise gaits.',
        epilog='exit codes: 0 ok, 1 the work failed (solver, bag, replay mismatch), '
        '2 bad input (usage, missing file, invalid scene) or a refused output (an input, '
        'inside an input bag, a directory, an existing bag), 130 interrupted',
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--debug', action='store_true',
                        help='show the full traceback on errors')
    parser.add_argument('--version', action='version', version=f'%(prog)s {_version()}')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', parser_class=_Parser)

    def add(name: str, func: Callable[[argparse.Namespace], int], help_: str,
            description: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=description)
        p.set_defaults(func=func)
        # --debug after the command too (`crawler-sim simulate S.yaml --debug`); SUPPRESS
        # keeps a --debug given before the command when this one is absent
        p.add_argument('--debug', action='store_true', default=argparse.SUPPRESS,
                       help='show the full traceback on errors')
        return p

    p = add('simulate', _cmd_simulate, 'run a scene offline and print its figures',
            'Simulate SCENE.yaml (see config/scenes/*.yaml) and print displacement, mean speed, '
            'stick '
            'fraction per body, events, dissipated energy, actuator work, cost of transport, '
            'the verify check and the wall time.')
    p.add_argument('scene', metavar='SCENE.yaml', help='scene file (top-level key "scene:")')
    p.add_argument('--method', choices=METHODS, help='solver (overrides scene.run.method)')
    p.add_argument('--stiction-rule', choices=RULES,
                   help='with static friction above kinetic: who holds when several parts come '
                   'to rest at once (overrides scene.run.stiction_rule; default incumbent)')
    p.add_argument('--t-end', type=_positive, metavar='T',
                   help='simulated time [s] (overrides scene.run.t_end)')
    p.add_argument('--dt', type=_positive, metavar='DT',
                   help='step of implicit/penalty [s] (overrides scene.run.dt)')
    p.add_argument('--penalty', type=_positive, metavar='N',
                   help='method penalty: the regularisation n [N s/m] (overrides '
                   'scene.run.penalty; default sim_node\'s 1e4)')
    p.add_argument('--out', metavar='BAG_DIR', help='record the run to a new bag directory')
    p.add_argument('--plot', metavar='PNG', help='write a plot of the run')
    p.add_argument('--json', action='store_true', help='print the figures as JSON')
    p.add_argument('--as-node', choices=AS_NODE_MODES,
                   help='run it as sim_node does when gait_node plays the gait: one preloaded '
                   'trajectory, streamed trajectories, or set-points on linkage_cmd (the '
                   "node's actuator and tick grid, without ROS)")
    p.add_argument('--rate', type=_positive, default=50.0, metavar='HZ',
                   help='with --as-node: gait_node\'s rate [Hz] (default 50)')
    p.add_argument('--initial-lengths', type=_positive, nargs='+', metavar='L',
                   help='with --as-node: the linkage lengths [m] the servo rests at before the '
                   "run, as sim_node's initial_lengths (one for all linkages or one each; "
                   "default: the gait's first lengths)")

    p = add('replay', _cmd_replay, 're-simulate a recorded run and compare',
            'Re-run a recorded run with the core: a sim_node bag through the node\'s engine with '
            'its recorded inputs (commands, trajectories, parameter changes, resets), an offline '
            'bag from its scene; report the largest difference from the recorded states. Exit 0 '
            'when within the tolerance, 1 on a mismatch.')
    p.add_argument('bag', metavar='BAG', help='bag directory or MCAP file')
    p.add_argument('--method', choices=METHODS, help='solver (default: the recorded one)')
    p.add_argument('--tol', type=_positive, default=REPLAY_TOL, metavar='TOL',
                   help=f'largest allowed |dx| [m] and |dv| [m/s] (default: {REPLAY_TOL:g})')

    p = add('info', _cmd_info, 'summarise a bag', 'Print topics, counts, duration and scene '
            'of a bag.')
    p.add_argument('bag', metavar='BAG', help='bag directory or MCAP file')

    p = add('plot', _cmd_plot, 'plot a recorded run', 'Plot a recorded run: body positions, '
            'velocities and friction forces, linkage lengths, and when each body is stuck '
            '(the figure `simulate --plot` draws).')
    p.add_argument('bag', metavar='BAG', help='bag directory or MCAP file')
    p.add_argument('-o', '--output', required=True, metavar='PNG', help='image file to write')

    p = add('recover', _cmd_recover, 'recover a damaged or unfinished recording',
            'Rewrite what can be read from a damaged or unfinished bag (e.g. after a crash) '
            'into a valid bag.')
    p.add_argument('source', metavar='BAG_OR_MCAP', help='damaged bag directory or MCAP file')
    p.add_argument('-o', '--output', metavar='OUT',
                   help='where to write the recovered bag (default: next to the source)')

    from .sweep_commands import register       # sweep, optimize, export
    register(add, _positive, _non_negative_int, _positive_int)
    return parser


def _version() -> str:
    try:
        from importlib.metadata import version
        return version('crawler_sim')
    except Exception:  # not installed: the source tree
        return '0.1.0'


#: optional packages a command may need (not in ``pip install .``), and the pip command that
#: installs each (exit 2, one line: issue 43)
_OPTIONAL = {'pandas': 'pip install pandas', 'pyarrow': 'pip install pyarrow',
             'dask': 'pip install "dask[distributed]"',
             'distributed': 'pip install "dask[distributed]"'}


def _optional(exc: BaseException) -> str | None:
    """The pip command for the optional package whose absence ``exc`` reports, or None."""
    name = getattr(exc, 'name', None) if isinstance(exc, ImportError) else None
    return _OPTIONAL.get((name or '').split('.')[0])


def _exit_code(exc: BaseException) -> int:
    if _optional(exc):
        return EXIT_USAGE
    scene = sys.modules.get('crawler_sim.core.scene')
    spec = sys.modules.get('crawler_sim.sweep.spec')
    files = sys.modules.get('crawler_sim.bag.files')     # loaded by every command that writes
    if spec is not None and isinstance(exc, spec.SpecError):
        return EXIT_USAGE
    if files is not None and isinstance(exc, files.OutputRefused):
        return EXIT_USAGE
    journal = sys.modules.get('crawler_sim.core.plant.replay')
    if journal is not None and isinstance(exc, journal.JournalError):   # a recorded input
        return EXIT_USAGE
    if isinstance(exc, UsageError) or (scene is not None and isinstance(exc, scene.SceneError)):
        return EXIT_USAGE
    return EXIT_FAILURE


def _describe(exc: BaseException) -> str:
    """One line for the user. Expected errors show their message; others their type too."""
    if isinstance(exc, OSError):          # a file that could not be read or written
        where = f'{exc.filename}: ' if exc.filename else ''
        return f'{where}{exc.strerror or exc or type(exc).__name__}'
    if isinstance(exc, MemoryError):
        return 'not enough memory for this command (a smaller run, sweep or bag needs less)'
    if _optional(exc):
        return (f'this command needs {exc.name}, which is not installed: {_optional(exc)} '
                '(or pip install ".[sweep]" in the crawler_sim checkout)')
    if isinstance(exc, ImportError):
        return f'a part of crawler_sim this command needs is missing: {exc}'
    errors = sys.modules.get('crawler_sim.bag.errors')
    known = (UsageError, ValueError, RuntimeError, ArithmeticError) + (
        (errors.BagError,) if errors is not None else ())
    if isinstance(exc, known):
        return str(exc) or type(exc).__name__
    return f'internal error ({type(exc).__name__}: {exc}); rerun with --debug for the traceback'


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings (e.g. a truncated bag was read in part) as one line on stderr."""
    print(f'{PROG}: warning: {" ".join(str(message).split())}', file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``crawler-sim``; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:     # --help, --version, usage errors
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return args.func(args)
    except BrokenPipeError:       # stdout closed early (e.g. `| head`): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except KeyboardInterrupt:
        _say_error('interrupted')
        return EXIT_INTERRUPTED
    except Exception as exc:
        if args.debug:
            raise
        _say_error(_describe(exc))
        return _exit_code(exc)
