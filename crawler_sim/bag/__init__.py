"""MCAP recording, reading, recovery and plotting of crawler_sim runs (rosbag2/Jazzy layout).

Public API
----------
``BagWriter(path, *, scene=None, qos=None, ...)``
    Low-level writer: ``write(topic, type_name, msg, t_ns)``, ``flush()``, ``close()``, ``error``.
``Recorder(path, *, masses=None, scene=None, namespace='')``
    The node's topics: ``record_state(t, x, v, ...)``, ``record_command``, ``record_event``.
``record_arrays(path, *, t, x, v, friction, contact, lengths, rates, linkage_force, ...)``
    Offline run -> bag with the same topics and types as the node.
``load(path, *, namespace=None) -> Run``
    Bag directory or .mcap -> numpy arrays.
``recover(src, dst=None) -> RecoverResult``
    Truncated .mcap (e.g. after SIGKILL) -> valid bag directory.
``info(path) -> str`` and ``plot(path, out_png) -> Path``
    Summaries for the command line.
``to_ns(t)``
    The one seconds -> integer nanoseconds conversion.
"""
from .clock import to_ns, to_seconds
from .errors import BagError
from .info import info
from .plot import plot
from .reader import BagWarning, Commands, Events, Run, TopicSummary, bag_files, load
from .recorder import Recorder, record_arrays, record_trajectory
from .recover import RecoverResult, recover
from .writer import BagWriter

__all__ = ['BagError', 'BagWarning', 'BagWriter', 'Commands', 'Events', 'RecoverResult',
           'Recorder', 'Run', 'TopicSummary', 'bag_files', 'info', 'load', 'plot',
           'record_arrays', 'record_trajectory', 'recover', 'to_ns', 'to_seconds']
