"""The one ``/clock`` of several sims in one domain: who publishes it, and who takes over.

``/clock`` is global, so the crawler_sim nodes of a domain (each in its own namespace) share
one clock. Each sim with ``publish_clock`` is a *candidate*; at any moment one of them owns the
clock (publishes it) and the others follow it (tick up to its time, never past it, so the
stamps of every robot agree). The rules, each in one place below:

- **Start** (:meth:`SharedClock.choose`): a sim listens until :data:`DISCOVERY` wall seconds
  after its creation (DDS discovery between processes takes seconds here). A clock that ticks
  is followed (a sim already running, a paused one, which keeps its clock
  alive, or a foreign clock such as a bag player). Otherwise the candidate with the smallest
  fully qualified name owns it; the order of start-up does not matter.
- **Owner silent** (:meth:`SharedClock.poll`, follower): an owner that is another crawler_sim
  and publishes nothing for :data:`SILENCE` wall seconds (killed, hung) is given up; the
  remaining candidates in name order take over one after the other, candidate k after
  ``SILENCE + k * STAGGER`` of silence (the first one heard by the others ends the wait of the
  rest: exactly one takes over, within about a second). It continues from the last time heard
  (:attr:`Outputs.clock_floor`: no /clock below it), so the clock never goes back and no
  follower stays frozen.
- **Silence** is counted from when the owner last *published* (the DDS source timestamp of the
  latest message, on this host's clock: :meth:`SharedClock._heard_at`), not from when this
  follower took the message. On a loaded machine the kernel leaves a runnable sim waiting on
  the run queue for up to seconds (measured here: 0.5-1.7 s of run-queue wait at load 10-25
  on 2 cores, see docs/node.md); a follower that waited across the owner's last messages took
  them when it ran again and, counting from then, waited a whole SILENCE more before taking
  over. A follower that has just run again after such a wait (:data:`STALL`) acts only
  :data:`WAKE` (+ its rank's turn) later: its own DDS threads deliver what arrived meanwhile,
  and the candidates before it, woken by the same stall, go first.
- **Foreign clock silent**: a /clock published by a node that is not a crawler_sim (a paused
  bag player, another simulator) is followed and never taken over; its silence is reported (a
  WARN line and a diagnostics WARN), not hidden.
- **Two owners** (a stalled owner coming back after a follower took over; two sims that did
  not discover each other in time): an owner that hears a /clock later than the last it
  published yields and follows it. The clock furthest ahead wins, so it never goes back.
- **Keep-alive**: an owner publishes its clock at least every :data:`HEARTBEAT` wall seconds
  (paused, or paced slowly), so silence means a dead or hung owner, not a slow one.

A candidate is a node named ``crawler_sim`` (``NODE_NAME``; namespaces tell them apart) that
publishes or subscribes ``/clock``: renamed with ``-r __node:=...``, a sim counts as a foreign
clock. The follower takes the /clock messages itself (raw, in the loop), so the executor never
wakes for them.
"""
from __future__ import annotations

import struct
import time
from typing import TYPE_CHECKING, Callable

from rosgraph_msgs.msg import Clock

from crawler_sim.bag import topics as T
from crawler_sim.core.simtime import from_stamp, to_seconds
from .params import NODE_NAME
from .taken import LoopTakenGroup

if TYPE_CHECKING:
    from .node import SimNode

__all__ = ['SharedClock', 'DISCOVERY', 'LISTEN', 'HEAR', 'SILENCE', 'STAGGER', 'HEARTBEAT',
           'STALL', 'WAKE', 'POLL', 'clock_ns']

#: wall s from a sim's creation before it may decide to own /clock: DDS discovery between
#: processes on this host took a few ms, or, when the first announcements are missed, until
#: the next periodic one (every 3 s): up to 2.8 s, measured with a probe node at load 6-7 ...
DISCOVERY = 4.0
LISTEN = 1.0         # ... and at least this long listening after its warm-up
#: ... and this much longer when the graph shows a /clock publisher not heard yet (its messages
#: followed the graph entry within 0.1 s in those measurements)
HEAR = 0.5
SILENCE = 0.6        # wall s without /clock after which an owner that is a sim is given up
#: wall s a follower chosen at start waits for the sim before it in name order, still starting,
#: to begin ticking (its discovery and warm-up), before it takes over
START_GRACE = DISCOVERY + LISTEN + HEAR + SILENCE
#: wall s between the turns of successive candidates to take over. The next one must hear
#: the /clock of the one before, from a publisher created at its takeover: under load its DDS
#: discovery took 0.30 s once (load 29; 3 sims: the second took over 0.25 s after the first
#: and /clock went back 3 times until it yielded), hence 0.5 s, not 0.25 s. Only a second
#: fault (the first in line dead or stalled too) waits for it.
STAGGER = 0.5
HEARTBEAT = 0.1      # wall s: an owner publishes /clock at least this often
#: wall s between two polls of a follower (it polls every loop iteration, ~1 ms apart) that
#: mean it was not running: waiting on the run queue (a loaded machine) or stopped
STALL = 0.1
WAKE = 0.1           # wall s a follower runs after a STALL before it may take over
POLL = 0.05          # wall s between two checks of an owner (keep-alive, a later clock heard)
DEPTH = 100          # /clock messages kept for the loop between two takes


