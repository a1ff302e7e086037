"""Stick Button in 3D: press every button, the far ones with a stick (paper App. A.3).

Rules (final, as simulated):

* Buttons are real push buttons: a static housing (7 cm wide) with a red cap (4.4 cm
  wide, top 4.5 cm above the table) on a vertical slide joint with a preloaded spring
  (stiffness 25 N/m, 0.15 N at rest, 0.35 N at the latch depth) and 12 mm of travel.
  A cap pushed down past ``LATCH_DEPTH`` (8 mm) *latches*: after that physics step an
  equality constraint (saved with the simulator state, ``eq_active``) holds it at 9.5 mm,
  so it stays down when released, and it is drawn green.
* Near buttons lie within 0.68 m of the Panda's base and are pressed with the closed
  fingertips. Far buttons lie 0.92-1.02 m from the base, beyond the fingertips' physical
  reach (about 0.84 m at button height; the workspace box is wider, so this is the arm's
  own limit, not a software clip). Train tasks have 1-2 buttons, eval tasks 3-4; each is
  far with probability 1/2. Goal: Pressed for every button.
* The stick (a 50 x 3 x 3 cm, 60 g box) lies on the table pointing forward (+x); its back
  12 cm rest in a slotted holder whose walls are taller than the stick and leave 6 mm
  either side (less than a finger's thickness), so fingers can only close around the
  stick's free part: over the holder they land on the walls' tops. The fingers close
  along y (the hand is turned 90 deg from Cover's), so a grasped stick stays horizontal
  along +x and its tip (a point 1.5 cm behind the front end, on the bottom face) presses
  a button when lowered onto the cap. The grasp point along the free part decides how far
  the tip reaches (paper KD1). No button lies in a far button's stick lane (|dy| < 8 cm),
  so the lowered stick never rests on another button. No button lies within 6 cm (xy) of
  the gripper's home position, so every task starts with AboveNoButton.
* Pressed(button): the cap's slide joint reads a travel >= LATCH_DEPTH (joint reading).
  Grasped(robot, stick): both finger pads touch the stick (MuJoCo contact list).
  HandEmpty(robot): no stick is grasped. RobotAboveButton(robot, button): the gripper
  centre is within 3 cm of the button's axis in xy. StickAboveButton(stick, button): the
  stick tip is within 3 cm of it in xy. AboveNoButton(): neither the gripper nor the tip
  is above any button (zero-arity, as in the paper). Contact-related: Grasped, Pressed.
* Action (dx, dy, dz, grip): end-effector translation in metres per 0.05 s step
  (|d| <= 2 cm) and a finger command in [-1, 1] (+1 opens, -1 closes at 0.1 m/s), as in
  Cover. The robot starts at its home pose; the stick (and holder) start on the left or
  right, 38-45 cm from the centre line. Horizon 1000 steps.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import GroundAtom, Object, Predicate, State, Type
from ik import ControllerConfig
from mj_envs.base import MujocoEnv, TaskLayout
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml
from mj_envs.world import ROBOT_PREFIX, World

# -- buttons ---------------------------------------------------------------------------
HOUSING_RADIUS, HOUSING_HEIGHT = 0.035, 0.03
CAP_RADIUS, CAP_HALF_HEIGHT = 0.022, 0.0125
CAP_REST_TOP = 0.045  # cap top above the table when up
CAP_MASS = 0.02
BUTTON_STIFFNESS, BUTTON_PRELOAD = 25.0, 0.006  # N/m; spring reference 6 mm above rest
BUTTON_DAMPING = 0.5
BUTTON_TRAVEL = 0.012
LATCH_DEPTH = 0.008  # travel at which the cap latches (Pressed)
LATCH_HOLD = 0.0095  # travel the latch holds the cap at
ABOVE_RADIUS = 0.03
CAP_RGBA = (0.85, 0.18, 0.15, 1.0)
PRESSED_RGBA = (0.2, 0.8, 0.3, 1.0)
# -- stick and holder ------------------------------------------------------------------
STICK_LENGTH, STICK_WIDTH, STICK_HEIGHT, STICK_MASS = 0.5, 0.03, 0.03, 0.06
TIP_INSET = 0.015  # the tip point lies this far behind the front end
HOLDER_LENGTH, HOLDER_WALL, HOLDER_HEIGHT, HOLDER_GAP = 0.12, 0.05, 0.04, 0.006
HOLDER_FRICTION = (0.3, 0.005, 0.0001)  # smooth plastic: the stick slides out freely
STICK_BACK_X = (0.12, 0.20)
STICK_SIDE_Y = (0.38, 0.45)
# -- layout ----------------------------------------------------------------------------
NEAR_X, NEAR_Y, NEAR_RADIUS = (0.35, 0.62), 0.25, 0.68
FAR_RADIUS, FAR_Y = (0.92, 1.02), 0.30
BUTTON_SPACING = 0.09  # centre distance, housings 2 cm apart
LANE_HALF_WIDTH = 0.08  # |dy| that keeps a button out of a far button's stick lane
# The gripper's xy at the home pose: no button starts under the hand, so every task
# starts in AboveNoButton (as in the paper, whose skills all start from there or from
# a button just pressed).
HOME_HAND_XY, HOME_CLEARANCE = (0.463, 0.0), 0.06
TRAIN_BUTTONS, EVAL_BUTTONS = (1, 2), (3, 4)
HORIZON = 1000
TABLE_HALF = (0.62, 0.65, 0.025)
TABLE_CENTRE_X = 0.55

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
BUTTON = Type("button", ("x", "y", "z", "pressed"))
STICK = Type("stick", ("x", "y", "z", "tip_x", "tip_y", "tip_z", "grasped"))
HOLDER = Type("holder", ("x", "y"))


def _robot_above(state: State, objs: Sequence[Object]) -> bool:
    robot, button = objs
    return _near_xy(state, robot, "x", "y", button)


def _stick_above(state: State, objs: Sequence[Object]) -> bool:
    stick, button = objs
    return _near_xy(state, stick, "tip_x", "tip_y", button)


def _near_xy(state: State, obj: Object, fx: str, fy: str, button: Object) -> bool:
    dx = state.get(obj, fx) - state.get(button, "x")
    dy = state.get(obj, fy) - state.get(button, "y")
    return dx * dx + dy * dy <= ABOVE_RADIUS * ABOVE_RADIUS


def _above_no_button(state: State, objs: Sequence[Object]) -> bool:
    buttons = state.objects_of_type(BUTTON)
    for robot in state.objects_of_type(ROBOT):
        if any(_robot_above(state, (robot, b)) for b in buttons):
            return False
    for stick in state.objects_of_type(STICK):
        if any(_stick_above(state, (stick, b)) for b in buttons):
            return False
    return True


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(state.get(s, "grasped") > 0.5 for s in state.objects_of_type(STICK))


def _pressed(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "pressed") > 0.5


def _grasped(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "grasped") > 0.5


# Classifiers are module-level functions (not lambdas) so tasks pickle to worker processes.
PRESSED = Predicate("Pressed", (BUTTON,), _pressed)
GRASPED = Predicate("Grasped", (ROBOT, STICK), _grasped)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
ROBOT_ABOVE_BUTTON = Predicate("RobotAboveButton", (ROBOT, BUTTON), _robot_above)
STICK_ABOVE_BUTTON = Predicate("StickAboveButton", (STICK, BUTTON), _stick_above)
ABOVE_NO_BUTTON = Predicate("AboveNoButton", (), _above_no_button)


class StickButtonEnv(MujocoEnv):
    """Press all buttons; those beyond the arm's reach with the tip of a held stick."""

    name = "stick_button"
    # Paper appendix B: many abstract plans are not refinable here (whether a button is
    # within reach is not in the predicates), so the planner may try up to 1000.
    planning_defaults = {"n_abstract": 1000}
    # The demonstrator switches within millimetres of its goals (close the fingers, press).
    learning_defaults = {"near_goal_scale": 0.01}
    # The hand is turned a quarter turn about the vertical (joint 7) so the fingers close
    # along y and hold the stick along +x; the workspace box reaches past the arm's own
    # limit so that reach is decided by kinematics, not by clipping.
    controller_config = ControllerConfig(
        home_qpos=(0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.7854),
        workspace_low=(0.15, -0.6, 0.005),
        workspace_high=(1.0, 0.6, 0.45),
    )

    @property
    def types(self) -> frozenset[Type]:
        return frozenset({ROBOT, BUTTON, STICK, HOLDER})

    @property
    def predicates(self) -> frozenset[Predicate]:
        return frozenset(
            {
                PRESSED,
                ROBOT_ABOVE_BUTTON,
                STICK_ABOVE_BUTTON,
                ABOVE_NO_BUTTON,
                GRASPED,
                HAND_EMPTY,
            }
        )

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        return frozenset({GRASPED, PRESSED})

    @property
    def goal_predicates(self) -> frozenset[Predicate]:
        return frozenset({PRESSED})

    @property
    def max_objects(self) -> dict[str, int]:
        return {"robot": 1, "button": EVAL_BUTTONS[1], "stick": 1, "holder": 1}

    # -- tasks ----------------------------------------------------------------------
    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        n_lo, n_hi = TRAIN_BUTTONS if train else EVAL_BUTTONS
        n = int(rng.integers(n_lo, n_hi + 1))
        side = 1.0 if rng.random() < 0.5 else -1.0
        stick_y = side * rng.uniform(*STICK_SIDE_Y)
        back_x = rng.uniform(*STICK_BACK_X)
        buttons = _sample_buttons(rng, n)

        arena = make_arena("stick_button", nuserdata=7)
        table = arena.worldbody.find("geom", "table")
        table.size = TABLE_HALF
        table.pos = (TABLE_CENTRE_X, 0.0, -TABLE_HALF[2])
        arena.worldbody.find("body", "workspace_focus").pos = (0.6, 0.0, 0.05)
        arena.worldbody.find("camera", "overview").pos = (1.45, -1.05, 0.95)
        arena.worldbody.find("camera", "front").pos = (1.9, 0.0, 0.7)
        top = arena.worldbody.find("camera", "top")
        top.pos, top.fovy = (0.6, 0.0, 1.9), 50
        for i, (bx, by) in enumerate(buttons):
            _add_button(arena, i, bx, by)
        _add_holder_and_stick(arena, back_x, stick_y)

        robot = Object("robot", ROBOT)
        button_objs = [Object(f"button{i}", BUTTON) for i in range(n)]
        stick = Object("stick", STICK)
        holder = Object("holder", HOLDER)
        goal = frozenset(GroundAtom(PRESSED, (b,)) for b in button_objs)
        return TaskLayout(
            xml=to_xml(arena),
            objects=(robot, *button_objs, stick, holder),
            goal=goal,
            horizon=HORIZON,
        )

    # -- physics beyond MuJoCo's: the latch --------------------------------------------
    def after_step(self, world: World) -> None:
        """Engage a button's latch (its equality constraint) once it travelled far enough."""
        ids = self._ids(world)
        d = world.data
        for adr, eq in zip(ids["cap_qpos"], ids["latch_eq"], strict=True):
            if d.eq_active[eq] == 0 and d.qpos[adr] >= LATCH_DEPTH:
                d.eq_active[eq] = 1

    def decorate(self, world: World) -> None:
        """Latched caps are drawn green (geom colours are looks, not simulator state)."""
        ids = self._ids(world)
        m, d = world.model, world.data
        for geom, eq in zip(ids["cap_geom"], ids["latch_eq"], strict=True):
            m.geom_rgba[geom] = PRESSED_RGBA if d.eq_active[eq] else CAP_RGBA

    # -- features -------------------------------------------------------------------
    def _ids(self, world: World) -> dict:
        ids = world.cache.get("stick_button")
        if ids is None:
            m = world.model
            caps = sorted(m.body(i).name for i in range(m.nbody) if m.body(i).name.endswith("_cap"))
            ids = {
                "site": m.site(ROBOT_PREFIX + "grip_site").id,
                "finger": m.joint(ROBOT_PREFIX + "finger_joint1").qposadr[0],
                "left_pad": m.geom(ROBOT_PREFIX + "left_pad").id,
                "right_pad": m.geom(ROBOT_PREFIX + "right_pad").id,
                "stick": m.geom("stick_geom").id,
                "holder": m.body("holder").id,
                "buttons": {c[: -len("_cap")]: k for k, c in enumerate(caps)},
                "cap_qpos": [m.joint(f"{c}_joint").qposadr[0] for c in caps],
                "cap_geom": [m.geom(f"{c}_geom").id for c in caps],
                "latch_eq": [m.equality(f"{c}_latch").id for c in caps],
            }
            world.cache["stick_button"] = ids
        return ids

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        d = world.data
        ids = self._ids(world)
        out: dict[Object, np.ndarray] = {}
        for obj in objects:
            if obj.type == ROBOT:
                x, y, z = d.site_xpos[ids["site"]]
                out[obj] = np.array([x, y, z, d.qpos[ids["finger"]]])
            elif obj.type == BUTTON:
                k = ids["buttons"][obj.name]
                x, y, z = d.geom_xpos[ids["cap_geom"][k]]
                travel = d.qpos[ids["cap_qpos"][k]]
                out[obj] = np.array([x, y, z + CAP_HALF_HEIGHT, float(travel >= LATCH_DEPTH)])
            elif obj.type == STICK:
                g = ids["stick"]
                centre = d.geom_xpos[g]
                rot = d.geom_xmat[g].reshape(3, 3)
                tip = centre + rot @ np.array(
                    [STICK_LENGTH / 2 - TIP_INSET, 0.0, -STICK_HEIGHT / 2]
                )
                out[obj] = np.array([*centre, *tip, float(self._grasped(world, g, ids))])
            elif obj.type == HOLDER:
                x, y, _ = d.xpos[ids["holder"]]
                out[obj] = np.array([x, y])
            else:
                raise KeyError(f"stick_button has no object type {obj.type.name!r}")
        return out

    @staticmethod
    def _grasped(world: World, geom: int, ids: dict) -> bool:
        """Both finger pads are in MuJoCo's contact list with ``geom``."""
        d = world.data
        n = d.ncon
        if n == 0:
            return False
        pads = {ids["left_pad"], ids["right_pad"]}
        touching = set()
        for (a, b), dist in zip(d.contact.geom[:n], d.contact.dist[:n], strict=True):
            if dist > 0.0:
                continue
            if a == geom and b in pads:
                touching.add(b)
            elif b == geom and a in pads:
                touching.add(a)
        return len(touching) == 2

    def demonstrator(self, task, rng):
        from mj_envs.stick_button_oracle import StickButtonDemonstrator

        return StickButtonDemonstrator(task, rng)

    def oracle_skills(self):
        from mj_envs.stick_button_skills import oracle_skills

        return oracle_skills()


