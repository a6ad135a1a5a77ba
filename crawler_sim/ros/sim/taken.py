"""``LoopTakenGroup``: subscriptions whose messages sim_node's loop takes itself."""
from __future__ import annotations

from typing import Any

from rclpy.callback_groups import CallbackGroup

__all__ = ['LoopTakenGroup']


class LoopTakenGroup(CallbackGroup):
    """Callback group of subscriptions whose messages the simulation loop takes itself.

    An executor never waits on nor runs anything of this group (``can_execute`` is always
    False), so an incoming message does not wake the executor thread (each wake-up rebuilds a
    wait set in Python and takes the GIL from the loop). The loop takes the messages between
    ticks instead (``SimNode.take_inputs``, ``SharedClock.poll``).
    """

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass
