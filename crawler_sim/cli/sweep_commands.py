"""The ``sweep``, ``optimize`` and ``export`` subcommands of ``crawler-sim``.

Registered by `crawler_sim.cli.build_parser` through :func:`register`; pandas, Dask and scipy
are imported inside the commands so ``crawler-sim --help`` stays light.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import shutil
import time
from typing import Any, Callable

__all__ = ['register']

Add = Callable[[str, Callable[[argparse.Namespace], int], str, str], argparse.ArgumentParser]


def _cli():
    from . import EXIT_OK, UsageError, _existing, _info, _print_table
    return EXIT_OK, UsageError, _existing, _info, _print_table


def _client(address: str | None) -> Any:
    if not address:
        return None
    from ..sweep.cluster import connect
    return connect(address)


def _spec_of(path: Path) -> Any:
    """A spec from a sweep YAML file, or from the metadata of a sweep's Parquet/CSV results;
    SpecError (a refused input, exit 2) naming the file otherwise."""
    from ..sweep import load_spec, spec_from_dict
    from ..sweep.spec import SpecError
    from ..sweep.tables import read_table

    if path.suffix.lower() in ('.parquet', '.csv'):
        try:
            meta = read_table(path).attrs.get('crawler_sim', {})
        except ValueError as exc:           # names the file and why it cannot be read
            raise SpecError(str(exc)) from None
        if meta.get('kind') != 'sweep' or 'spec' not in meta:
            raise SpecError(f'{path}: holds no sweep spec in its metadata (not written by '
                            'crawler-sim sweep)')
        try:
            return spec_from_dict(meta['spec'])
        except SpecError as exc:
            raise SpecError(f'{path}: {exc}') from None
    return load_spec(path)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from ..bag.files import reading

    source = _cli()[2](args.spec)
    with reading(source):                 # no output may be the spec (or results) it runs
        return _sweep(args, source)


def _sweep(args: argparse.Namespace, source: Path) -> int:
    EXIT_OK, UsageError, _existing, _info, _print_table = _cli()
    from ..bag.files import OutputRefused, check_outputs
    from ..sweep import sweep
    from ..sweep.tables import table_files, write_table

    spec = _spec_of(source)
    fmt = 'csv' if args.csv else 'parquet'
    out = Path(args.output or f'sweep_{spec.name}.{fmt}')
    check_outputs(*table_files(out, fmt))     # before the sweep runs, not after
    checkpoint = Path(args.checkpoint) if args.checkpoint else out.with_name(out.name + '.chunks')
    if not args.checkpoint and checkpoint.is_symlink():
        # a folder the sweep makes beside its output is not followed through a planted link
        # (a folder the user names with --checkpoint is, as given)
        raise OutputRefused(f'{checkpoint}: the default checkpoint folder is a link; remove it '
                            'or name a folder with --checkpoint')
    if checkpoint.exists():
        _info(f'resuming from {checkpoint} (finished chunks are not recomputed)')
    client = _client(args.scheduler)
    start = time.perf_counter()
    try:
        df = sweep(spec, client=client, workers=args.workers, checkpoint=checkpoint,
                   progress=not args.quiet)
    finally:
        if client is not None:
            client.close()
    wall = time.perf_counter() - start
    write_table(df, out, fmt)
    if not args.checkpoint:
        shutil.rmtree(checkpoint, ignore_errors=True)     # the table now holds every chunk
    errors = int((df['error'] != '').sum())
    speed = df['mean_speed']
    rows = [('sweep', f'{spec.name}: {len(df)} scenes x {spec.periods} periods'),
            ('where', args.scheduler or f'local ({args.workers or "all"} processes)'),
            ('wall time', f'{wall:.2f} s'),
            ('errors', f'{errors} scenes' + (f' (first: {df.loc[df.error != "", "error"].iloc[0]})'
                                              if errors else '')),
            ('not steady', f'{int((df["steady"] == False).sum())} scenes'),  # noqa: E712
            ('mean speed', f'min {speed.min():.4g}, median {speed.median():.4g}, '
                           f'max {speed.max():.4g} m/s'),
            ('output', str(out))]
    _print_table(rows)
    return EXIT_OK


def _cmd_export(args: argparse.Namespace) -> int:
    EXIT_OK, UsageError, _existing, _info, _print_table = _cli()
    from ..sweep.tables import export_bag

    bag = _existing(args.bag, 'bag')
    out, fmt = (args.parquet, 'parquet') if args.parquet else (args.csv, 'csv')
    samples, events = export_bag(bag, out, fmt)   # every output checked before any is written
    print(samples)
    print(events)
    return EXIT_OK


def _cmd_optimize(args: argparse.Namespace) -> int:
    from ..bag.files import reading

    source = _cli()[2](args.scene)
    with reading(source):                 # no output may be the scene it optimises
        return _optimize(args, source)


def _optimize(args: argparse.Namespace, source: Path) -> int:
    EXIT_OK, UsageError, _existing, _info, _print_table = _cli()
    import yaml

    from dataclasses import replace

    from ..bag.files import check_outputs, write_text
    from ..core.actuator import ActuatorLimits
    from ..core.scene import load_scene, scene_to_dict
    from ..sweep.optimize import STREAM, gait_node_params, optimize, sim_node_params
    from ..sweep.tables import table_files

    scene = load_scene(source)
    limits = ActuatorLimits(args.bandwidth, args.max_speed, args.max_acceleration)
    stream = replace(STREAM, rate=args.play_rate, duration=args.play_seconds)
    out = Path(args.output)
    stem = out.with_suffix('')
    scene_file = stem.with_name(stem.name + '_scene.yaml')
    sim_file = stem.with_name(stem.name + '_sim.yaml')
    # every output checked before the optimiser runs (minutes), not after it
    outputs = [out, scene_file] + ([sim_file] if args.score == 'node' else [])
    if args.history:
        from ..bag.plot import figure_output
        outputs.append(figure_output(args.history)[0])
    if args.history_table:
        outputs += table_files(args.history_table)
    check_outputs(*outputs)
    client = _client(args.scheduler)
    try:
        res = optimize(scene, objective=args.objective, family_name=args.family,
                       limits=limits, harmonics=args.harmonics, periods=args.periods,
                       maxiter=args.maxiter, popsize=args.popsize, seed=args.seed,
                       client=client, workers=args.workers, score=args.score,
                       stream=stream, progress=_info)
    finally:
        if client is not None:
            client.close()
    best_scene = scene_to_dict(scene)
    spec: dict[str, Any] = {'type': res.family.name}      # the scene-file gait schema
    params = res.params
    if res.family.name in ('scallop', 'stroke'):
        spec.update(mean=list(res.family.mean), amplitude=params['amplitude'],
                    frequency=params['frequency'], asymmetry=params['asymmetry'])
        spec['phase'] = [-j * params.get('phase_lag', 0.0) for j in range(res.family.n_links)]
    else:
        spec.update(mean=list(res.family.mean), frequency=res.family.frequency,
                    coefficients=[res.gait.cos.tolist(), res.gait.sin.tolist()])
    best_scene['gait'] = spec
    best_scene['name'] = f'{scene.name}_optimized'
    best_scene['description'] = (f'{scene.name} with the {res.family.name} stroke of best '
                                 f'{args.objective} found by crawler-sim optimize')
    scored = ('as sim_node runs it (OUT_sim.yaml) when gait_node plays it (OUT)'
              if args.score == 'node' else 'on its ideal lengths (an ideal actuator; the '
              'node\'s servo changes it)')
    header = (f'# crawler-sim optimize {args.scene}: {args.family} stroke, objective '
              f'{args.objective}, limits |l\'| <= {limits.max_speed} m/s, |l\'\'| <= '
              f'{limits.max_acceleration} m/s^2, bandwidth {limits.bandwidth} Hz\n'
              f'# mean speed {res.best["mean_speed"]:.6g} m/s, cost of transport '
              f'{res.best["cost_of_transport"]:.6g}, scored {scored}\n')
    play = (f'# play: ros2 run crawler_sim sim_node --ros-args --params-file {sim_file.name}\n'
            f'#       ros2 run crawler_sim gait_node --ros-args --params-file {out.name}\n'
            if args.score == 'node' else
            f'# play: ros2 run crawler_sim gait_node --ros-args --params-file {out.name}\n')
    write_text(scene_file, header + yaml.safe_dump({'scene': best_scene}, sort_keys=False))
    node = gait_node_params(res, str(scene_file.resolve()))
    write_text(out, header + play + yaml.safe_dump(node, sort_keys=False))
    sim = sim_node_params(res)
    if sim is not None:
        write_text(sim_file, header + play + yaml.safe_dump(sim, sort_keys=False))
    if args.history:
        from ..sweep.figures import optimize_history
        optimize_history(res, args.history)
    if args.history_table:
        import pandas as pd
        from ..sweep.tables import write_table
        write_table(pd.DataFrame(res.history), args.history_table)
    n_global = sum(h['stage'] == 'global' for h in res.history)
    rows = [('family', f'{res.family.name} ({", ".join(res.family.names)})'),
            ('objective', args.objective),
            ('evaluations', f'{len(res.history)} ({n_global} global, then local)'),
            ('best', ', '.join(f'{k} {v:.6g}' for k, v in params.items())),
            ('mean speed', f'{res.best["mean_speed"]:.6g} m/s'),
            ('cost of transport', f'{res.best["cost_of_transport"]:.6g}'),
            ('scored', scored.replace('OUT_sim.yaml', str(sim_file)).replace('OUT', str(out))),
            ('scene', str(scene_file))]
    rows.append(('gait_node params', str(out)))
    if sim is not None:
        rows.append(('sim_node params', str(sim_file)))
    if args.json:
        print(json.dumps({'params': params, 'best': {k: (v if not isinstance(v, float) or
                                                          math.isfinite(v) else None)
                                                      for k, v in res.best.items()},
                          'scene': str(scene_file), 'score': args.score,
                          'gait_node_params': str(out),
                          'sim_node_params': str(sim_file) if sim is not None else None},
                         indent=2))
    else:
        _print_table(rows)
    return EXIT_OK


def register(add: Add, positive: Callable[[str], float],
             non_negative_int: Callable[[str], int],
             positive_int: Callable[[str], int]) -> None:
    """Add the sweep, optimize and export subcommands through ``add`` (build_parser's helper);
    ``positive``, ``non_negative_int`` and ``positive_int`` are its argument types."""
    p = add('sweep', _cmd_sweep, 'run a parameter sweep and write one row per scene',
            'Simulate every scene of SPEC.yaml (a grid or a random sample over scene and gait '
            'parameters, see config/sweeps/) and write mean speed, displacement per period, '
            'stick fractions, dissipated energy, cost of transport, actuator peak force and the '
            'verify figure per scene to Parquet (or CSV) with the spec as metadata. SPEC may '
            'also be the results of an earlier sweep: it is run again. Interrupted runs resume '
            'from OUT.chunks/.')
    p.add_argument('spec', metavar='SPEC.yaml', help='sweep file (top-level key "sweep:"), or '
                   'a results .parquet/.csv to re-run')
    p.add_argument('-o', '--output', metavar='OUT', help='results file (default: '
                   'sweep_<name>.parquet)')
    p.add_argument('--csv', action='store_true', help='write CSV instead of Parquet')
    p.add_argument('--scheduler', metavar='ADDRESS', help='run on the Dask scheduler at '
                   'ADDRESS (e.g. tcp://host:8786) instead of local processes')
    p.add_argument('--workers', type=non_negative_int, metavar='N',
                   help='local processes (default: all cores)')
    p.add_argument('--checkpoint', metavar='DIR', help='keep finished chunks in DIR '
                   '(default: OUT.chunks, removed after success)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')

    p = add('optimize', _cmd_optimize, 'find the fastest or cheapest stroke',
            'Find the stroke that maximises the steady mean speed (or minimises the cost of '
            'transport) of the crawler of SCENE.yaml under sim_node\'s actuator limits: '
            'differential evolution, then Nelder-Mead. Scored by default as sim_node runs it '
            '(--score). Writes OUT (a gait_node parameter file: the stroke as one preloaded '
            'trajectory), OUT_sim.yaml (the sim_node parameters it was scored with) and '
            'OUT_scene.yaml (a scene with the best gait).')
    p.add_argument('scene', metavar='SCENE.yaml', help='scene: crawler, run options, mean lengths')
    p.add_argument('--objective', choices=('speed', 'cot'), default='speed',
                   help='speed (maximise) or cot (minimise cost of transport); default speed')
    p.add_argument('--family', choices=('scallop', 'stroke', 'fourier'), default='scallop',
                   help='stroke family (default scallop; gait_node plays every family)')
    p.add_argument('--harmonics', type=positive_int, default=3, metavar='K',
                   help='fourier harmonics')
    p.add_argument('--max-speed', type=positive, default=0.5, metavar='V',
                   help="largest |l'| [m/s] (sim_node's actuator_max_speed, default 0.5)")
    p.add_argument('--max-acceleration', type=positive, default=5.0, metavar='A',
                   help="largest |l''| [m/s^2] (actuator_max_acceleration, default 5)")
    p.add_argument('--bandwidth', type=positive, default=5.0, metavar='HZ',
                   help='highest stroke frequency [Hz] (actuator_bandwidth, default 5)')
    p.add_argument('--score', choices=('node', 'ideal'), default='node',
                   help='node (default): the stroke as sim_node runs it when gait_node plays '
                   'the written file (the servo shapes it); ideal: its own lengths')
    p.add_argument('--play-rate', type=positive, default=100.0, metavar='HZ',
                   help='trajectory samples per second gait_node sends (default 100)')
    p.add_argument('--play-seconds', type=positive, default=600.0, metavar='S',
                   help='length of the preloaded trajectory gait_node sends (default 600)')
    p.add_argument('--periods', type=positive_int, default=12, metavar='N',
                   help='periods per run')
    p.add_argument('--maxiter', type=non_negative_int, default=15, metavar='N',
                   help='generations')
    p.add_argument('--popsize', type=positive_int, default=8, metavar='N',
                   help='population factor')
    p.add_argument('--seed', type=non_negative_int, default=0, metavar='N', help='random seed')
    p.add_argument('--workers', type=positive_int, default=1, metavar='N',
                   help='local processes')
    p.add_argument('--scheduler', metavar='ADDRESS', help='evaluate on a Dask scheduler')
    p.add_argument('-o', '--output', default='best_gait.yaml', metavar='OUT',
                   help='gait_node parameter file (default best_gait.yaml)')
    p.add_argument('--history', metavar='PNG', help='plot of the optimiser history')
    p.add_argument('--history-table', metavar='FILE', help='every evaluation (.parquet/.csv)')
    p.add_argument('--json', action='store_true', help='print the result as JSON')

    p = add('export', _cmd_export, 'write a bag as tables (Parquet or CSV)',
            'Write a recorded run as a table with one row per sample (one column per body '
            'quantity) and its contact events as a second table OUT_events.')
    p.add_argument('bag', metavar='BAG', help='bag directory or MCAP file')
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument('--parquet', metavar='OUT', help='Parquet file to write')
    g.add_argument('--csv', metavar='OUT', help='CSV file to write')
