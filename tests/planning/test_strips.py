import time

import numpy as np
import pytest

from bpns.env.abstraction import abstract
from bpns.planning.strips import GroundProblem, SearchTimeout, ground
from bpns.structs import GroundAtom, LiftedAtom, Object, Predicate, STRIPSOperator, Type, Variable
from tests import toy_planning as toy


def _stick_problem(ops, button_xs=(2.0, 8.0)):
    env = toy.ToyStickButton()
    task = toy.make_task(list(button_xs))
    init = abstract(task.init, env.predicates)
    return ground(ops, task.objects, init, task.goal), task


def test_operators_whose_preconditions_are_unreachable_are_never_grounded():
    p, _ = _stick_problem([toy.PRESS_DIRECT, toy.PRESS_WITH_STICK])  # nothing achieves Holding
    assert {o.name for o in p.operators} == {"PressDirect"}
    assert len(p.operators) == 2  # one per button


def test_reachability_follows_chains_of_operators():
    p, _ = _stick_problem([toy.PRESS_DIRECT, toy.PRESS_WITH_STICK, toy.PICK_STICK, toy.PLACE_STICK])
    names = sorted(str(o) for o in p.operators)
    assert names == [
        "PickStick(robot, stick)",
        "PlaceStick(robot, stick)",
        "PressDirect(robot, button0)",
        "PressDirect(robot, button1)",
        "PressWithStick(robot, stick, button0)",
        "PressWithStick(robot, stick, button1)",
    ]


def test_grounding_binds_distinct_objects_of_the_right_type():
    t = Type("t", ("v",))
    u = Type("u", ("v",))
    x, y = Variable("?x", t), Variable("?y", t)
    z = Variable("?z", u)
    pair = STRIPSOperator("Pair", (x, y, z), frozenset(), frozenset(), frozenset())
    objs = [Object(f"o{i}", t) for i in range(3)] + [Object("w", u)]
    p = ground([pair], objs, set(), set())
    bindings = {tuple(o.name for o in g.objects) for g in p.operators}
    assert len(bindings) == 6
    assert all(a != b and c == "w" for a, b, c in bindings)


def test_parameters_bound_through_preconditions_stay_consistent_across_atoms():
    t = Type("t", ("v",))
    edge = Predicate("Edge", (t, t), lambda s, o: False)
    at = Predicate("At", (t,), lambda s, o: False)
    a, b = Variable("?a", t), Variable("?b", t)
    move = STRIPSOperator(
        "Move",
        (a, b),
        frozenset({LiftedAtom(at, (a,)), LiftedAtom(edge, (a, b))}),
        frozenset({LiftedAtom(at, (b,))}),
        frozenset({LiftedAtom(at, (a,))}),
    )
    n = [Object(f"n{i}", t) for i in range(4)]
    init = {
        GroundAtom(at, (n[0],)),
        GroundAtom(edge, (n[0], n[1])),
        GroundAtom(edge, (n[1], n[2])),
        GroundAtom(edge, (n[3], n[0])),
    }
    p = ground([move], n, init, {GroundAtom(at, (n[2],))})
    assert sorted(str(o) for o in p.operators) == ["Move(n0, n1)", "Move(n1, n2)"]


def test_successors_match_ground_operator_semantics():
    p, _ = _stick_problem([toy.PRESS_DIRECT, toy.PRESS_WITH_STICK, toy.PICK_STICK, toy.PLACE_STICK])
    init_atoms = p.decode(p.init)
    for i, nxt in p.successors(p.init):
        g = p.operators[i]
        assert g.applicable(init_atoms)
        assert p.decode(nxt) == g.apply(init_atoms)
    applicable = {p.operators[i].name for i in p.applicable(p.init)}
    assert applicable == {"PressDirect", "PickStick"}


def test_encode_decode_round_trip_and_unknown_atoms_are_ignored():
    p, task = _stick_problem([toy.PRESS_DIRECT])
    atoms = p.decode(p.init)
    assert p.encode(atoms) == p.init
    other = GroundAtom(Predicate("Other", (), lambda s, o: True), ())
    assert p.encode(atoms | {other}) == p.init
    assert not p.is_goal(p.init)
    assert p.is_goal(p.encode(task.goal))


def test_ground_operators_are_in_a_deterministic_order():
    ops = [toy.PLACE_STICK, toy.PRESS_WITH_STICK, toy.PICK_STICK, toy.PRESS_DIRECT]
    a, _ = _stick_problem(ops)
    b, _ = _stick_problem(list(reversed(ops)))
    assert [str(o) for o in a.operators] == [str(o) for o in b.operators]


