"""Per-category joint dynamics and material densities, each number with where it comes from.

Two tables feed the simulated objects, generated or loaded from a PartNet-Mobility folder:

* ``JOINT_TABLE``: how a movable part resists and where it rests, per (category, part kind):
  Coulomb friction (N for a slide, N m for a hinge) that holds a released part in place,
  viscous damping, and a behaviour -- ``friction`` (stays where it is left), ``bistable``
  (a toggle's over-centre spring snaps it to the nearer end) or ``counterbalanced`` (a
  vertical sash's balance springs cancel its weight, so only friction remains).
* ``MATERIALS``: densities (kg/m^3) per material, and which material each part kind of each
  category is made of (:func:`part_material`), for masses from part volumes.

API for loaders::

    category_dynamics("storage_furniture", "drawer")  -> JointDynamics (nominal values)
    sample_dynamics("storage_furniture", "drawer", rng) -> JointDynamics drawn from the range
    part_material("refrigerator", "door") -> Material; effective_density(category) for hulls

Semantics follow PartNet-Mobility's ``semantics.txt`` labels (drawer, door, lid, lever,
knob, switch, slider, ...); :data:`SEMANTIC_ALIASES` maps its spellings onto the table's
part kinds. Unknown categories or part kinds fall back to the generic row (``"*"``), so a
real folder always gets dynamics.

Friction is what a released part must overcome to move: gravity and the robot both act
against it. A part whose weight pulls along its joint (a lid, a vertical sash, a lever on a
horizontal axis) stays put only where the gravity torque is below the friction, which is
the real behaviour: a lid on plain hinges falls shut below its balance point and falls
open past it. Numbers marked "estimate" are derived in their source string from a typical
part and a published friction coefficient or hardware rating.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FRICTION = "friction"  # Coulomb friction holds the part wherever it is released
BISTABLE = "bistable"  # an over-centre spring drives it to the nearer end of its range
COUNTERBALANCED = "counterbalanced"  # its weight is cancelled (sash balances); friction holds it


@dataclass(frozen=True)
class JointDynamics:
    """How one joint behaves. Units: N and N s/m (prismatic), N m and N m s/rad (revolute)."""

    friction: float  # Coulomb friction force / torque (also the static holding limit)
    damping: float  # viscous damping on top of the friction
    behaviour: str = FRICTION
    snap: float = 0.0  # bistable only: the spring force / torque at the ends of the range
    source: str = ""


@dataclass(frozen=True)
class DynamicsRange:
    """A table row: ranges the generator draws from; the nominal value is the mid-point."""

    friction: tuple[float, float]
    damping: tuple[float, float]
    source: str
    behaviour: str = FRICTION
    snap: tuple[float, float] = (0.0, 0.0)

    def nominal(self) -> JointDynamics:
        mid = lambda r: 0.5 * (r[0] + r[1])  # noqa: E731
        return JointDynamics(mid(self.friction), mid(self.damping), self.behaviour, mid(self.snap), self.source)

    def sample(self, rng: np.random.Generator) -> JointDynamics:
        draw = lambda r: float(rng.uniform(*r)) if r[1] > r[0] else float(r[0])  # noqa: E731
        return JointDynamics(draw(self.friction), draw(self.damping), self.behaviour, draw(self.snap), self.source)


_WOOD_RUNNER = ("estimate: a 2-4 kg empty drawer on roller or wooden runners, rolling/sliding coefficient "
                "0.1-0.25 (wood on wood 0.25-0.5, Engineering ToolBox 'Friction coefficients'; nylon rollers lower) "
                "x 20-40 N weight; it holds wherever released as real drawers do")
_PLAIN_HINGE = ("estimate: plain butt or concealed cabinet hinges have 'no resistance to speak of' (Leeco, 'How does a "
                "constant torque hinge work'); pivot friction of a 3-6 kg leaf on two steel pins, coefficient ~0.15, "
                "gives 0.05-0.3 N m")

# (category, part kind) -> row; (category, "*") and ("*", kind) are fallbacks, ("*", "*") the last one.
JOINT_TABLE: dict[tuple[str, str], DynamicsRange] = {
    ("*", "*"): DynamicsRange((0.2, 0.2), (0.1, 0.1), "generic fallback: a light hinge or slide that holds when released"),
    ("*", "drawer"): DynamicsRange((4.0, 8.0), (1.0, 3.0), _WOOD_RUNNER),
    ("*", "door"): DynamicsRange((0.1, 0.3), (0.1, 0.5), _PLAIN_HINGE),
    ("storage_furniture", "drawer"): DynamicsRange((4.0, 8.0), (1.0, 3.0), _WOOD_RUNNER),
    ("storage_furniture", "door"): DynamicsRange((0.1, 0.3), (0.1, 0.5), _PLAIN_HINGE),
    ("table", "drawer"): DynamicsRange((5.0, 9.0), (1.0, 3.0), _WOOD_RUNNER + "; table drawers mostly run on wood"),
    ("table", "door"): DynamicsRange((0.1, 0.3), (0.1, 0.5), _PLAIN_HINGE),
    ("three_drawer_shelf", "drawer"): DynamicsRange((3.0, 6.0), (1.0, 2.0), _WOOD_RUNNER),
    ("door", "door"): DynamicsRange((0.3, 1.0), (0.3, 1.0), "estimate: interior door leaf of 20-30 kg on 3 butt hinges, "
                                    "pivot coefficient ~0.15 at ~8 mm pin radius: 0.3-1 N m; the scaled leaf keeps it"),
    ("door", "slider"): DynamicsRange((6.0, 12.0), (2.0, 4.0), "estimate: sliding door on top-hung nylon rollers, rolling "
                                      "resistance ~0.03-0.05 x 20-30 kg leaf weight"),
    ("refrigerator", "door"): DynamicsRange((0.3, 0.6), (0.3, 0.8), "estimate: fridge door cam hinge with a nylon bush, "
                                            "pivot coefficient ~0.2 under a 5-8 kg door; the gasket's magnet is not modelled"),
    ("refrigerator", "drawer"): DynamicsRange((6.0, 10.0), (2.0, 4.0), "estimate: freezer drawer on telescopic rails, "
                                              "coefficient ~0.1 x 6-10 kg drawer"),
    ("faucet", "lever"): DynamicsRange((0.2, 0.6), (0.01, 0.05), "ceramic-disc cartridge operating torque: ASME A112.18.1 "
                                       "caps it at 1.7 N m (Geann cartridge FAQ, 'operating torque'); typical cartridges "
                                       "turn at a fraction of that, and single-lever handles stay where they are left"),
    ("faucet", "spout"): DynamicsRange((0.3, 0.8), (0.02, 0.08), "estimate: swivel spout on two O-rings (EPDM on brass, "
                                       "coefficient ~0.5, ~25 mm diameter, ~30 N seal load per ring)"),
    ("faucet", "knob"): DynamicsRange((0.2, 0.6), (0.01, 0.05), "as the lever: ASME A112.18.1 cartridge torque limit 1.7 N m"),
    ("switch", "toggle"): DynamicsRange((0.005, 0.01), (0.001, 0.003), "toggle switches hold each end by an over-centre "
                                        "compression spring and snap past the centre (jxnma.com, 'The principle of the "
                                        "button subswitch'); estimate: 3-5 N at a 2.5-3.5 cm lever tip = 0.08-0.15 N m",
                                        BISTABLE, (0.08, 0.15)),
    ("switch", "lever"): DynamicsRange((0.02, 0.05), (0.01, 0.03), "breaker-style lever switch: over-centre spring like a "
                                       "toggle, larger (estimate: 10-15 N at a 5-6 cm lever = 0.5-0.8 N m)",
                                       BISTABLE, (0.5, 0.8)),
    ("switch", "slider"): DynamicsRange((1.5, 3.0), (0.5, 1.0), "estimate: slide dimmer, a felt/grease-damped slider "
                                        "pressed by a leaf spring: 1.5-3 N, it holds any position (and its own ~10 g weight)"),
    ("switch", "knob"): DynamicsRange((0.03, 0.08), (0.005, 0.01), "estimate: rotary dimmer potentiometer, rotational torque "
                                      "of panel potentiometers is specified around 10-80 mN m in manufacturer datasheets"),
    ("window", "sash"): DynamicsRange((5.0, 10.0), (2.0, 4.0), "estimate: sliding sash in PVC or wooden tracks with brush "
                                      "seals, 5-10 N; a vertical sash hangs on balances that carry its weight "
                                      "(spring or weight balances, as sash windows are built)", COUNTERBALANCED),
    ("window", "door"): DynamicsRange((0.8, 1.5), (0.2, 0.5), "casement friction stays: 'torque hinges ... hold a door, "
                                      "lid or panel in place at any angle' (Sugatsune, 'How to specify friction hinges'); "
                                      "constant-torque hinge catalogues list 0.5-6 N m ratings (HSP constant torque hinges)"),
    ("box", "lid"): DynamicsRange((0.02, 0.06), (0.005, 0.02), "plain box hinges: 'a standard hinge has no resistance to "
                                  "speak of... a horizontal-axis panel either slams back shut or falls fully open' (Leeco, "
                                  "'How does a constant torque hinge work'); pin friction only, estimate 0.02-0.06 N m"),
    ("box", "drawer"): DynamicsRange((2.0, 4.0), (0.5, 1.5), _WOOD_RUNNER + "; a small box drawer weighs ~1 kg"),
    ("box", "slider"): DynamicsRange((1.0, 2.5), (0.3, 0.8), "estimate: a sliding lid in wooden grooves, wood on wood "
                                     "0.25-0.5 (Engineering ToolBox) x ~0.5 kg lid x 2 (both grooves pressed)"),
    ("safe", "door"): DynamicsRange((0.5, 1.2), (0.5, 1.5), "estimate: 8-15 kg safe door on steel pin hinges, coefficient "
                                    "~0.15 at ~10 mm pin radius under the door weight and its moment"),
    ("safe", "lid"): DynamicsRange((0.5, 1.0), (0.5, 1.0), "heavy deposit-box lid on gas struts sized to its weight (gas "
                                   "springs carry a heavy lid so it stays at any angle; estimate: strut seal friction "
                                   "0.5-1 N m about the hinge)", COUNTERBALANCED),
}

SEMANTIC_ALIASES: dict[str, str] = {
    # PartNet-Mobility semantics.txt labels -> table part kinds
    "rotation_door": "door", "translation_door": "slider", "sliding_door": "slider", "drawer": "drawer",
    "door": "door", "lid": "lid", "rotation_lid": "lid", "translation_lid": "slider", "lever": "lever",
    "handle": "lever", "knob": "knob", "switch": "toggle", "toggle": "toggle", "toggle_button": "toggle",
    "slider": "slider", "slider_button": "slider", "spout": "spout", "sash": "sash", "window": "sash",
    "rotation_window": "door", "translation_window": "sash", "casement": "door", "button": "toggle",
}


def _row(category: str, semantic: str) -> DynamicsRange:
    kind = SEMANTIC_ALIASES.get(semantic, semantic)
    for key in ((category, kind), (category, "*"), ("*", kind), ("*", "*")):
        if key in JOINT_TABLE:
            return JOINT_TABLE[key]
    raise AssertionError("the table has a ('*', '*') row")


def category_dynamics(category: str, semantic: str = "") -> JointDynamics:
    """Nominal dynamics of a part kind (``semantic``: a semantics.txt label) of ``category``."""
    return _row(category, semantic).nominal()


def sample_dynamics(category: str, semantic: str, rng: np.random.Generator) -> JointDynamics:
    """Dynamics drawn from the table's range (the generator's per-instance values)."""
    return _row(category, semantic).sample(rng)


def behaviour(category: str, semantic: str) -> tuple[str, float]:
    """(behaviour, nominal snap) of a part kind: what the URDF's friction/damping cannot say."""
    d = category_dynamics(category, semantic)
    return d.behaviour, d.snap