# -- scene building ----------------------------------------------------------------------
def _sample_buttons(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    """Button centres: each near or far with probability 1/2, spaced, lanes kept clear."""
    for _ in range(10_000):
        far = rng.random(n) < 0.5
        pts: list[tuple[float, float]] = []
        for is_far in far:
            if is_far:
                r = rng.uniform(*FAR_RADIUS)
                y = rng.uniform(-FAR_Y, FAR_Y)
                pts.append((float(np.sqrt(r * r - y * y)), float(y)))
            else:
                while True:
                    x, y = rng.uniform(*NEAR_X), rng.uniform(-NEAR_Y, NEAR_Y)
                    if np.hypot(x, y) <= NEAR_RADIUS:
                        break
                pts.append((float(x), float(y)))
        if _layout_ok(pts, far):
            return pts
    raise RuntimeError("could not place the buttons; widen the regions")


def _layout_ok(pts: Sequence[tuple[float, float]], far: np.ndarray) -> bool:
    hx, hy = HOME_HAND_XY
    if any(np.hypot(x - hx, y - hy) < HOME_CLEARANCE for x, y in pts):
        return False
    for i in range(len(pts)):
        for j in range(i + 1, len(pts)):
            (xi, yi), (xj, yj) = pts[i], pts[j]
            if np.hypot(xi - xj, yi - yj) < BUTTON_SPACING:
                return False
            if (far[i] or far[j]) and abs(yi - yj) < LANE_HALF_WIDTH:
                return False
    return True


def _add_button(arena, i: int, x: float, y: float) -> None:
    base = arena.worldbody.add("body", name=f"button{i}", pos=(x, y, 0.0))
    base.add(
        "geom",
        name=f"button{i}_housing",
        type="cylinder",
        size=(HOUSING_RADIUS, HOUSING_HEIGHT / 2),
        pos=(0, 0, HOUSING_HEIGHT / 2),
        rgba=(0.22, 0.22, 0.25, 1),
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
    )
    cap = base.add(
        "body", name=f"button{i}_cap", pos=(0, 0, CAP_REST_TOP - CAP_HALF_HEIGHT), gravcomp=1
    )
    cap.add(
        "joint",
        name=f"button{i}_cap_joint",
        type="slide",
        axis=(0, 0, -1),  # qpos = travel, positive downwards
        range=(0.0, BUTTON_TRAVEL),
        limited=True,
        stiffness=BUTTON_STIFFNESS,
        springref=-BUTTON_PRELOAD,
        damping=BUTTON_DAMPING,
        armature=0.001,
    )
    cap.add(
        "geom",
        name=f"button{i}_cap_geom",
        type="cylinder",
        size=(CAP_RADIUS, CAP_HALF_HEIGHT),
        mass=CAP_MASS,
        rgba=CAP_RGBA,
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
    )
    # the cap slides inside the housing: never collide the two
    arena.contact.add("exclude", body1=f"button{i}", body2=f"button{i}_cap")
    arena.equality.add(
        "joint",
        name=f"button{i}_cap_latch",
        joint1=f"button{i}_cap_joint",
        polycoef=(LATCH_HOLD, 0, 0, 0, 0),
        active=False,
        solref=(0.004, 1),
    )


def _add_holder_and_stick(arena, back_x: float, stick_y: float) -> None:
    wb = arena.worldbody
    holder = wb.add("body", name="holder", pos=(back_x + HOLDER_LENGTH / 2, stick_y, 0.0))
    grey = (0.55, 0.56, 0.6, 1)
    offset = STICK_WIDTH / 2 + HOLDER_GAP + HOLDER_WALL / 2
    for k, sign in enumerate((-1.0, 1.0)):
        holder.add(
            "geom",
            name=f"holder_wall{k}",
            type="box",
            size=(HOLDER_LENGTH / 2, HOLDER_WALL / 2, HOLDER_HEIGHT / 2),
            pos=(0, sign * offset, HOLDER_HEIGHT / 2),
            rgba=grey,
            contype=OBJECT_CONTYPE,
            conaffinity=OBJECT_CONAFFINITY,
            friction=HOLDER_FRICTION,
        )
    holder.add(  # end stop behind the stick
        "geom",
        name="holder_back",
        type="box",
        size=(0.01, offset + HOLDER_WALL / 2, HOLDER_HEIGHT / 2),
        pos=(-HOLDER_LENGTH / 2 - 0.01 - HOLDER_GAP, 0, HOLDER_HEIGHT / 2),
        rgba=grey,
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
        friction=HOLDER_FRICTION,
    )
    stick = wb.add("body", name="stick", pos=(back_x + STICK_LENGTH / 2, stick_y, STICK_HEIGHT / 2))
    stick.add("freejoint", name="stick_joint")
    stick.add(
        "geom",
        name="stick_geom",
        type="box",
        size=(STICK_LENGTH / 2, STICK_WIDTH / 2, STICK_HEIGHT / 2),
        mass=STICK_MASS,
        rgba=(0.62, 0.4, 0.2, 1),
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
        friction=(1.0, 0.02, 0.001),
        condim=4,
    )
