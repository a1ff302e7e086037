"""Named eval sets and object counts (issue 38): the texts users type, what an
environment that declares nothing allows, and the checks against declared limits."""

from __future__ import annotations

import dataclasses

import pytest

from bpns.env.environment import Capabilities, eval_environment, eval_set_of
from bpns.env.object_counts import PAPER_SET, EvalSet, ObjectCountError, ObjectCounts


def test_counts_parse_single_values_ranges_and_comma_lists():
    counts = ObjectCounts.parse(["button=6", "cup=4:6,pot=1"])
    assert counts.as_dict() == {"button": (6, 6), "cup": (4, 6), "pot": (1, 1)}
    assert ObjectCounts.parse(counts.text()) == counts  # the text form round-trips


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("button", "expected KIND=N or KIND=LO:HI"),
        ("=3", "expected KIND=N or KIND=LO:HI"),
        ("button=x", "expected a whole number"),
        ("button=2:y", "expected a whole number"),
        ("button=5:3", "low 5 exceeds high 3"),
        ("button=-1", "must be >= 0"),
        ("button=3,button=4", "given twice"),
    ],
)
def test_malformed_count_texts_are_one_clear_error(text, message):
    with pytest.raises(ObjectCountError, match=message):
        ObjectCounts.parse(text)


def test_overrides_replace_only_the_kinds_they_name():
    base = ObjectCounts.of({"button": (5, 8), "stick": 1})
    assert base.updated(ObjectCounts.parse("button=6")).as_dict() == {
        "button": (6, 6),
        "stick": (1, 1),
    }


def test_eval_sets_round_trip_through_json_and_say_what_they_are():
    chosen = EvalSet("large", ObjectCounts.parse("button=6"))
    assert EvalSet.from_json(chosen.to_json()) == chosen
    assert chosen.label() == "large, button=6" and not chosen.is_paper
    assert PAPER_SET.is_paper and PAPER_SET.label() == "paper"


class _Plain:
    """An environment that declares nothing about object counts (today's plugins)."""

    name = "plain"
    capabilities = Capabilities()


def test_an_environment_declaring_nothing_has_only_the_paper_set():
    env = _Plain()
    assert eval_environment(env) is env
    assert eval_environment(env, "paper") is env
    with pytest.raises(ObjectCountError, match="no eval set 'large'; known: paper"):
        eval_set_of(env, "large")
    with pytest.raises(ObjectCountError, match="declare no with_objects"):
        eval_set_of(env, objects=ObjectCounts.parse("block=3"))


class _Declaring:
    name = "declaring"
    capabilities = Capabilities(
        eval_sets={"large": ObjectCounts.of({"block": (3, 4)})},
        object_limits={"block": (1, 4)},
        with_objects=lambda env, counts: dataclasses.replace(_Copy(), counts=counts),
    )


@dataclasses.dataclass(frozen=True)
class _Copy:
    counts: ObjectCounts = ObjectCounts()


def test_a_declared_set_and_overrides_reach_with_objects_within_the_limits():
    env = _Declaring()
    assert eval_environment(env, "large").counts.as_dict() == {"block": (3, 4)}
    over = eval_environment(env, "large", ObjectCounts.parse("block=2"))
    assert over.counts.as_dict() == {"block": (2, 2)}
    with pytest.raises(ObjectCountError, match=r"block=9: declaring scenes hold 1\.\.4"):
        eval_set_of(env, objects=ObjectCounts.parse("block=9"))
    with pytest.raises(ObjectCountError, match="no object kind 'cup'; kinds: block"):
        eval_set_of(env, objects=ObjectCounts.parse("cup=2"))


def test_the_paper_set_cannot_be_declared_again():
    with pytest.raises(ValueError, match="paper"):
        Capabilities(eval_sets={"paper": ObjectCounts()})