def test_grounding_obeys_its_deadline():
    with pytest.raises(SearchTimeout):
        _ = ground(
            [toy.TURN_ON, toy.TURN_OFF],
            toy.lights(5),
            set(),
            set(),
            deadline=time.monotonic() - 1.0,
        )


def test_from_ground_operators_keeps_given_operator_order():
    ops = [toy.op("b", [], ["x"]), toy.op("a", ["x"], ["g"])]
    p = GroundProblem.from_ground_operators(ops, set(), {toy.atom("g")})
    assert [o.name for o in p.operators] == ["b", "a"]
    assert p.n_atoms == 2
    assert np.all([p.pre[1] == 1 << p.index[toy.atom("x")]])


def test_grounding_orders_operators_by_their_order_key_so_renaming_keeps_plans():
    import dataclasses

    ops = [toy.PRESS_DIRECT, toy.PRESS_WITH_STICK, toy.PICK_STICK, toy.PLACE_STICK]
    before, _ = _stick_problem(ops)
    # new names sort the other way round; the old names stay as order keys
    renamed = [
        dataclasses.replace(op, name=f"Z{9 - k}", order_key=op.name) for k, op in enumerate(ops)
    ]
    after, _ = _stick_problem(renamed)
    assert [(o.operator.order_key, o.objects) for o in after.operators] == [
        (o.name, o.objects) for o in before.operators
    ]


def _naive_ground(operators, objects, init_atoms, goal):
    """The reference: every pass enumerates every binding again, until nothing is new."""
    from bpns.planning.strips import _bindings

    by_type: dict = {}
    for o in sorted(objects):
        by_type.setdefault(o.type, []).append(o)
    reached = set(init_atoms)
    by_pred: dict = {}
    for a in sorted(reached):
        by_pred.setdefault(a.predicate, []).append(a.objects)
    found: set = set()
    changed = True
    while changed:
        changed = False
        for op in operators:
            for objs in list(_bindings(op, by_pred, by_type, None)):
                g = op.ground(objs)
                found.add(g)
                for a in sorted(g.add_effects - reached):
                    reached.add(a)
                    by_pred.setdefault(a.predicate, []).append(a.objects)
                    changed = True
    return found


@pytest.mark.parametrize("seed", range(6))
def test_grounding_reaches_the_same_operators_as_enumerating_every_binding_each_pass(seed):
    """Rooms linked at random, doors to unlock with keys found in rooms: joins whose
    preconditions become reachable in different passes (the semi-naive fixpoint)."""
    rng = np.random.default_rng(seed)
    room, key = Type("room", ("v",)), Type("key", ("v",))
    r1, r2, k = Variable("?a", room), Variable("?b", room), Variable("?k", key)
    at, link, lies, has, opened = (
        Predicate("At", (room,), lambda s, o: False),
        Predicate("Link", (room, room), lambda s, o: False),
        Predicate("KeyIn", (key, room), lambda s, o: False),
        Predicate("Has", (key,), lambda s, o: False),
        Predicate("Unlocked", (room, room), lambda s, o: False),
    )
    ops = [
        STRIPSOperator(
            "Move",
            (r1, r2),
            frozenset({LiftedAtom(at, (r1,)), LiftedAtom(opened, (r1, r2))}),
            frozenset({LiftedAtom(at, (r2,))}),
            frozenset({LiftedAtom(at, (r1,))}),
        ),
        STRIPSOperator(
            "Unlock",
            (r1, r2, k),
            frozenset({LiftedAtom(at, (r1,)), LiftedAtom(link, (r1, r2)), LiftedAtom(has, (k,))}),
            frozenset({LiftedAtom(opened, (r1, r2))}),
            frozenset(),
        ),
        STRIPSOperator(
            "Take",
            (k, r1),
            frozenset({LiftedAtom(at, (r1,)), LiftedAtom(lies, (k, r1))}),
            frozenset({LiftedAtom(has, (k,))}),
            frozenset(),
        ),
    ]
    rooms = [Object(f"r{i}", room) for i in range(9)]
    keys = [Object(f"k{i}", key) for i in range(3)]
    init = {GroundAtom(at, (rooms[0],)), GroundAtom(lies, (keys[0], rooms[0]))}
    for i, a in enumerate(rooms):
        for b in rooms[i + 1 :]:
            if rng.random() < 0.35:
                init |= {GroundAtom(link, (a, b)), GroundAtom(link, (b, a))}
    for kk in keys[1:]:
        init.add(GroundAtom(lies, (kk, rooms[int(rng.integers(1, 9))])))
    goal = {GroundAtom(at, (rooms[-1],))}
    problem = ground(ops, rooms + keys, init, goal)
    assert set(problem.operators) == _naive_ground(ops, rooms + keys, init, goal)
    assert len(problem.operators) > 3
