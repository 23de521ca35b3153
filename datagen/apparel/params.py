"""Simulation parameters: per-kind chain parameters with defaults, and a JSON override file.

The override file (``--params FILE``) holds any subset of::

    {"simulation": {"gravity": 9.8, "max_speed": 25.0, "solver_iterations": 30, "anchor_force": 2000.0,
                    "contact_erp": 0.5, "max_joint_velocity": 30.0, "constraint_erp": 0.8, "piece_mass": 0.0,
                    "piece_velocity": true, "max_resettles": 5},
     "kinds": {"hair": {"stiffness": 0.05, "swing_limit": 0.8}, "default": {"link_mass": 0.1}}}

A kind is the apparel kind of a chain (``skirt``, ``hair``, ``cape``, ``coat_tail``,
``ponytail``, ...; the zoo writes it in the bone roles, ``--apparel-bones`` derives it from bone
names); kinds without an entry use ``default``. Unknown sections, kinds' fields or values out
of range are errors that name what was expected.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from mimicbench.schemas.errors import UserError


@dataclass(frozen=True)
class ChainParams:
    """Physics of the chains of one apparel kind.

    link_mass: kg per link. stiffness: the joint spring's pull toward the rest pose (0..1, the
    share of the angle error it takes out in one step; :mod:`mimicbench.datagen.apparel.springs`). damping:
    the spring's damping (the share of the joint's speed it takes out in one step). strength:
    the spring's torque limit as a multiple of the gravity torque of the links below the joint
    held horizontally (>1 holds the chain up against gravity). linear_damping,
    angular_damping: Bullet's per-link damping. swing_limit, twist_limit: radians from rest.
    radius_scale: capsule radius as a multiple of the driven vertices' 75th-percentile distance
    from the bone (the capsule gives the link's inertia; it collides only where the link's
    vertices span no volume, else the link collides as their convex hull). axial_inertia: a
    link's moment of inertia about its bone as a share of the one across it (at least the
    capsule's own m r^2 / 2; 0 keeps the capsule's, :func:`mimicbench.datagen.apparel.urdf.capsule_inertia`).
    friction: contact friction. collide_body: links
    collide with the body pieces; collide_chains: links collide with other chains that also ask
    for it. root_contact_frequency: rad/s, above 0 a root link's contacts are a critically damped
    spring of that natural frequency on the link's mass instead of Bullet's rigid contact
    (:class:`~mimicbench.datagen.apparel.chain_spec.LinkSpec` ``contact_frequency``): a skirt strip's root
    hangs at the hip where a thigh, placed anew every step, starts each step centimetres inside
    it, and a rigid contact throws the strip out within one step. contact_frequency: rad/s, the same
    contact spring on every link but the root (0: Bullet's rigid contact): a hair strand lying in
    the crevice of the neck, shoulder and upper back, each piece placed anew every step, took
    rigid contact impulses of 150-400 N on a 20 g link and its tip whipped at 10-15 m/s. A root link keeps ``root_contact_frequency``: it carries the whole
    chain's load, and on a spring sized for its own mass it sank into the neck (a seed-707 jump's
    hair 0.28 -> 0.58 % of apparel vertices inside the body). contact_shell: metres, how far the
    collision hull of each link on a ``contact_frequency`` spring reaches past its vertices: a
    contact spring pushes only as deep as it is pressed, so without the shell a strand lying on
    the back sank its vertices into it (a seed-0 run's hair 0.09 -> 0.20 %; 0.02 % with 3 mm).
    root_hull_from: a share of a root link's length (0..1): its collision hull keeps only the points
    at least that far along its bone from the pivot (0: the whole hull). A thigh pressing a skirt
    strip's top next to the hip pivot pushes off the strip's axis, where no turn clears it: the
    contact turned the root past its twist limit every other step and the limit's projection whipped
    the strip (zoo seed 0's random poses, 117.7 m/s^2 against a kinematic 12.3; simulation version
    14, issue 33); below that share the thigh passes through the top of the strip, as it passes
    through cloth sewn at the waist, and still pushes its lower part, which a turn clears. Coat
    tails hang from the pelvis too: a thigh pressed one's rigid root contact at up to 700 N on a
    60 g link and whipped it (seed 707's ``apparel-0026/turn``, 154.7 m/s^2, growing with the
    physics rate; 51.2 with the cut).
    """

    link_mass: float = 0.05
    stiffness: float = 0.02
    damping: float = 0.6
    strength: float = 1.5
    linear_damping: float = 0.1
    angular_damping: float = 0.3
    swing_limit: float = 0.9
    twist_limit: float = 0.2
    radius_scale: float = 1.0
    friction: float = 0.3
    collide_body: bool = True
    collide_chains: bool = False
    axial_inertia: float = 1.0
    root_contact_frequency: float = 0.0
    contact_frequency: float = 150.0
    contact_shell: float = 0.003
    root_hull_from: float = 0.0


@dataclass(frozen=True)
class SimParams:
    """Scene-wide settings: gravity (m/s^2, along -Y; default 9.8, MMD's 9.8 x 10 units/s^2 taken in
    metres, as issue 18 reads it: "9.8 m/s^2 in the dataset's units"), the explosion bound ``max_speed`` (m/s of
    any link), Bullet's ``solver_iterations``, ``anchor_force`` (N), the largest force of the
    fixed constraint that carries each chain's anchor with its body bone, ``contact_erp``, the
    share of a contact's penetration Bullet removes each step (0..1; the body pieces are moved
    by placement, so a limb walking into a skirt is pushed out only by this: at Bullet's 0.2 a
    thigh sank centimetres into a skirt strip), and ``max_joint_velocity`` (rad/s), Bullet's
    bound on every chain joint's speed (a light strip struck by a thigh whips past the explosion
    bound without it; Bullet bounds the anchor's six speeds by it too, so it must stay above the
    body's fastest turn: at 5 rad/s struck skirt strips peaked 2-4x lower, but the anchors
    trailed a quarter turn in 0.13 s and the chains barely swung), and ``constraint_erp``, the
    share of a joint constraint's error Bullet removes each step (0..1): each chain's anchor
    follows its moved constraint only through it, and at Bullet's 0.2 an anchor trailed a body bone turning 23.6 rad/s by 0.2 rad.
    ``piece_mass`` (kg): 0 places the body pieces at their bones' poses; above 0 they are bodies of that
    mass carried there by constraints, so contacts see a limb's speed (slower; docs/notes/apparel-simulation.md).
    ``piece_velocity``: with ``piece_mass`` 0, each piece placed at its bone's pose every step is also
    given the speed of that motion (linear and angular, from the step before; a body of
    :data:`mimicbench.datagen.apparel.world.MOVING_PIECE_MASS` kg), so Bullet's contacts see the limb's speed;
    False: static pieces, which contacts take as standing still: a contact spring's damping then
    pulls a link toward the world's rest, not the limb's, and an arm sweeping round in a spin strikes
    the cape it carries.
    ``max_resettles`` (an integer >= 0): frames of a clip at which chains that escaped the speed
    bound (or went NaN) may be put back at rest on their anchors before the clip fails
    (:mod:`mimicbench.datagen.apparel.simulate`); 0 fails the clip at its first escape.
    The world of a file's own bodies (an MMD model, :mod:`mimicbench.datagen.apparel.file_physics`) takes the
    settings MMD's players make explicit, each measured on Gene's motion capture
    (``docs/physics-mmd.md``): ``file_step_rate`` (Hz, > 0): physics steps a second, rounded up to a
    whole number of steps a clip frame (Saba and babylon-mmd step at 120 Hz, three.js at 65 Hz; the
    zoo's chains take the stage's ``--fps``); ``file_erp`` (0..1): the share of a joint's error
    Bullet removes each step, its non-contact ERP (three.js sets 0.475 on every joint axis;
    Bullet's default is 0.2); ``file_solver_iterations``: Bullet's solver iterations (mmd_tools sets
    60); ``file_sleeping``: whether Bullet may put still chains to sleep (no player lets them: a
    sleeping chain misses its bone's next move); ``file_warmup``: True starts a clip as the players'
    reset does, every chain placed rigidly with its body at the clip's first pose where it is, its
    joints at rest, stepped once and every velocity zeroed, then held at that pose for the
    relaxation frames (three.js's warm-up); False blends the body from the rest pose at the origin
    into the first pose over the relaxation frames (:mod:`mimicbench.datagen.apparel.relax`), which drags a
    clip that starts far from the origin. ``file_contact_frequency`` (rad/s, >= 0): 0 keeps Bullet's
    rigid contacts, as the players do; above 0 each dynamic body touches others through a
    critically damped contact spring of that frequency (it sinks g / w^2 under its own weight,
    1.7 mm at 75): under rigid contacts, hair resting on the shoulders' bodies shook frame to frame
    on motion capture (Gene's `guide`: peak 39.0 m/s^2 against a jitter bound of 10.0; 14.4 at 75).
    ``file_body_velocity``: True makes each bone-following body a heavy body placed every step where
    the step before left it and given the speed that carries it to its bone's pose (Bullet's
    kinematic bodies in the players; the zoo's ``piece_velocity``), so contacts see a limb's speed;
    False (the default) teleports mass-0 bodies, which contacts take as
    standing still: a contact spring's damping then drags what a limb pushes, which sinks 2 v / w
    into it (27 mm at 1 m/s and 75 rad/s) and springs out when the limb slows (the strand on top
    of Gene's head on `walk-left`; measurements in ``docs/physics-mmd.md``).
    ``file_duplicate_ranges``: True limits a joint to the overlap of its own range and those of the
    other joints between the same two bodies (MMD's Bullet enforces all of them; the scene keeps one
    joint a pair, :func:`mimicbench.datagen.apparel.file_plan.intersect_bounds`); False (the default)
    keeps the range of the joint the scene keeps (Gene's head strand and side hair have a second,
    reversed joint a pair, the strand's narrower: x [-0.087, 0.175] rad where the kept joint allows
    [-0.087, 0.524]; measurements in ``docs/notes/issue-52.md``).
    ``file_body_damping``: True damps each body of a chain whose bodies' dampings differ by its own
    linear and angular damping, in world velocity, as MMD's Bullet does
    (:mod:`mimicbench.datagen.apparel.body_damping`); False (the default) gives every chain one
    Bullet multibody damping, its bodies' rates averaged by mass (pybullet damps a multibody as a
    whole; Gene's head strand then whips its 50 g tip, whose own damping is 1).
    ``file_contact_cap`` (m/s^2, >= 0): above 0, a bone-following body touches a chain's link through
    one closest point a pair, the contact spring of ``file_contact_frequency`` seeing the body's own
    speed, its force capped at the link's mass times this
    (:mod:`mimicbench.datagen.apparel.capped_contacts`): a link squeezed between two bodies that
    overlap each other (hair between a raised arm and the head) yields into them instead of being
    thrown out when Bullet's contact gains a point; 0 keeps Bullet's contacts for those pairs."""

    gravity: float = 9.8
    max_speed: float = 25.0
    solver_iterations: int = 30
    anchor_force: float = 2000.0
    contact_erp: float = 0.5
    max_joint_velocity: float = 30.0
    constraint_erp: float = 0.8
    piece_mass: float = 0.0
    piece_velocity: bool = True
    max_resettles: int = 5
    file_contact_frequency: float = 75.0
    file_step_rate: float = 240.0
    file_erp: float = 0.2
    file_solver_iterations: int = 30
    file_sleeping: bool = False
    file_warmup: bool = True
    file_body_velocity: bool = False
    file_duplicate_ranges: bool = False
    file_body_damping: bool = False
    file_contact_cap: float = 0.0


DEFAULT_KINDS: dict[str, ChainParams] = {
    "default": ChainParams(),
    "hair": ChainParams(link_mass=0.02, stiffness=0.015, damping=0.3, strength=1.2, swing_limit=0.8),
    "ponytail": ChainParams(link_mass=0.03, stiffness=0.015, damping=0.3, strength=1.2, swing_limit=0.8),
    "skirt": ChainParams(link_mass=0.05, stiffness=0.03, damping=0.6, strength=2.0, swing_limit=0.7,
                         twist_limit=0.1, radius_scale=1.5, root_contact_frequency=150.0, contact_frequency=0.0,
                         root_hull_from=0.3),
    "cape": ChainParams(link_mass=0.08, stiffness=0.02, damping=0.6, strength=1.5, swing_limit=0.9),
    "coat_tail": ChainParams(link_mass=0.06, stiffness=0.025, damping=0.6, strength=1.8, swing_limit=0.8,
                             root_hull_from=0.3),
}

_RANGES = {  # field: (low, high, low_open)
    "link_mass": (0.0, None, True), "stiffness": (0.0, 1.0, False), "damping": (0.0, None, False),
    "strength": (0.0, None, False), "linear_damping": (0.0, 1.0, False), "angular_damping": (0.0, 1.0, False),
    "swing_limit": (0.0, math.pi, True), "twist_limit": (0.0, math.pi, True), "radius_scale": (0.0, None, True),
    "friction": (0.0, None, False), "axial_inertia": (0.0, 1.0, False), "gravity": (0.0, None, False),
    "max_speed": (0.0, None, True), "root_contact_frequency": (0.0, None, False),
    "contact_frequency": (0.0, None, False), "root_hull_from": (0.0, 1.0, False), "contact_shell": (0.0, None, False),
    "piece_mass": (0.0, None, False),
    "solver_iterations": (1, None, False), "anchor_force": (0.0, None, True), "contact_erp": (0.0, 1.0, True),
    "max_joint_velocity": (0.0, None, True), "constraint_erp": (0.0, 1.0, True), "max_resettles": (0, None, False),
    "file_contact_frequency": (0.0, None, False),
    "file_step_rate": (0.0, None, True), "file_erp": (0.0, 1.0, True), "file_solver_iterations": (1, None, False),
    "file_contact_cap": (0.0, None, False),
}


RECORDED_WHEN_ON = ("file_body_velocity", "file_duplicate_ranges", "file_body_damping", "file_contact_cap")
"""Opt-in :class:`SimParams` switches that enter a run's record only when on (true, or above 0)."""


@dataclass(frozen=True)
class ApparelParams:
    """All parameters of a run: the scene and the chain parameters per kind."""

    simulation: SimParams = field(default_factory=SimParams)
    kinds: dict = field(default_factory=lambda: dict(DEFAULT_KINDS))

    def for_kind(self, kind: str) -> ChainParams:
        """The parameters of ``kind`` (``default`` when it has none of its own)."""
        return self.kinds.get(kind, self.kinds["default"])

    def to_json(self) -> dict:
        """Plain JSON (for the manifest and the resume fingerprint). The opt-in switches of
        :data:`RECORDED_WHEN_ON` appear only when on, so a run that leaves them off has the
        fingerprint (and reuses the output) of a run made without them."""
        simulation = dataclasses.asdict(self.simulation)
        for name in RECORDED_WHEN_ON:
            if not simulation[name]:
                del simulation[name]
        return {"simulation": simulation, "kinds": {k: dataclasses.asdict(v) for k, v in sorted(self.kinds.items())}}


def _checked(cls, base, values: dict, where: str):
    if not isinstance(values, dict):
        raise UserError(f"{where}: expected a JSON object of fields, got {type(values).__name__}")
    names = {f.name: f for f in dataclasses.fields(cls)}
    out = {}
    for key, value in values.items():
        if key not in names:
            raise UserError(f"{where}: unknown field {key!r}; expected some of {', '.join(names)}")
        kind = names[key].type
        if kind == "bool":
            if not isinstance(value, bool):
                raise UserError(f"{where}.{key}: expected true or false, got {value!r}")
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise UserError(f"{where}.{key}: expected a finite number, got {value!r}")
            lo, hi, low_open = _RANGES[key]
            if kind == "int" and value != int(value):
                raise UserError(f"{where}.{key}: expected a whole number, got {value!r}")
            if (lo is not None and (value <= lo if low_open else value < lo)) or (hi is not None and value > hi):
                rng = f"{'>' if low_open else '>='} {lo:g}" + (f" and <= {hi:g}" if hi is not None else "")
                raise UserError(f"{where}.{key}: expected a number {rng}, got {value!r}")
            value = int(value) if kind == "int" else float(value)
        out[key] = value
    return dataclasses.replace(base, **out)


def params_from_json(data: dict, where: str = "params") -> ApparelParams:
    """Defaults overridden by ``data`` (the override file's object); see the module docstring."""
    if not isinstance(data, dict):
        raise UserError(f"{where}: expected a JSON object with 'simulation' and/or 'kinds', got {type(data).__name__}")
    unknown = set(data) - {"simulation", "kinds"}
    if unknown:
        raise UserError(f"{where}: unknown section(s) {sorted(unknown)}; expected 'simulation' and/or 'kinds'")
    sim = _checked(SimParams, SimParams(), data.get("simulation", {}), f"{where}.simulation")
    if sim.file_contact_cap > 0 and sim.file_contact_frequency <= 0:
        raise UserError(f"{where}.simulation.file_contact_cap: {sim.file_contact_cap} needs a contact spring; expected "
                        f"file_contact_frequency above 0, got {sim.file_contact_frequency}")
    kinds = dict(DEFAULT_KINDS)
    overrides = data.get("kinds", {})
    if not isinstance(overrides, dict):
        raise UserError(f"{where}.kinds: expected an object {{kind: {{field: value}}}}, got {type(overrides).__name__}")
    default = _checked(ChainParams, kinds["default"], overrides.get("default", {}), f"{where}.kinds.default")
    for kind in list(kinds):  # a changed default reaches kinds only through their own entries
        kinds[kind] = default if kind == "default" else kinds[kind]
    for kind, values in overrides.items():
        if kind != "default":
            kinds[kind] = _checked(ChainParams, kinds.get(kind, default), values, f"{where}.kinds.{kind}")
    return ApparelParams(sim, kinds)


def load_params(path: str | Path | None) -> ApparelParams:
    """The defaults, or the defaults overridden by the JSON file at ``path``.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        UserError: the file is not JSON or holds an unknown field or a value out of range.
    """
    if path is None:
        return ApparelParams()
    text = Path(path).read_text()
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}: not valid JSON ({exc})") from None
    return params_from_json(data, str(path))
