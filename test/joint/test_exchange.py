"""The synchronous exchange and the pause gate without ROS: one test per rule."""
from __future__ import annotations

import re

import pytest

from pendulum_sim.joint.exchange import Action, Gate, StepError, SyncExchange, Verdict

MS = 1_000_000
PERIOD = 10 * MS            # stamps of a 10 ms control period
TIMEOUT = 1000 * MS


class Loop:
    """Drive an exchange as the node does, with a joint that is only a step counter."""

    def __init__(self, action: str = 'hold', paused: bool = False) -> None:
        self.gate = Gate(paused)
        self.ex = SyncExchange(self.gate, TIMEOUT, action)
        self.step = 0          # periods of the joint
        self.now = 0
        self.applied: list[tuple[int, float | None]] = []   # (period, command)
        self.published: list[int] = []                       # stamps, in order

    def publish(self) -> None:
        self.published.append(self.step * PERIOD)
        self.ex.published(self.step, self.step * PERIOD, self.now)

    def run(self, ready: bool = True, subscribers: int = 1, dt: int = 0) -> Action:
        """One wake of the driver: act on what the exchange says; return the action."""
        self.now += dt
        action = self.ex.poll(self.now, ready, subscribers)
        if action in (Action.PUBLISH, Action.REPUBLISH):
            self.publish()
        elif action in (Action.ADVANCE, Action.HOLD):
            self.applied.append((self.step, self.ex.take()))
            self.step += 1
            self.ex.period_done()
            self.publish()
        return action

    def settle(self) -> None:
        """Wake until the exchange waits."""
        while self.run() is not Action.WAIT:
            pass

    def send(self, value: float, stamp: int | None) -> Verdict:
        verdict = self.ex.answer(value, stamp)
        self.settle()
        return verdict


def test_nothing_is_published_until_a_controller_is_ready() -> None:
    loop = Loop()
    assert loop.run(ready=False) is Action.WAIT
    assert loop.published == []
    assert loop.run() is Action.PUBLISH
    assert loop.published == [0]


def test_each_state_is_answered_by_its_stamped_command_and_stamp_0_is_a_stamp() -> None:
    loop = Loop()
    loop.settle()
    assert loop.send(1.5, 0) is Verdict.ANSWER          # stamp 0 answers state 0
    assert loop.send(1.5, 0) is Verdict.DUPLICATE       # a second copy is not state 1's answer
    assert loop.published == [0, PERIOD]
    assert loop.send(2.5, PERIOD) is Verdict.ANSWER
    assert loop.applied == [(0, 1.5), (1, 2.5)]
    assert loop.ex.stats == {'answered': 2, 'late': 0, 'duplicates': 1, 'ahead': 0,
                             'timeouts': 0, 'republished': 0}


def test_a_stamp_after_the_awaited_state_is_ahead_and_dropped() -> None:
    loop = Loop()
    loop.settle()
    assert loop.send(9.0, PERIOD) is Verdict.AHEAD
    assert loop.applied == []
    assert loop.send(1.0, 0) is Verdict.ANSWER


def test_unstamped_answers_are_counted_per_published_state() -> None:
    loop = Loop()
    loop.settle()
    for k in range(3):
        assert loop.send(float(k), None) is Verdict.ANSWER
    assert loop.applied == [(0, 0.0), (1, 1.0), (2, 2.0)]
    # An unstamped answer with no state left to answer is ahead, and takes no place in the
    # count: the next one still answers the awaited state.
    loop.ex.pause(True)
    loop.settle()
    assert loop.ex.answer(7.0, None) is Verdict.ANSWER
    assert loop.ex.answer(8.0, None) is Verdict.AHEAD
    loop.ex.pause(False)
    loop.settle()
    assert loop.send(4.0, None) is Verdict.ANSWER
    assert loop.applied[-2:] == [(3, 7.0), (4, 4.0)]


