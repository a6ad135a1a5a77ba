"""Entry point of ``ros2 run crawler_sim sim_node`` (also ``crawler_sim.ros.sim_node:main``).

The simulation loop runs in the main thread; ROS callbacks (services, parameters) in an executor
thread. On SIGINT/SIGTERM the loop stops between two ticks; the executor thread is joined before
anything is destroyed, then the bag is closed, the node destroyed and rclpy shut down.

``-h``/``--help`` prints the parameters (``crawler_sim.ros.args.help_text``) and exits 0
before rclpy starts. Before rclpy parses them, the arguments are checked
(``crawler_sim.ros.args``): a ``--params-file`` that is missing, not YAML, or not a ROS
parameter file, or an argument outside ``--ros-args``, gives one line naming it and exit code
2, instead of an rcl traceback or silence.

Before rclpy starts, :func:`use_fastdds_profile` gives Fast DDS the node's writer profile
(``fastdds_profile.xml`` next to this module: why in its comments) unless the user chose a
profile or another middleware.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import sys
import threading
from typing import MutableMapping

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from .standard import ACTION, SERVICES

__all__ = ['main', 'use_fastdds_profile', 'FASTDDS_PROFILE']

SPIN_TIMEOUT = 2.0       # s, the longest wait of the executor thread for a callback

#: the first paragraph of ``sim_node --help`` (the standard's services and action named from
#: their table, .standard)
HELP_SUMMARY = ('Simulates a friction crawler of p bodies joined by p-1 imposed linkages: takes '
                'lengths on linkage_cmd (or linkage_trajectory), publishes joint_states, '
                'body_states, contact_states, contacts, odom, markers, robot_description, '
                '/tf (odom -> base_link; r1/odom -> r1/base_link in namespace /r1), /clock and '
                '/diagnostics; services ~/reset, ~/pause, ~/step, and the simulation_interfaces '
                f'services {", ".join(SERVICES)} and action {ACTION} (when the package is '
                'installed). Node name crawler_sim; parameters change at run time unless read '
                'only (docs/node.md).')


#: sim_node's Fast DDS profile: every writer's nack suppression (issue 42), installed with the
#: package (setup.py package_data) so that it is found wherever the code is
FASTDDS_PROFILE = Path(__file__).with_name('fastdds_profile.xml')
#: the variables naming a user's own profile file (Fast DDS 2 reads the first, 3 the second)
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')
#: the file Fast DDS loads from the working directory when present
CWD_PROFILE = 'DEFAULT_FASTRTPS_PROFILES.xml'


def use_fastdds_profile(environ: MutableMapping[str, str] = os.environ) -> str:
    """Point ``FASTRTPS_DEFAULT_PROFILES_FILE`` of ``environ`` (this process's environment: call
    before rclpy starts) at :data:`FASTDDS_PROFILE` and return its path, or leave ``environ``
    alone and return '' when the user chose otherwise: a profile file of their own (either
    variable of :data:`PROFILE_VARIABLES`, or :data:`CWD_PROFILE` in the working directory),
    QoS from XML (``RMW_FASTRTPS_USE_QOS_FROM_XML``), or a middleware other than rmw_fastrtps
    (``RMW_IMPLEMENTATION``)."""
    rmw = environ.get('RMW_IMPLEMENTATION', '')
    if (any(environ.get(name) for name in PROFILE_VARIABLES)
            or environ.get('RMW_FASTRTPS_USE_QOS_FROM_XML', '0') not in ('', '0')
            or (rmw and not rmw.startswith('rmw_fastrtps'))
            or Path(CWD_PROFILE).is_file() or not FASTDDS_PROFILE.is_file()):
        return ''
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(FASTDDS_PROFILE)
    return str(FASTDDS_PROFILE)


def main(args: list[str] | None = None) -> None:
    """Run sim_node until SIGINT/SIGTERM."""
    from crawler_sim.ros.args import (ArgsError, check_args, print_help_and_exit,
                                      unknown_parameters)
    from .params import NODE_NAME, PARAMETERS
    argv = sys.argv if args is None else args
    print_help_and_exit(list(argv), 'sim_node', NODE_NAME, HELP_SUMMARY, PARAMETERS)
    from .node import SimNode
    try:
        check_args(list(argv), 'sim_node')
    except ArgsError as exc:
        print(f'[crawler_sim] cannot start: {exc}', file=sys.stderr, flush=True)
        raise SystemExit(2) from None
    use_fastdds_profile()
    rclpy.init(args=args)
    node = None
    executor = None
    spin_thread = None
    stop_spin = threading.Event()
    try:
        executor = SingleThreadedExecutor()
        node = SimNode()
        unknown = unknown_parameters(node, argv)
        if unknown:                 # a misspelt name would otherwise be ignored silently
            print(f'[crawler_sim] cannot start: {"; ".join(unknown)}', file=sys.stderr,
                  flush=True)
            raise SystemExit(1)
        executor.add_node(node)
        node.warm_up()
        # From here a signal only asks the loop to stop between two ticks: an exception raised
        # at an arbitrary point (e.g. inside a bag write) could leave the MCAP file inconsistent.
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda signum, frame, n=node: n.stop())
        failure: list[BaseException] = []
        spin_thread = threading.Thread(target=_spin, args=(executor, stop_spin, node, failure),
                                       daemon=True)
        spin_thread.start()
        node.choose_clock()         # several sims in one domain: one of them owns /clock
        node.log_ready()
        node.run()
        if failure:
            raise failure[0]
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if not rclpy.ok():
            pass                  # a signal shut ROS down while starting: a clean exit
        elif node is None:        # e.g. invalid parameter overrides: one clear line, exit 1
            print(f'[crawler_sim] cannot start: {exc}', file=sys.stderr, flush=True)
            raise SystemExit(1) from None
        else:
            raise
    finally:
        stop_spin.set()
        if executor is not None:
            executor.wake()       # the spin thread returns now, not at the end of its wait
        if spin_thread is not None:
            spin_thread.join(timeout=5.0)
        if node is not None:
            node.close()
        if executor is not None and not (spin_thread is not None and spin_thread.is_alive()):
            # (rclpy 7.1's Executor.shutdown destroys its guard conditions without waiting
            # for a spinning thread, so it is called only once that thread has ended)
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def _spin(executor: SingleThreadedExecutor, stop: threading.Event, node,
          failure: list[BaseException]) -> None:
    """Run callbacks until ``stop`` is set or the context shuts down; a callback that raises
    (a bug) stops the node and is re-raised by ``main``."""
    try:
        # a long wait: every wake-up of an idle executor rebuilds its wait set in Python (about
        # 0.5 % of a core at 10 Hz); main() wakes it to stop, and a shutdown of the context
        # ends the wait
        while not stop.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_TIMEOUT)
    except (ExternalShutdownException, KeyboardInterrupt):
        pass
    except Exception as exc:
        if executor.context.ok():
            failure.append(exc)
            node.stop()