@dataclass(frozen=True)
class Material:
    name: str
    density: float  # kg/m^3 of the solid the shape stands for
    source: str


MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material("softwood", 500.0, "pine/spruce at 12% moisture: specific gravity 0.40-0.51 (USDA Wood Handbook, FPL-GTR-190, "
                                "table 5-3a)"),
    Material("particleboard", 650.0, "EN 312 particleboard, 600-750 kg/m^3 typical"),
    Material("mdf", 750.0, "medium-density fibreboard, 700-800 kg/m^3 typical (EN 622-5)"),
    Material("brass", 8500.0, "CW617N / C37700 forging brass, 8.4-8.5 g/cm^3"),
    Material("zinc_alloy", 6600.0, "Zamak 3 (ASTM B86) die-cast handles, 6.6 g/cm^3"),
    Material("abs", 1050.0, "ABS moulding grades 1.03-1.07 g/cm^3"),
    Material("glass", 2500.0, "EN 572-1 soda-lime float glass, 2500 kg/m^3"),
    Material("fridge_door", 180.0, "effective: a foam-filled sheet-steel door; estimate from a typical 5 kg under-counter "
                                   "fridge door over its 0.60 x 0.82 x 0.055 m outer volume"),
    Material("safe_door", 2200.0, "effective: steel plate with fire-resistant fill; estimate from a typical 9 kg door of a "
                                  "35 cm safe over its 0.30 x 0.32 x 0.045 m volume"),
    Material("safe_body", 1500.0, "effective: a small safe's welded shell and fill (fixed base: its mass does not move)"),
)}