def test_a_timeout_holds_the_last_command_and_its_late_answer_never_shifts_the_rest() -> None:
    loop = Loop('hold')
    loop.settle()
    assert loop.send(1.0, None) is Verdict.ANSWER            # state 0
    assert loop.run(dt=TIMEOUT - 1) is Action.WAIT            # state 1: not yet
    assert loop.run(dt=1) is Action.HOLD                      # state 1 given up, state 2 out
    assert loop.applied == [(0, 1.0), (1, None)]
    assert loop.send(2.0, None) is Verdict.LATE               # state 1's answer, late: dropped
    assert loop.send(3.0, None) is Verdict.ANSWER             # state 2's answer, on time
    assert loop.send(4.0, None) is Verdict.ANSWER             # state 3's
    assert loop.applied == [(0, 1.0), (1, None), (2, 3.0), (3, 4.0)]
    # The same with stamps.
    assert loop.run(dt=TIMEOUT) is Action.HOLD                # state 4 given up
    assert loop.send(5.0, 4 * PERIOD) is Verdict.LATE
    assert loop.send(6.0, 5 * PERIOD) is Verdict.ANSWER
    assert loop.applied[-2:] == [(4, None), (5, 6.0)]
    assert loop.ex.stats['timeouts'] == 2 and loop.ex.stats['late'] == 2


def test_an_answer_to_a_stamp_never_published_before_the_awaited_one_is_late() -> None:
    loop = Loop()
    loop.settle()
    loop.send(1.0, 0)
    assert loop.send(1.0, 3 * MS) is Verdict.LATE    # not on the grid of published states


def test_a_controller_connecting_after_timeouts_is_counted_from_what_it_sees() -> None:
    loop = Loop('hold')
    loop.settle()
    loop.send(1.0, None)                                      # state 0 answered
    loop.run(dt=TIMEOUT, subscribers=0)                       # the controller died: hold
    loop.run(dt=TIMEOUT, subscribers=0)                       # and again
    # A new controller subscribes; the awaited state went out before it could see it.
    assert loop.run(subscribers=1) is Action.WAIT
    assert loop.run(dt=TIMEOUT) is Action.HOLD
    assert loop.send(2.0, None) is Verdict.ANSWER             # its first answer, on time
    assert loop.applied[-1] == (loop.step - 1, 2.0)


def test_pause_true_ends_any_step_budget() -> None:
    gate = Gate(paused=True)
    gate.step(4294967295)
    assert gate.open
    assert gate.pause(True)            # changed: the budget is gone
    assert not gate.open and gate.budget == 0
    assert not gate.pause(True)        # already paused, nothing to stop


def test_pause_false_ends_the_budget_and_runs() -> None:
    gate = Gate(paused=True)
    gate.step(3)
    assert gate.pause(False)
    assert gate.open and gate.budget == 0
    assert not gate.pause(False)


@pytest.mark.parametrize(('paused', 'periods', 'message'), [
    (False, 1, 'not paused: ~/step advances a paused simulation (call ~/pause true)'),
    (True, 0, 'the number of control periods must be >= 1, got 0'),
    (True, -3, 'the number of control periods must be >= 1, got -3'),
])
def test_a_step_that_cannot_be_taken_says_why(paused: bool, periods: int, message: str) -> None:
    gate = Gate(paused)
    with pytest.raises(StepError, match=f'^{re.escape(message)}$'):
        gate.step(periods)


def test_the_budget_lets_exactly_n_periods_through_and_publishes_the_last_state() -> None:
    loop = Loop(paused=True)
    assert loop.run() is Action.WAIT                          # paused: nothing published
    loop.ex.step(3)
    loop.settle()
    for k in range(3):
        loop.send(float(k), k * PERIOD)
    # Three periods taken; the state after them is out and its answer held until a step.
    assert [s for s, _ in loop.applied] == [0, 1, 2]
    assert loop.published == [0, PERIOD, 2 * PERIOD, 3 * PERIOD]
    assert loop.send(9.0, 3 * PERIOD) is Verdict.ANSWER
    assert len(loop.applied) == 3
    loop.ex.step(1)
    loop.settle()
    assert loop.applied[-1] == (3, 9.0)