def clock_ns(data: bytes) -> int:
    """The time [ns] of a rosgraph_msgs/Clock in CDR (4-byte encapsulation header, then
    int32 sec and uint32 nanosec, little- or big-endian as the header says)."""
    sec, nanosec = struct.unpack_from('<iI' if data[1] & 1 else '>iI', data, 4)
    return from_stamp(sec, nanosec)


def _fqn(info) -> str:
    return f'{info.node_namespace.rstrip("/")}/{info.node_name}'


class SharedClock:
    """The clock role of one sim (owner, follower, or neither with ``publish_clock`` false).

    The loop calls :meth:`poll` (under the node's lock) and reads :attr:`target_ns`: ``None``
    while it owns the clock (or has none), else the sim time it may tick up to."""

    def __init__(self, node: SimNode, log: Callable[[str, str], None]) -> None:
        self._node = node
        self._created = time.perf_counter()
        self._log = log                    # (level, line)
        self._take = None                  # the /clock subscription's take, once choosing
        self._sub = None
        self.owner = ''                    # what this sim follows ('' while it owns)
        self.foreign = False               # the clock followed is not a crawler_sim's
        self.target_ns: int | None = None  # following: tick up to this sim time
        self.heard_ns = -1                 # the latest /clock heard [ns]
        #: when its publisher last published (perf_counter s, :meth:`_heard_at`); 0: never
        self.heard_wall = 0.0
        #: min over the messages taken of (this host's time of the take - source timestamp)
        #: [ns]: the delivery delay of a message taken at once, plus the offset between the
        #: publisher's clock and this one's (another host); None: no message yet
        self._delay_ns: int | None = None
        self._taken_wall = 0.0             # perf_counter s of the last take that got messages
        self._tried = 0.0                  # ... of the last take (a follower's last poll)
        self._woke = 0.0                   # ... of a follower's first poll after a STALL
        self.silent_for = 0.0              # wall s the followed clock has been silent
        self.takeovers = 0
        self.yields = 0
        self._wait_from = 0.0              # when following began (silence before any message)
        self.next_poll = 0.0               # perf_counter s of the owner's next check
        self._silence_logged = False
        self._fresh = False                # following from the start, no /clock heard yet
        #: the sims publishing /clock when the current silence began (None: not silent)
        self._episode: set[str] | None = None

    # ------------------------------------------------------------------ what the loop reads
    @property
    def active(self) -> bool:
        """Whether this sim takes part in the shared clock (after :meth:`choose`)."""
        return self._take is not None

    def due(self, now: float) -> bool:
        """Whether the loop should call :meth:`poll` now (a follower: every iteration)."""
        return self.target_ns is not None or now >= self.next_poll

    @property
    def following(self) -> bool:
        return self.target_ns is not None

    @property
    def waiting(self) -> bool:
        """Following from the start a clock not heard yet: the sim has not begun (it publishes
        its first state when it hears the clock, at that time)."""
        return self._fresh

    def values(self) -> dict:
        """The figures for /diagnostics."""
        return {'clock': ('following ' + self.owner if self.following else
                          'owner' if self._node.outputs.clock_pub is not None else 'none'),
                'clock_silent_s': round(self.silent_for, 3) if self.following else 0.0,
                'clock_takeovers': self.takeovers, 'clock_yields': self.yields}

    def warnings(self) -> list[str]:
        """A diagnostics WARN while the followed clock is silent (a foreign one stays silent:
        it is never taken over)."""
        if self.following and self.silent_for > SILENCE:
            return [f'/clock of {self.owner} silent for {self.silent_for:.1f} s: '
                    + ('following it, not taking over (a foreign clock)' if self.foreign
                       else 'taking over')]
        return []

    # ------------------------------------------------------------------ start
    def choose(self, discovery: float = DISCOVERY) -> None:
        """At start, with the executor spinning: listen until ``discovery`` wall s after the
        node's creation (at least :data:`LISTEN`) and take the owner's or a follower's role
        (module docstring). Call before the loop, without the lock."""
        node = self._node
        if not node.config.publish_clock:
            return
        self._sub = node.create_subscription(Clock, T.CLOCK.node_name, lambda _m: None, DEPTH,
                                             callback_group=LoopTakenGroup(), raw=True)
        self._take = self._sub.handle.take_message
        end = max(time.perf_counter() + LISTEN, self._created + discovery)
        self._listen(end)
        mine = node.get_fully_qualified_name()
        publishing, sims, foreign = self._graph()
        if not self.heard_wall and (publishing or foreign):
            self._listen(time.perf_counter() + HEAR)     # a clock seen, not heard yet
            publishing, sims, foreign = self._graph()
        lower = [fqn for fqn in sims if fqn < mine]
        if self.heard_wall or foreign or lower:
            with node.lock:
                # heard: the publisher(s) of /clock; else the first sim before this one,
                # which is starting and will own it
                self._follow(foreign, publishing if self.heard_wall else lower, start=True)

    def _listen(self, end: float) -> None:
        while time.perf_counter() < end and not self._drain():
            time.sleep(0.02)

    def _publishers(self) -> int:
        return self._node.count_publishers(T.CLOCK.node_name)

    def _graph(self) -> tuple[list[str], list[str], list[str]]:
        """The other nodes on /clock as the graph shows them, sorted: (sims that publish it,
        sims that publish or subscribe it, foreign publishers). A follower has no /clock
        publisher, so a sim that publishes it is the owner (or one starting, or one killed: the
        graph keeps a killed process for its DDS lease)."""
        node = self._node
        mine = node.get_fully_qualified_name()
        publishing, sims, foreign = set(), set(), set()
        for info in node.get_publishers_info_by_topic(T.CLOCK.node_name):
            (publishing if info.node_name == NODE_NAME else foreign).add(_fqn(info))
        for info in node.get_subscriptions_info_by_topic(T.CLOCK.node_name):
            if info.node_name == NODE_NAME:
                sims.add(_fqn(info))
        sims |= publishing
        for group in (publishing, sims, foreign):
            group.discard(mine)
        return sorted(publishing), sorted(sims), sorted(foreign)

    def _follow(self, foreign: list[str], owners: list[str], start: bool = False) -> None:
        """Stop publishing /clock and follow the one heard, published by ``foreign`` nodes or
        else the sims ``owners`` (under the lock)."""
        node = self._node
        self.foreign = bool(foreign)
        self.owner = (', '.join(foreign) if foreign else owners[0] if owners
                      else 'another node')
        self.silent_for = 0.0
        self._silence_logged = False
        self._wait_from = time.perf_counter()
        self._episode = None
        node.outputs.set_clock_owner(False)
        self._fresh = start and not self.heard_wall
        if start and self.heard_wall:          # a fresh sim starts at the clock's time
            node.restart_at(self.heard_ns)
        self.target_ns = max(self.heard_ns, node.sim_time_ns)
        kind = 'a foreign clock: ' if self.foreign else ''
        self._log('info', f'/clock is published by {kind}{self.owner}: this node follows it '
                  f'(sim time from {to_seconds(node.sim_time_ns):.9f} s) and publishes no '
                  '/clock of its own')

    # ------------------------------------------------------------------ running
    def _drain(self) -> bool:
        """Take every /clock message waiting; return whether any was."""
        take = self._take
        now = time.perf_counter()
        since, self._tried = now - (self._tried or now), now
        got = take(Clock, True)
        if got is None:
            return False
        latest = self.heard_ns
        source = 0
        while got is not None:
            try:
                latest = max(latest, clock_ns(got[0]))
            except (struct.error, IndexError, ValueError):
                pass                              # not a Clock in CDR: ignored
            source = max(source, got[1].get('source_timestamp', 0))
            got = take(Clock, True)
        self.heard_ns = latest
        self.heard_wall = max(self.heard_wall, self._heard_at(now, source, since))
        return True

    def _heard_at(self, now: float, source_ns: int, since: float) -> float:
        """When (perf_counter s) the latest message taken at ``now`` was published, from its
        source timestamp ``source_ns`` (0: unknown, then ``now``), at most ``since`` s (the
        time since the take before) earlier: only what came while this sim was not taking
        (not running) is dated back. The publisher's clock may be another host's: its offset
        goes with the smallest delay seen between publication and take (a message taken at
        once), allowed to grow by 1 % of the time since the last take (clocks drift)."""
        if source_ns <= 0:
            return now
        delay = time.time_ns() - source_ns
        if self._delay_ns is not None:
            delay_min = min(delay, self._delay_ns + int(1e7 * (now - self._taken_wall)))
        else:
            delay_min = delay
        self._delay_ns, self._taken_wall = delay_min, now
        return now - min((delay - delay_min) / 1e9, since)

    def poll(self, now: float) -> None:
        """One check from the loop (under the node's lock), ``now`` = perf_counter()."""
        if self._take is None:
            return
        if self.target_ns is None:
            if now >= self.next_poll:
                self.next_poll = now + POLL
                self._poll_owner(now)
            return
        if now - self._tried > STALL:
            self._woke = now                   # it did not run: waited on the run queue
        if self._drain():
            if self._fresh:                    # the first tick of the clock chosen at start
                self._fresh = False
                self._node.restart_at(self.heard_ns)
                self._node.publish_state()     # the first state, at the clock's time
            self.target_ns = max(self.target_ns, self.heard_ns)
            if self._silence_logged:
                self._log('info', f'/clock of {self.owner} heard again')
            self.silent_for = 0.0
            self._silence_logged = False
            self._episode = None
            return
        self.silent_for = now - max(self.heard_wall, self._wait_from)
        if self.silent_for <= SILENCE or now < self.next_poll:
            return
        self.next_poll = now + POLL
        self._on_silence(now)

    def _poll_owner(self, now: float) -> None:
        outputs = self._node.outputs
        if outputs.clock_pub is None:
            return                              # publish_clock switched off
        if self._drain() and self.heard_ns > outputs.clock_last_ns:
            # another /clock ahead of this one (a stalled owner back, or two sims that did
            # not see each other start): the clock furthest ahead wins, this one follows
            self.yields += 1
            publishing, _sims, foreign = self._graph()
            ahead, mine = to_seconds(self.heard_ns), to_seconds(outputs.clock_last_ns)
            self._log('warn', f'another /clock is ahead of this one ({ahead:.6f} s > '
                      f'{mine:.6f} s): following it')
            self._follow(foreign, publishing)
            return
        if now - outputs.clock_wall > HEARTBEAT:
            outputs.publish_clock_again()        # keep-alive: silence means dead or hung

    def _on_silence(self, now: float) -> None:
        """The followed clock has been silent for more than SILENCE: report a foreign one; a
        sim's is given up, and the followers take over in name order, one STAGGER apart (a
        follower waiting for a sim still starting gives it START_GRACE; one that has just run
        again after a STALL waits WAKE too)."""
        publishing, sims, foreign = self._graph()
        if foreign:
            self.foreign = True
            self.owner = ', '.join(foreign)
            if not self._silence_logged:
                self._log('warn', f'/clock of {self.owner} silent for {self.silent_for:.1f} s: '
                          'following it (a foreign clock is not taken over)')
                self._silence_logged = True
            return
        grace = START_GRACE if self._fresh else SILENCE
        mine = self._node.get_fully_qualified_name()
        if self._episode is None:
            self._episode = set(publishing)
        taking = [fqn for fqn in publishing if fqn not in self._episode and fqn < mine]
        if taking:
            # a sim before this one has just taken over (its /clock publisher is new): wait
            # for its clock, as after any other message
            self._episode.update(taking)
            self.owner = taking[0]
            self._wait_from = time.perf_counter()
            return
        # the candidates are the followers when the silence began (sims without a /clock
        # publisher then): the same list in every follower, whatever each presumed about the
        # owner, and not shortened by the one taking over
        rank = sum(fqn < mine for fqn in sims if fqn not in self._episode)
        if (self.silent_for < grace + rank * STAGGER
                or now - self._woke < WAKE + rank * STAGGER):
            return
        self._take_over()

    def _take_over(self) -> None:
        node = self._node
        floor = max(self.heard_ns, node.sim_time_ns)
        self._log('warn', f'/clock of {self.owner} silent for {self.silent_for:.1f} s: this node '
                  f'publishes /clock from t = {to_seconds(floor):.9f} s')
        self.takeovers += 1
        fresh, self._fresh = self._fresh, False
        self._episode = None
        self.target_ns = None
        self.owner = ''
        self.foreign = False
        self.silent_for = 0.0
        node.outputs.set_clock_owner(True, floor)
        node.reanchor()
        if fresh:                     # it had not begun: its first state (and /clock) now
            node.publish_state()