# (category, part kind) -> material of the part's panel; handles have their own (HANDLE_MATERIAL).
PART_MATERIALS: dict[tuple[str, str], str] = {
    ("*", "*"): "particleboard",
    ("storage_furniture", "*"): "particleboard",
    ("table", "*"): "softwood",
    ("three_drawer_shelf", "*"): "softwood",
    ("door", "*"): "mdf",
    ("refrigerator", "door"): "fridge_door",
    ("refrigerator", "drawer"): "abs",
    ("faucet", "*"): "brass",
    ("switch", "*"): "abs",
    ("window", "sash"): "softwood",
    ("window", "door"): "softwood",
    ("window", "glass"): "glass",
    ("box", "*"): "softwood",
    ("safe", "door"): "safe_door",
    ("safe", "lid"): "safe_door",
    ("safe", "*"): "safe_body",
}
HANDLE_MATERIAL = "zinc_alloy"


def part_material(category: str, semantic: str) -> Material:
    """Material of a part kind of a category (e.g. ``("refrigerator", "door")`` -> foam-filled steel)."""
    kind = SEMANTIC_ALIASES.get(semantic, semantic)
    for key in ((category, kind), (category, "*"), ("*", kind), ("*", "*")):
        if key in PART_MATERIALS:
            return MATERIALS[PART_MATERIALS[key]]
    raise AssertionError("the table has a ('*', '*') row")


def effective_density(category: str, semantic: str = "") -> float:
    """kg/m^3 to give a part's collision hulls when its folder has no inertial data."""
    return part_material(category, semantic).density