def test_no_timeout_while_paused_and_the_wait_restarts_when_stepping_resumes() -> None:
    loop = Loop(paused=True)
    loop.ex.step(1)
    loop.settle()
    loop.send(1.0, 0)                                         # budget spent; state 1 out
    assert loop.run(dt=10 * TIMEOUT) is Action.WAIT           # paused: no timeout
    loop.ex.step(1)
    assert loop.run(dt=1) is Action.WAIT                      # the wait starts now
    assert loop.run(dt=TIMEOUT - 1) is Action.WAIT
    assert loop.run(dt=1) is Action.HOLD


def test_stop_pauses_then_publishes_the_awaited_state_again_when_stepping_resumes() -> None:
    loop = Loop('stop')
    loop.settle()
    loop.send(1.0, None)
    assert loop.run(dt=TIMEOUT) is Action.STOPPED
    assert loop.gate.paused and loop.ex.stopped
    assert loop.run(dt=10 * TIMEOUT) is Action.WAIT           # stopped: nothing more
    assert loop.ex.stats['timeouts'] == 1
    assert loop.ex.pause(False)                               # ~/pause false
    assert loop.run() is Action.REPUBLISH
    assert loop.published == [0, PERIOD, PERIOD]
    assert loop.send(2.0, None) is Verdict.ANSWER             # the new controller's answer
    assert loop.applied == [(0, 1.0), (1, 2.0)]
    assert loop.ex.stats['republished'] == 1


def test_stop_recovers_through_step() -> None:
    loop = Loop('stop')
    loop.settle()
    loop.run(dt=TIMEOUT)
    loop.ex.step(2)
    assert loop.run() is Action.REPUBLISH
    assert loop.send(1.0, 0) is Verdict.ANSWER
    assert loop.send(2.0, PERIOD) is Verdict.ANSWER
    assert loop.applied == [(0, 1.0), (1, 2.0)]
    assert loop.gate.paused and loop.gate.budget == 0


def test_stop_recovers_when_a_controller_connects() -> None:
    loop = Loop('stop')
    loop.settle()
    loop.run(dt=TIMEOUT, subscribers=1)
    assert loop.run(subscribers=0) is Action.WAIT             # the controller is gone
    assert loop.run(subscribers=1) is Action.REPUBLISH        # a new one: the loop goes on
    assert not loop.gate.paused
    assert loop.send(1.0, None) is Verdict.ANSWER
    assert loop.applied == [(0, 1.0)]


def test_a_reset_is_a_new_publication_at_the_same_stamp() -> None:
    loop = Loop()
    loop.settle()
    loop.send(1.0, 0)
    assert loop.ex.reset()                  # started: publish the reset state
    loop.publish()                          # at the same stamp (the step count goes on)
    assert loop.published == [0, PERIOD, PERIOD]
    assert loop.ex.answer(5.0, PERIOD) is Verdict.LATE     # the answer to the old state
    assert loop.send(2.0, PERIOD) is Verdict.ANSWER        # the reset state's answer
    assert loop.applied == [(0, 1.0), (1, 2.0)]
    # Unstamped: the old state's answer is late, the next answers the reset state.
    loop = Loop()
    loop.settle()
    loop.send(1.0, None)
    loop.send(2.0, None)
    assert loop.ex.reset()
    loop.publish()
    assert loop.ex.answer(7.0, None) is Verdict.LATE
    assert loop.send(8.0, None) is Verdict.ANSWER
    assert loop.applied == [(0, 1.0), (1, 2.0), (2, 8.0)]


