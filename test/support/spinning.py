"""Waiting and service calls shared by the ROS test harnesses (no sleeps: spin to a deadline)."""
from __future__ import annotations

import time
from typing import Callable


class Spinning:
    """Mixin for a harness with an executor ``self.ex``, a node ``self.client_node`` that makes
    service clients, and a per-wait limit ``self.deadline`` [wall s]."""

    deadline: float

    def until(self, cond: Callable[[], bool], what: str, timeout: float | None = None) -> None:
        timeout = self.deadline if timeout is None else timeout
        end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > end:
                raise AssertionError(f'timed out after {timeout} s waiting for {what}')
            self.ex.spin_once(timeout_sec=0.01)

    def call(self, srv_type, name: str, request, attempts: int = 4):
        """Call a service and return its response. The request is sent again if no response
        came within deadline / attempts: right after discovery a server can answer before it
        has matched the client's response reader, and DDS then drops the response (seen on a
        loaded host). The node's services (pause, reset, set_parameters) can be repeated."""
        client = self.client_node.create_client(srv_type, name)
        self.until(client.service_is_ready, f'service {name}')
        for _ in range(attempts):
            future = client.call_async(request)
            self.ex.spin_until_future_complete(future, timeout_sec=self.deadline / attempts)
            if future.done():
                return future.result()
            client.remove_pending_request(future)
        raise AssertionError(f'no response from {name} in {attempts} attempts')
