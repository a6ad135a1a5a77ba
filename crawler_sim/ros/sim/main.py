"""Entry point of ``ros2 run crawler_sim sim_node`` (also ``crawler_sim.ros.sim_node:main``).

The simulation loop runs in the main thread; ROS callbacks (services, parameters) in an executor
thread. On SIGINT/SIGTERM the loop stops between two ticks; the executor thread is joined before
anything is destroyed, then the bag is closed, the node destroyed and rclpy shut down.

Before rclpy parses them, the ``--params-file`` arguments are checked: a file that is missing,
not YAML, or not a ROS parameter file (no ``ros__parameters`` section, e.g. one of the scene
files of ``config/scenes/``) gives one line naming the file and exit code 2, instead of an rcl
traceback.
"""
from __future__ import annotations

import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

__all__ = ['main', 'check_params_files', 'ParamsFileError']

SPIN_TIMEOUT = 2.0       # s, the longest wait of the executor thread for a callback


class ParamsFileError(ValueError):
    """A --params-file argument that rcl could not use."""


def _has_ros_parameters(node) -> bool:
    if not isinstance(node, dict):
        return False
    return 'ros__parameters' in node or any(_has_ros_parameters(v) for v in node.values())


def check_params_files(args: list[str]) -> None:
    """Raise ParamsFileError for a ``--params-file`` in ``args`` that is not a ROS 2
    parameter file."""
    import yaml
    for k, arg in enumerate(args):
        if arg != '--params-file':
            continue
        if k + 1 >= len(args):
            raise ParamsFileError('--params-file needs a file name')
        path = args[k + 1]
        try:
            with open(path, encoding='utf-8') as f:
                doc = yaml.safe_load(f)
        except OSError as exc:
            raise ParamsFileError(f'cannot read parameter file {path}: {exc.strerror}') from None
        except yaml.YAMLError as exc:
            raise ParamsFileError(f'{path} is not valid YAML: {exc}') from None
        if not _has_ros_parameters(doc):
            hint = ''
            if isinstance(doc, dict) and 'scene' in doc:
                hint = (' It is a scene file: run it with `crawler-sim simulate ' + path
                        + '`; the node\'s parameter files are in config/ros/ '
                        '(e.g. config/ros/crawler_sim.yaml).')
            raise ParamsFileError(f'{path} is not a ROS 2 parameter file (no '
                                  f'"<node name>: ros__parameters:" section).{hint}')


def main(args: list[str] | None = None) -> None:
    """Run sim_node until SIGINT/SIGTERM."""
    from .node import SimNode
    argv = sys.argv if args is None else args
    try:
        check_params_files(list(argv))
    except ParamsFileError as exc:
        print(f'[crawler_sim] cannot start: {exc}', file=sys.stderr, flush=True)
        raise SystemExit(2) from None
    rclpy.init(args=args)
    node = None
    executor = None
    spin_thread = None
    stop_spin = threading.Event()
    try:
        executor = SingleThreadedExecutor()
        node = SimNode()
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
