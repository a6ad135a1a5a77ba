"""MCAP recording, reading, recovery and plotting of crawler_sim runs (rosbag2/Jazzy layout).

Public API
----------
``BagWriter.create(record_dir, record_name, *, scene=None, topics=None, ...)``
    A new bag in its own folder inside ``record_dir`` (name checked and made unique; header,
    schemas and channels on disk at once; flushed every 0.5 s). ``BagWriter(path, ...)`` for an
    explicit path. ``write(topic, type_name, msg, t_ns)``, ``flush()``, ``close()``, ``error``.
``Recorder.create(record_dir, record_name, *, masses=None, scene=None, namespace='')``
    The node's topics: ``record_state(t, x, v, ...)``, ``record_command``, ``record_event``.
``check_record_name(name)``
    ``ValueError`` naming ``record_name`` unless ``name`` is one folder of ``[A-Za-z0-9._-]``.
``record_arrays(path, *, t, x, v, friction, contact, lengths, rates, linkage_force, ...)``
    Offline run -> bag with the node's state topics (body_states, joint_states,
    contact_states, odom), commands, events and scene, with the same types; the node records
    more (markers, diagnostics, its inputs' journal, ...): :mod:`crawler_sim.bag.topics`.
``load(path, *, namespace=None) -> Run``
    Bag directory or .mcap -> numpy arrays (every intact chunk of a damaged file; bodies that
    did not exist at a state, when p changed mid-run: ``Run.present`` False, ``NO_BODY``).
``recover(src, dst=None) -> RecoverResult``
    Truncated or damaged .mcap (SIGKILL, flipped bits) -> valid bag directory holding every
    message of every intact chunk.
``info(path) -> str`` and ``plot(path, out_png) -> Path``
    Summaries for the command line.

See docs/bags.md for the guarantees (crashes, hostile files, definitions without the ament
index) and how they are tested.
``to_ns(t)``
    The one seconds -> integer nanoseconds conversion.
"""
from .clock import to_ns, to_seconds
from .errors import BagError
from .info import info
from .naming import check_record_name
from .plot import plot
from .reader import NO_BODY, BagWarning, Commands, Events, Run, TopicSummary, bag_files, load
from .recorder import Recorder, record_arrays, record_trajectory
from .recover import RecoverResult, recover
from .writer import BagWriter

__all__ = ['NO_BODY', 'BagError', 'BagWarning', 'BagWriter', 'Commands', 'Events',
           'RecoverResult',
           'Recorder', 'Run', 'TopicSummary', 'bag_files', 'check_record_name', 'info', 'load',
           'plot',
           'record_arrays', 'record_trajectory', 'recover', 'to_ns', 'to_seconds']
