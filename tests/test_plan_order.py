"""Which of several equally short plans the planner gives, pinned: the order is what a
robot carries out, so it is part of what users see. ``_moves`` (planning/plan.py) lists
the moves from a state in a fixed order, unfolds first, so that of two equally short
plans the one through fewer folds at once is taken, and a fourth corner is never folded
onto three smaller flaps. One test per rule, and the plans of the pairs where the order
decides."""

from __future__ import annotations

from functools import lru_cache
from itertools import pairwise

import pytest

from dgli_vision.core.fold_graph import folds_of, state_keys
from dgli_vision.planning.plan import _moves, shortest_path

STATES = state_keys()
BY_FOLDS = {folds_of(*k): k for k in STATES}


def steps(start, goal):
    """The plan as (action, fold) pairs."""
    return [(action, word) for action, word, _ in shortest_path(start, goal)]


@lru_cache(maxsize=1)
def every_plan():
    """(start, goal, plan) for every pair of the 44 states (1936, all reachable)."""
    return tuple((start, goal, shortest_path(start, goal)) for start in STATES for goal in STATES)


def test_moves_are_in_a_fixed_order_each_kind_in_state_order():
    # rule 1, "in a fixed order": within the unfolds and within the folds, by the state
    # each leads to, in class then variant order
    assert _moves(("06", "AC")) == [
        ("unfold", "C over", ("02", "A")),
        ("unfold", "A over", ("02", "C")),
        ("fold", "D over", ("07", "B")),
        ("fold", "B over", ("07", "D")),
    ]
    for key in STATES:
        moves = _moves(key)
        assert moves == _moves(key)
        for kind in ("unfold", "fold"):
            after = [STATES.index(nxt) for action, _, nxt in moves if action == kind]
            assert after == sorted(after), (key, kind)
    # so among plans equal in every other way the first in state order is taken: from
    # 06/AC to 06/BD, C is unfolded first (leaving 02/A, before 02/C), B folded first
    assert steps(("06", "AC"), ("06", "BD")) == [
        ("unfold", "C over"),
        ("unfold", "A over"),
        ("fold", "B over"),
        ("fold", "D over"),
    ]
    assert steps(("01", None), ("04", "DA")) == [("fold", "A over"), ("fold", "D over")]


def test_moves_list_every_unfold_before_every_fold():
    # rule 2, "unfolds first"
    assert _moves(("02", "A")) == [
        ("unfold", "A over", ("01", None)),
        ("fold", "B over", ("04", "AB")),
        ("fold", "D over", ("04", "DA")),
        ("fold", "B over crossing A", ("05", "AB/B")),
        ("fold", "D over crossing A", ("05", "DA/D")),
        ("fold", "C over", ("06", "AC")),
    ]
    for key in STATES:
        kinds = [action for action, _, _ in _moves(key)]
        assert kinds == sorted(kinds, key=lambda k: k == "fold"), key


@pytest.mark.parametrize(
    ("start", "goal", "plan"),
    [
        (("02", "A"), ("02", "B"), [("unfold", "A over"), ("fold", "B over")]),
        (("02", "D"), ("02", "C"), [("unfold", "D over"), ("fold", "C over")]),
        (("04", "AB"), ("04", "BC"), [("unfold", "A over"), ("fold", "C over")]),
        (("04", "AB"), ("06", "BD"), [("unfold", "A over"), ("fold", "D over")]),
        (("06", "AC"), ("04", "CD"), [("unfold", "A over"), ("fold", "D over")]),
    ],
)
def test_of_two_equally_short_plans_the_one_through_fewer_folds_is_taken(start, goal, plan):
    # rule 3: 02/A -> 02/B through the flat napkin (no fold), not through 04/AB (two);
    # 04/AB -> 04/BC through 02/B, not through 07/D (three)
    assert steps(start, goal) == plan
    # where nothing is to choose, the plan is the one there is
    assert steps(("03", "A"), ("02", "A")) == [("unfold", "A under"), ("fold", "A over")]


def test_no_plan_folds_and_then_unfolds_where_the_other_order_exists():
    # rule 3 over all 1936 plans: a fold followed at once by an unfold is never taken
    # where unfolding first, then folding, passes through a state with fewer folds
    swappable = []
    for start, goal, plan in every_plan():
        here = folds_of(*start)
        for (a1, w1, _), (a2, w2, _) in pairwise(plan):
            if a1 == "fold" and a2 == "unfold":
                between = here - {w2}
                if between in BY_FOLDS and between | {w1} in BY_FOLDS:
                    swappable.append((start, goal, w1, w2))
            here = here | {w1} if a1 == "fold" else here - {w1}
    assert swappable == []


def test_a_fourth_corner_is_never_folded_onto_three_smaller_flaps():
    # rule 4: 08 reached from 07 leaves more table covered than 08 allows; no plan passes
    # through 08 on its way to another state
    assert steps(("07", "A"), ("07", "B")) == [("unfold", "B over"), ("fold", "A over")]
    through = [
        (start, goal)
        for start, goal, plan in every_plan()
        if ("08", None) in [state for _, _, state in plan[:-1]]
    ]
    assert through == []


# the first flap of two crossing ones has the crossing class's longer legs: the second
# is unfolded, then the first (a corner-over flap beside it would cross it), then the
# four corners are folded in state order
TO_FOUR = [("fold", "A over"), ("fold", "B over"), ("fold", "D over"), ("fold", "C over")]


@pytest.mark.parametrize(
    ("variant", "top", "first"),
    [
        ("AB/A", "A", "B"), ("AB/B", "B", "A"), ("BC/B", "B", "C"), ("BC/C", "C", "B"),
        ("CD/C", "C", "D"), ("CD/D", "D", "C"), ("DA/D", "D", "A"), ("DA/A", "A", "D"),
    ],
)
def test_the_plans_from_two_crossing_flaps_to_four_corners(variant, top, first):
    assert steps(("05", variant), ("08", None)) == [
        ("unfold", f"{top} over crossing {first}"),
        ("unfold", f"{first} over"),
        *TO_FOUR,
    ]
