"""Pause, the step budget and the synchronous exchange, without ROS.

Two small state machines that the node only drives:

- :class:`Gate` says whether simulated time may advance: running, or paused with a budget of
  control periods still to take (``~/step``, ``~/step_periods``). ``~/pause`` in either
  direction ends any budget.
- :class:`SyncExchange` says, in synchronous lockstep, which command answers which published
  state, and what the node must do next: publish a state, advance one control period with the
  answer (or hold the last command), or wait.

Which command answers which state (the rules, also tabled in the reference docs):

- Every publication of a *new* state is numbered. A command stamped ``S`` (any integer, 0
  included) answers a publication stamped ``S``: the answers carrying ``S`` are counted, and the
  ``j``-th answer stamped ``S`` answers the ``j``-th publication stamped ``S`` (two publications
  share a stamp only across a reset). A command without a stamp answers by count: the ``i``-th
  unstamped answer answers publication ``i``.
- An answer to the awaited publication is taken (``answered``); a second one is a
  ``duplicate``; an answer to an earlier publication (one given up by a ``hold``, or replaced by
  a reset) is ``late``; an answer to a stamp after the awaited one, or an unstamped answer with
  no publication left to answer, is ``ahead``. Everything but the taken answer is dropped and
  counted, and never moves the count of the answers after it.
- No answer within ``sync_timeout`` (wall time while the gate is open): ``hold`` gives the
  publication up (its answer, if it comes, will be late) and advances with the last command;
  ``stop`` pauses, and the awaited state is published again when stepping resumes (``~/pause
  false`` or ``~/step``) or a controller connects (a new subscriber on ``joint_states``,
  which also resumes), so the loop goes on.
- A controller connecting while publications are owed an answer starts the count afresh at the
  next publication it can see.
- A reset publishes the reset state at the reset stamp as a new publication, awaited like any
  other; unless the awaited publication is that reset state already (published by the last
  reset, with no period taken and no live parameter applied since): then it goes on awaiting
  its answer and nothing is published, so a burst of resets sends the state once instead of
  once per reset (the answers to a burst of copies overflowed the controller's queue and the
  node's, and answers counted by number never caught up again).
- A state that cannot go out (a sensor delay still filling) is no publication: nothing awaits
  an answer, and the next period is advanced at once with the last command.

Nothing here imports rclpy; time is passed in (steady-clock ns).
"""
from __future__ import annotations

import enum
from collections import OrderedDict
from dataclasses import dataclass

from pendulum_sim.core import PendulumError

ACTIONS = ('hold', 'stop')
# Stamped answers are matched against the publications of this many recent stamps; an answer
# to an older stamp is late.
KEPT_STAMPS = 256


class StepError(PendulumError):
    """A step request cannot be taken (the message says why)."""


class Gate:
    """Whether simulated time may advance: running, or paused with a budget of periods.

    Parameters
    ----------
    paused : bool
        Start paused (nothing advances until :meth:`step` or ``pause(False)``).
    """

    def __init__(self, paused: bool = False) -> None:
        self._paused = paused
        self._budget = 0

    @property
    def paused(self) -> bool:
        """Return True while paused (a step budget may still let periods through)."""
        return self._paused

    @property
    def budget(self) -> int:
        """Return the control periods still to take while paused."""
        return self._budget

    @property
    def open(self) -> bool:
        """Return True when a control period may be taken now."""
        return not self._paused or self._budget > 0

    def pause(self, paused: bool) -> bool:
        """Pause or resume; end any step budget. Return False if nothing changed."""
        changed = paused != self._paused or self._budget > 0
        self._paused = paused
        self._budget = 0
        return changed

    def step(self, periods: int) -> None:
        """Add ``periods`` control periods to the budget; raise StepError if it cannot."""
        if not self._paused:
            raise StepError('not paused: ~/step advances a paused simulation '
                            '(call ~/pause true)')
        if periods < 1:
            raise StepError(f'the number of control periods must be >= 1, got {periods}')
        self._budget += periods

    def period_done(self) -> None:
        """Count one control period taken (from the budget, when paused)."""
        if self._paused and self._budget > 0:
            self._budget -= 1


class Verdict(enum.Enum):
    """What became of one command in synchronous mode."""

    ANSWER = 'answered'
    LATE = 'late'
    DUPLICATE = 'duplicates'
    AHEAD = 'ahead'


