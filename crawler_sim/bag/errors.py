"""The one exception type of :mod:`crawler_sim.bag`."""
from __future__ import annotations


class BagError(Exception):
    """A bag cannot be written, read or recovered.

    The message is a single line that names the file and the reason, fit to show a user as is.
    """