def test_a_reset_while_its_state_awaits_its_answer_publishes_nothing_more() -> None:
    # A burst of resets sends the reset state once: answers to 200 copies overflowed the
    # controller's queue and the node's, and the count of unstamped answers never caught up.
    loop = Loop()
    loop.settle()
    loop.send(1.0, None)
    assert loop.ex.reset()
    loop.ex.published(loop.step, loop.step * PERIOD, loop.now, reset=True)
    assert not any(loop.ex.reset() for _ in range(199))
    assert loop.published == [0, PERIOD]              # the Loop's own publications
    assert loop.send(9.0, None) is Verdict.LATE       # the answer to the state replaced
    assert loop.send(2.0, None) is Verdict.ANSWER     # the one answer to the one reset state
    assert loop.send(3.0, None) is Verdict.ANSWER
    assert loop.applied == [(0, 1.0), (1, 2.0), (2, 3.0)]
    assert loop.ex.stats['late'] == 1
    # Stamped: the reset stamp has one publication more, not 200.
    loop = Loop()
    loop.settle()
    loop.send(1.0, 0)
    assert loop.ex.reset()
    loop.ex.published(loop.step, PERIOD, loop.now, reset=True)
    assert not loop.ex.reset()
    assert loop.send(9.0, PERIOD) is Verdict.LATE     # the state replaced
    assert loop.send(2.0, PERIOD) is Verdict.ANSWER   # the reset state, its one publication
    assert loop.send(2.0, PERIOD) is Verdict.DUPLICATE
    assert loop.applied == [(0, 1.0), (1, 2.0)]


@pytest.mark.parametrize('between', ['period', 'parameters', 'stop'])
def test_a_reset_after_the_joint_moved_or_changed_publishes_its_state_anew(
        between: str) -> None:
    loop = Loop('stop')
    loop.settle()
    assert loop.ex.reset()
    loop.ex.published(loop.step, loop.step * PERIOD, loop.now, reset=True)
    if between == 'period':
        assert loop.send(9.0, None) is Verdict.LATE   # the state replaced
        assert loop.send(1.0, None) is Verdict.ANSWER  # a period taken since
    elif between == 'parameters':
        loop.ex.reconfigured()                        # a new phi0 may apply to this reset
    else:
        assert loop.run(dt=TIMEOUT) is Action.STOPPED  # stopped: to be published again
    assert loop.ex.reset()


def test_a_reset_before_the_loop_started_publishes_nothing() -> None:
    loop = Loop()
    assert not loop.ex.reset()


def test_answers_while_a_period_is_advanced_are_late() -> None:
    loop = Loop()
    loop.settle()
    loop.ex.answer(1.0, 0)
    assert loop.ex.poll(0, True, 1) is Action.ADVANCE
    assert loop.ex.take() == 1.0
    assert loop.ex.stepping
    assert loop.ex.answer(2.0, 0) is Verdict.DUPLICATE
    assert loop.ex.answer(3.0, None) is Verdict.LATE


def test_a_state_that_cannot_go_out_awaits_nothing_and_the_period_goes_on_at_once() -> None:
    """A sensor delay still filling: no state is published, so no answer can come."""
    ex = SyncExchange(Gate(), TIMEOUT, 'stop')
    assert ex.poll(0, True, 1) is Action.PUBLISH
    ex.unseen()
    assert ex.awaiting is None and not ex.started and ex.stepping
    assert ex.answer(1.0, None) is Verdict.AHEAD           # nothing was published to answer
    assert ex.poll(0, True, 1) is Action.ADVANCE           # not after sync_timeout
    ex.period_done()
    ex.published(1, PERIOD, 0)
    assert ex.answer(2.0, None) is Verdict.ANSWER          # the first state that went out
    assert ex.poll(0, True, 1) is Action.ADVANCE and ex.take() == 2.0
    ex.period_done()
    ex.unseen()                                            # the next one cannot go out
    assert ex.answer(3.0, None) is Verdict.AHEAD
    assert ex.answer(3.0, PERIOD) is Verdict.LATE
    assert ex.poll(0, True, 1) is Action.ADVANCE
    assert ex.stats == {'answered': 1, 'late': 1, 'duplicates': 0, 'ahead': 2, 'timeouts': 0,
                        'republished': 0}