class Action(enum.Enum):
    """What the node must do now in synchronous mode."""

    WAIT = 'wait'              # nothing until an answer, a timeout, a step or a controller
    PUBLISH = 'publish'        # publish the state now, then call published()
    REPUBLISH = 'republish'    # publish the awaited state again, then call published()
    ADVANCE = 'advance'        # take(), apply it, advance one period, publish, published()
    HOLD = 'hold'              # a timeout: as ADVANCE, with the last command held
    STOPPED = 'stopped'        # a timeout: paused (sync_timeout_action stop)


@dataclass
class Publication:
    """A published state waiting for its answer."""

    index: int            # the count of new-state publications before this one
    step: int             # the joint's step count when it was published
    stamp_ns: int
    since_ns: int         # when the wait (re)started, steady clock
    answered: bool = False
    value: float | None = None
    reset: bool = False   # the state a reset left, the joint unchanged since


class SyncExchange:
    """Match commands to published states; say when to publish, advance, hold or stop.

    Parameters
    ----------
    gate : Gate
        The pause and step budget the exchange obeys (shared with the node).
    timeout_ns : int
        ``sync_timeout`` in ns.
    action : str
        ``sync_timeout_action``: ``'hold'`` or ``'stop'``.
    """

    def __init__(self, gate: Gate, timeout_ns: int, action: str) -> None:
        self.gate = gate
        self.timeout_ns = timeout_ns
        self.action = action
        self.stats = {v.value: 0 for v in Verdict} | {'timeouts': 0, 'republished': 0}
        self._awaiting: Publication | None = None
        self._stepping = False        # an answer was taken; the period is being advanced
        self._publications = 0        # new-state publications so far
        self._next_unstamped = 0      # the publication the next unstamped answer answers
        self._last_stamp: int | None = None
        self._stamp_pubs: OrderedDict[int, int] = OrderedDict()    # stamp -> publications
        self._stamp_answers: dict[int, int] = {}                   # stamp -> answers seen
        self._stopped = False         # paused by a timeout (stop); the state goes out again
        self._republish = False
        self._was_open = gate.open
        self._subscribers = 0

    # ------------------------------------------------------------------ state
    @property
    def awaiting(self) -> Publication | None:
        """Return the publication waiting for its answer, or None."""
        return self._awaiting

    @property
    def started(self) -> bool:
        """Return True once the first state was published."""
        return self._publications > 0

    @property
    def stepping(self) -> bool:
        """Return True while a taken answer's period is being advanced."""
        return self._stepping

    @property
    def stopped(self) -> bool:
        """Return True while paused by a ``stop`` timeout."""
        return self._stopped

    # ------------------------------------------------------------------ the driver's calls
    def poll(self, now_ns: int, ready: bool, subscribers: int = 0) -> Action:
        """Return what to do now.

        Parameters
        ----------
        now_ns : int
            Steady-clock time.
        ready : bool
            True when a controller can take part (a subscriber on the states and a publisher
            of commands are matched).
        subscribers : int
            Matched subscribers on the states: a rise means a controller connected.
        """
        gate = self.gate
        rose = subscribers > self._subscribers
        self._subscribers = subscribers
        aw = self._awaiting
        if rose and aw is not None and not aw.answered:
            if self._stopped:
                gate.pause(False)
                self._stopped = False
                self._republish = True
            elif self._next_unstamped < aw.index:
                # Owed answers will not come from a controller that just connected.
                self._next_unstamped = aw.index + 1
        is_open = gate.open
        if is_open and not self._was_open and aw is not None:
            aw.since_ns = now_ns   # a wait counts only while time may advance
        self._was_open = is_open
        if self._stepping:
            return Action.ADVANCE if is_open else Action.WAIT
        if aw is None:
            return Action.PUBLISH if ready and is_open else Action.WAIT
        if self._republish and ready and is_open:
            return Action.REPUBLISH
        if aw.answered:
            return Action.ADVANCE if is_open else Action.WAIT
        if not is_open or now_ns - aw.since_ns < self.timeout_ns:
            return Action.WAIT
        self.stats['timeouts'] += 1
        if self.action == 'stop':
            gate.pause(True)
            self._stopped = True
            self._republish = True
            self._was_open = False
            return Action.STOPPED
        return Action.HOLD

    def published(self, step: int, stamp_ns: int, now_ns: int, reset: bool = False) -> None:
        """Record that the state at ``step`` was published (after PUBLISH, REPUBLISH, a period
        or a reset: ``reset`` True); it now awaits its answer."""
        aw = self._awaiting
        if self._republish and aw is not None and aw.step == step and not aw.answered:
            # The same state again (after a stop): either copy's answer answers it, and the
            # count of unstamped answers starts at it.
            self._republish = False
            self._stopped = False
            aw.since_ns = now_ns
            self._next_unstamped = aw.index
            self.stats['republished'] += 1
            return
        self._republish = False
        self._stepping = False
        self._awaiting = Publication(self._publications, step, stamp_ns, now_ns, reset=reset)
        self._publications += 1
        self._last_stamp = stamp_ns
        pubs = self._stamp_pubs
        pubs[stamp_ns] = pubs.get(stamp_ns, 0) + 1
        pubs.move_to_end(stamp_ns)
        while len(pubs) > KEPT_STAMPS:
            old, _ = pubs.popitem(last=False)
            self._stamp_answers.pop(old, None)

    def unseen(self) -> None:
        """Record that no state went out (after PUBLISH, REPUBLISH, a period or a reset: a
        sensor delay still filling): nothing awaits an answer; the next period goes on with the
        last command (ADVANCE, without :meth:`take`)."""
        self._republish = False
        self._stopped = False
        self._stepping = True

    def answer(self, value: float, stamp_ns: int | None) -> Verdict:
        """Match a command (its stamp, or None if it has none); return what became of it."""
        verdict = (self._unstamped() if stamp_ns is None else self._stamped(stamp_ns))
        self.stats[verdict.value] += 1
        if verdict is Verdict.ANSWER:
            aw = self._awaiting
            assert aw is not None
            aw.answered = True
            aw.value = value
        return verdict

    def _unstamped(self) -> Verdict:
        i = self._next_unstamped
        if i >= self._publications:
            return Verdict.AHEAD
        self._next_unstamped = i + 1
        aw = self._awaiting
        if aw is not None and i == aw.index and not self._stepping:
            return Verdict.DUPLICATE if aw.answered else Verdict.ANSWER
        return Verdict.LATE

    def _stamped(self, stamp_ns: int) -> Verdict:
        last = self._last_stamp
        if last is None or stamp_ns > last:
            return Verdict.AHEAD
        pubs = self._stamp_pubs.get(stamp_ns, 0)
        if pubs == 0:
            return Verdict.LATE
        j = self._stamp_answers.get(stamp_ns, 0)
        self._stamp_answers[stamp_ns] = j + 1
        if j >= pubs:
            return Verdict.DUPLICATE
        aw = self._awaiting
        if (j == pubs - 1 and aw is not None and stamp_ns == aw.stamp_ns
                and not self._stepping):
            return Verdict.DUPLICATE if aw.answered else Verdict.ANSWER
        return Verdict.LATE

    def take(self) -> float | None:
        """Start the period after ADVANCE or HOLD: return the answer to apply (None: hold)."""
        aw = self._awaiting
        value = aw.value if aw is not None and aw.answered else None
        if aw is not None:
            aw.reset = False   # the joint moves on from the state it awaited
        self._stepping = True
        return value

    def reconfigured(self) -> None:
        """Record that live parameters were applied: a reset after them publishes its state
        anew, even if the awaited state is a reset's."""
        if self._awaiting is not None:
            self._awaiting.reset = False

    def period_done(self) -> None:
        """Count a period taken through the gate (call before publishing its end state)."""
        self.gate.period_done()

    def pause(self, paused: bool) -> bool:
        """Pause or resume (``~/pause``); return False if nothing changed."""
        changed = self.gate.pause(paused)
        if not paused and self._stopped:
            self._stopped = False
            changed = True
        return changed

    def step(self, periods: int) -> None:
        """Add periods to the budget (``~/step``); a stopped exchange publishes again."""
        self.gate.step(periods)
        self._stopped = False

    def reset(self) -> bool:
        """Forget the period under way (a reset); return True if the reset state must be
        published, as a new publication awaiting its answer: the exchange has started, and the
        awaited publication is not that reset state already (left by the last reset, nothing
        stepped, applied, stopped or to be published again since)."""
        aw = self._awaiting
        if (aw is not None and aw.reset and not self._stepping and not self._stopped
                and not self._republish):
            return False
        self._stepping = False
        self._republish = False
        self._stopped = False
        return self.started
