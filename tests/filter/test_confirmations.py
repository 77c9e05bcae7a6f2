"""The count of searches that confirm the filter's place after a jump
(mcl.filter.confirmations): a worse rival neither counts nor breaks the row."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.confirmations import SearchConfirmations

WORSE, AS_WELL, BETTER = -1, 0, 1


def test_a_search_settled_on_a_worse_place_between_two_agreements_leaves_the_row_whole() -> None:
    count = SearchConfirmations(needed=2)
    assert not count.agreed()
    count.settled_elsewhere(WORSE)
    assert count.agreed()  # the second in a row


def test_a_place_that_fits_as_well_or_better_breaks_the_row() -> None:
    for verdict in (AS_WELL, BETTER):
        count = SearchConfirmations(needed=2)
        assert not count.agreed()
        count.settled_elsewhere(verdict)
        assert not count.agreed()  # counted from one again
        assert count.agreed()


def test_a_restart_breaks_the_row_and_zero_needed_never_confirms() -> None:
    count = SearchConfirmations(needed=2)
    count.agreed()
    count.restart()
    assert not count.agreed()
    never = SearchConfirmations(needed=0)
    assert not any(never.agreed() for _ in range(10))


EVENTS = st.lists(st.sampled_from(["agree", "as_well", "better", "restart"]), max_size=30)


def _answers(count: SearchConfirmations, events: list[str], worse_before: list[int]) -> list[bool]:
    """agreed()'s answers over ``events``, with ``worse_before[i]`` worse rivals before event i."""
    answers = []
    for event, worse in zip(events, worse_before, strict=True):
        for _ in range(worse):
            count.settled_elsewhere(WORSE)
        if event == "agree":
            answers.append(count.agreed())
        elif event == "restart":
            count.restart()
        else:
            count.settled_elsewhere(AS_WELL if event == "as_well" else BETTER)
    return answers


@settings(max_examples=200)
@given(events=EVENTS, needed=st.integers(0, 4), data=st.data())
def test_worse_rivals_anywhere_change_no_answer(events, needed, data) -> None:
    worse = data.draw(st.lists(st.integers(0, 3), min_size=len(events), max_size=len(events)))
    plain = _answers(SearchConfirmations(needed), events, [0] * len(events))
    assert _answers(SearchConfirmations(needed), events, worse) == plain


@given(agreements=st.integers(1, 12), needed=st.integers(1, 6))
def test_a_row_confirms_exactly_from_the_needed_agreement_on(agreements, needed) -> None:
    count = SearchConfirmations(needed)
    answers = [count.agreed() for _ in range(agreements)]
    assert answers == [i + 1 >= needed for i in range(agreements)]
