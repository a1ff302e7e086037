"""PDDL export of learned operators parses with a standard parser (AI-Planning's pddl)."""

import numpy as np
import pytest

from bpns.learning.artifacts.pddl import domain_pddl, pddl_name, problem_pddl, task_problem_pddl
from bpns.structs import (
    GroundAtom,
    LiftedAtom,
    Object,
    Predicate,
    STRIPSOperator,
    Type,
    Variable,
)
from tests import toy_learning as toy

pddl_parser = pytest.importorskip("pddl.parser.domain")
problem_parser = pytest.importorskip("pddl.parser.problem")


@pytest.fixture(scope="module")
def skills():
    return toy.learned_toy_skills()


def test_learned_domain_parses(skills):
    text = domain_pddl("toycover", toy.TYPES, toy.PREDICATES, skills.operators)
    domain = pddl_parser.DomainParser()(text)
    assert {str(a.name) for a in domain.actions} == {"Holding", "Covers_HandEmpty"}
    assert {str(p.name) for p in domain.predicates} == {"Covers", "HandEmpty", "Holding"}
    assert {str(t) for t in domain.types} >= {"block", "robot", "target"}
    op1 = next(a for a in domain.actions if str(a.name) == "Covers_HandEmpty")
    assert [str(p.name) for p in op1.parameters] == ["block0", "robot0", "target0"]


def test_task_problem_parses(skills):
    task = toy.sample_task(np.random.default_rng(0))
    text = task_problem_pddl(task, toy.PREDICATES, "toycover", name="p0")
    problem = problem_parser.ProblemParser()(text)
    assert {str(o.name) for o in problem.objects} == {o.name for o in task.objects}
    assert len(problem.goal.operands) == 2


def test_empty_preconditions_nullary_predicates_and_odd_names_are_valid_pddl():
    thing = Type("my thing", ("x",))
    on = Predicate("Lights.On", (), lambda s, o: True)
    touched = Predicate("touched", (thing,), lambda s, o: True)
    v = Variable("?my thing0", thing)
    op = STRIPSOperator(
        "Op-0",
        (v,),
        frozenset(),
        frozenset({LiftedAtom(on, ())}),
        frozenset({LiftedAtom(touched, (v,))}),
    )
    text = domain_pddl("d", [thing], [on, touched], [op])
    pddl_parser.DomainParser()(text)
    assert "(:action Op-0" in text and "(Lights_On)" in text
    obj = Object("1st.obj", thing)
    problem = problem_pddl("p", "d", [obj], [GroundAtom(touched, (obj,))], [GroundAtom(on, ())])
    problem_parser.ProblemParser()(problem)
    assert "x1st_obj - my_thing" in problem


def test_names_that_collide_after_sanitising_are_rejected():
    a = Predicate("a.b", (), lambda s, o: True)
    b = Predicate("a_b", (), lambda s, o: True)
    with pytest.raises(ValueError, match="both become"):
        domain_pddl("d", [], [a, b], [])
    assert pddl_name("ok-name_1") == "ok-name_1"
