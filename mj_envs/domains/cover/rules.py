"""Cover in 3D: put blocks over target pads on a line across the table (paper App. A.1).

Rules (final, as simulated):

* Two blocks (free bodies, 4.5 cm deep along x, 4 cm tall, 6-10 cm wide along y, 0.1 kg)
  and two flat target pads (3-5 cm wide, decoration only) lie on the line x = 0.5 m,
  y in [-0.3, 0.3]. The Panda's fingers close along x, so a block can be gripped anywhere
  along its width: the grasp offset is a continuous choice.
* Allowed regions (yellow strips) are the blocks' initial spans and +-1 cm around each
  target's centre. The finger command is *ignored* unless the gripper centre is inside a
  region (within 5 cm of the line in x). So a block can only be released over a target
  with the hand within 1 cm of the target's centre, and the grasp offset chosen at pick
  time decides whether the released block can cover the target (the paper's KD1).
* Covers(block, target): the block rests on the table (contact with the table), is not
  held, is within 1.5 cm of the line and its y-extent contains the target's.
  Holding(block): both finger pads touch the block (MuJoCo contact list).
  HandEmpty(robot): no block is held. IsBlock, IsTarget: type tests.
  Contact-related: Covers, HandEmpty, Holding.
* Action (dx, dy, dz, grip): end-effector translation in metres per 0.05 s step
  (|d| <= 2 cm) and a finger command in [-1, 1] (+1 opens, -1 closes at 0.1 m/s).
* Train and eval tasks come from the same distribution (different seeds); goals hold one
  or two Covers atoms. Horizon 500 steps.
* Eval tasks with more blocks (``bpns eval --eval-set large``: 3-4 blocks and as many
  targets; ``--objects block=N``, N in 1..4) lie on a line y in [-0.5, 0.5]; goals hold
  1..N Covers atoms; the horizon grows to 250 steps per block.
"""

from __future__ import annotations

from collections.abc import Sequence

from bpns.structs import Object, Predicate, State, Type

LINE_X = 0.5
Y_RANGE = (-0.30, 0.30)
BLOCK_DEPTH, BLOCK_HEIGHT, BLOCK_MASS = 0.045, 0.04, 0.1
BLOCK_WIDTH_RANGE = (0.06, 0.10)
TARGET_WIDTH_RANGE = (0.03, 0.05)
TARGET_REGION_HALF = 0.01
REGION_X_HALF = 0.05
COVER_X_TOL = 0.015
HORIZON = 500
N_BLOCKS = N_TARGETS = 2
# More blocks than the paper's two (``--objects block=N``, the ``large`` set: 3-4) lie on
# a longer line: four blocks and four landing zones need up to 0.99 m. Its ends stay
# within the arm's reach (0.71 m from the base) and on the table (|y| <= 0.65).
WIDE_Y_RANGE = (-0.50, 0.50)
BLOCK_LIMITS = (1, 4)

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
BLOCK = Type("block", ("x", "y", "z", "width", "height", "grasped", "on_table"))
TARGET = Type("target", ("x", "y", "width"))
REGION = Type("region", ("y_lo", "y_hi"))


def _holding(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "grasped") > 0.5


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(state.get(b, "grasped") > 0.5 for b in state.objects_of_type(BLOCK))


def _covers(state: State, objs: Sequence[Object]) -> bool:
    block, target = objs
    b, t = state.data[block], state.data[target]
    bx, by, _, bw, _, grasped, on_table = b
    tx, ty, tw = t
    return (
        grasped < 0.5
        and on_table > 0.5
        and abs(bx - tx) <= COVER_X_TOL
        and by - bw / 2 <= ty - tw / 2
        and ty + tw / 2 <= by + bw / 2
    )


HOLDING = Predicate("Holding", (BLOCK,), _holding)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
COVERS = Predicate("Covers", (BLOCK, TARGET), _covers)


def _always(state: State, objs: Sequence[Object]) -> bool:
    """Type predicates hold for every object of their type."""
    return True


IS_BLOCK = Predicate("IsBlock", (BLOCK,), _always)
IS_TARGET = Predicate("IsTarget", (TARGET,), _always)
