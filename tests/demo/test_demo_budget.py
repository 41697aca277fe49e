"""A page's message budget (minifilm/demo/budget.py), on a clock the test moves by hand."""
import pytest

from minifilm.demo.budget import MessageBudget


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_messages_within_the_rate_all_pass():
    clock = Clock()
    budget = MessageBudget(rate=10, clock=clock)
    for _ in range(100):              # 10 a second for 10 s
        clock.t += 0.1
        assert budget.take()
    assert budget.dropped == 0 and not budget.flooding


def test_a_burst_over_the_rate_is_dropped_with_one_warning_a_second():
    clock = Clock()
    budget = MessageBudget(rate=10, clock=clock)
    taken = [budget.take() for _ in range(15)]          # all at one instant
    assert taken == [True] * 10 + [False] * 5
    assert budget.dropped == 5 and not budget.flooding
    budget.take()
    assert not budget.should_warn                       # still the same second: said once already
    clock.t += 0.5                                      # half a second refills 5 tokens
    assert [budget.take() for _ in range(6)] == [True] * 5 + [False]
    assert not budget.should_warn
    clock.t += 0.6                                      # a new second of dropping is reported again
    [budget.take() for _ in range(6)]
    budget.take()
    assert budget.dropped > 7


def test_the_first_drop_of_a_second_asks_for_a_warning():
    clock = Clock()
    budget = MessageBudget(rate=2, clock=clock)
    budget.take(), budget.take()
    assert not budget.take() and budget.should_warn


def test_keeping_on_flooding_is_flagged():
    clock = Clock()
    budget = MessageBudget(rate=10, clock=clock)
    assert sum(budget.take() for _ in range(10 + 2 * 10)) == 10
    assert not budget.flooding                          # 20 dropped: exactly 2 x rate, not over
    budget.take()
    assert budget.flooding


def test_the_rate_must_be_positive():
    with pytest.raises(ValueError, match="rate must be positive"):
        MessageBudget(rate=0)
