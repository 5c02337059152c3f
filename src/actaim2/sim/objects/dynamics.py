"""Joint friction, damping, toggle springs and counterbalances of a loaded object, in PhysX.

URDF's ``<dynamics friction>`` is a force (N, slides) or torque (N m, hinges). PhysX's own
articulation "friction coefficient" is something else: dimensionless, proportional to the
joint's reaction force (so a heavier part holds better), and it lets a loaded joint creep
(measured here: a 0.5 kg lid with coefficient 0.3 still sank 0.1 rad in 2 s). So it is
switched off and each movable joint's drive realises the dynamics instead:

* ``friction`` parts: a velocity drive towards zero with a stiff gain (``friction / V_CREEP``)
  whose force is clamped at ``friction + damping * |v|``. Below that load the part stands
  still (creeping under ``V_CREEP``); above it, it slides against Coulomb friction plus
  viscous damping. The clamp is refreshed every physics step from the joint velocity.
* ``bistable`` parts (toggles): a spring towards the nearer end of the range, preloaded so
  that it presses the part onto that end with ``snap``; past the centre the target flips
  to the other end and the part snaps over, as an over-centre toggle mechanism does.
* ``counterbalanced`` parts (vertical sashes on balances, lids on gas struts, and flaps: doors
  hinged on a horizontal axis, :func:`is_flap`): the link ignores gravity, the balances' job;
  friction as above.

Gravity acts on every other link: a lid falls shut below its balance point and open past
it wherever its weight's torque beats the hinge friction.
"""
from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sapien

from .physics_table import (
    BISTABLE,
    COUNTERBALANCED,
    SEMANTIC_ALIASES,
    JointDynamics,
    behaviour,
    category_dynamics,
)

V_CREEP = 1e-4  # m/s or rad/s: the fastest a joint drifts under a load just below its friction
MIN_FRICTION = 1e-3  # N or N m: the drive gain's floor, so a frictionless joint is still damped
LIMIT_TOLERANCE = 0.02  # relative change of a friction clamp worth passing on to PhysX
# A door whose hinge axis lies within this of horizontal is a flap. Flaps are hung on fittings
# that carry their weight: lift-up flaps on gas struts or lift mechanisms, drop-down flaps on
# friction or soft-down stays, oven and dishwasher doors on hinge springs; each holds the flap
# at any angle, as the counterbalanced behaviour does. (A box lid is a lid, not a door: plain
# hinges, it falls shut below its balance point.)
FLAP_MAX_TILT_DEG = 30.0


@dataclass
class _Driven:
    joint: sapien.physx.PhysxArticulationJoint
    index: int  # DoF index in the articulation
    dynamics: JointDynamics
    lower: float
    upper: float
    limit: float = 0.0  # the force clamp last set (friction joints)


class ObjectDynamics:
    """The drives of one object's movable joints; :meth:`step` runs before every physics step."""

    def __init__(self, articulation: sapien.physx.PhysxArticulation, joints: list, dynamics: list[JointDynamics]):
        self.articulation = articulation
        self.dynamics = list(dynamics)
        active = [j.name for j in articulation.get_active_joints()]
        self._viscous: list[_Driven] = []
        self._bistable: list[_Driven] = []
        for joint, d in zip(joints, dynamics):
            lower, upper = (float(v) for v in joint.limit[0])
            driven = _Driven(joint, active.index(joint.name), d, lower, upper)
            joint.friction = 0.0  # PhysX's coefficient: see the module docstring
            if d.behaviour == COUNTERBALANCED:
                joint.child_link.disable_gravity = True
            if d.behaviour == BISTABLE and np.isfinite(upper - lower):
                span = upper - lower
                stiffness = 2.0 * d.snap / span  # the preload (half a span beyond the end) gives ``snap``
                joint.set_drive_property(stiffness, d.damping, force_limit=d.snap + d.friction)
                joint.set_drive_velocity_target(0.0)
                self._bistable.append(driven)
            else:
                joint.set_drive_velocity_target(0.0)
                if d.damping > 0.0:
                    self._viscous.append(driven)
                else:
                    joint.set_drive_property(0.0, max(d.friction, MIN_FRICTION) / V_CREEP, force_limit=max(d.friction, MIN_FRICTION))
        self.at_rest()

    def at_rest(self) -> None:
        """The drives of parts standing still: called when the object is teleported to rest, so
        that an episode starts from the same drive state whatever the episodes before it did
        (the clamps are otherwise only refreshed when they change by LIMIT_TOLERANCE)."""
        for v in self._viscous:
            d = v.dynamics
            v.limit = max(d.friction, MIN_FRICTION)
            v.joint.set_drive_property(0.0, v.limit / V_CREEP, force_limit=v.limit)
        self.step()

    def step(self) -> None:
        """Refresh the friction clamps (viscous part) and the toggles' spring targets."""
        if not (self._viscous or self._bistable):
            return
        qvel = self.articulation.get_qvel()
        for v in self._viscous:
            d = v.dynamics
            limit = max(d.friction, MIN_FRICTION) + d.damping * abs(float(qvel[v.index]))
            if abs(limit - v.limit) > LIMIT_TOLERANCE * v.limit:  # a part at rest costs no PhysX call
                v.joint.set_drive_property(0.0, max(d.friction, MIN_FRICTION) / V_CREEP, force_limit=limit)
                v.limit = limit
        if self._bistable:
            qpos = self.articulation.get_qpos()
            for b in self._bistable:
                span = b.upper - b.lower
                near_upper = float(qpos[b.index]) > 0.5 * (b.lower + b.upper)
                b.joint.set_drive_target(b.upper + 0.5 * span if near_upper else b.lower - 0.5 * span)


def joint_dynamics(urdf: Path, joints: list, category: str, semantics: dict[str, str]) -> list[JointDynamics]:
    """Dynamics of each movable joint: friction and damping from the URDF's ``<dynamics>`` where
    it gives a friction above zero (placeholders of 0 count as missing), else the category
    table's (:func:`.physics_table.category_dynamics`, keyed by the part's semantics.txt label);
    the behaviour (bistable, counterbalanced) from the table, counterbalanced for a flap."""
    given = {}
    for j in ET.parse(urdf).getroot().iter("joint"):
        dyn = j.find("dynamics")
        if dyn is not None and float(dyn.get("friction", 0.0)) > 0.0:
            given[j.get("name")] = (float(dyn.get("friction")), float(dyn.get("damping", 0.0)))
    out = []
    axes = _axes_as_modelled(joints[0].child_link.articulation) if joints else {}
    for joint in joints:
        label = semantics.get(joint.child_link.name, "")
        kind, snap = behaviour(category, label)
        if is_flap(axes[joint.name], joint.type, label):
            kind = COUNTERBALANCED
        if joint.name in given:
            friction, damping = given[joint.name]
            out.append(JointDynamics(friction, damping, kind, snap, "URDF <dynamics>"))
        else:
            out.append(dataclasses.replace(category_dynamics(category, label), behaviour=kind))
    return out


def is_flap(axis: np.ndarray, joint_type: str, semantic: str) -> bool:
    """A door (by its semantics.txt label) on a hinge whose ``axis`` (object frame, z up) lies
    within FLAP_MAX_TILT_DEG of horizontal."""
    if SEMANTIC_ALIASES.get(semantic, semantic) != "door" or not joint_type.startswith("revolute"):
        return False
    return abs(float(axis[2])) < np.sin(np.deg2rad(FLAP_MAX_TILT_DEG))


def _axes_as_modelled(articulation: sapien.physx.PhysxArticulation) -> dict[str, np.ndarray]:
    """Each joint's axis in the root's frame at q = 0, composed along the tree from the joints'
    poses in their parent and child links (link poses are not computed before the first step)."""
    link_pose = {articulation.root.entity.name: sapien.Pose()}
    axes = {}
    for joint in articulation.joints:  # a parent link's joint comes before its children's
        if joint.parent_link is None:
            continue
        in_world = link_pose[joint.parent_link.entity.name] * joint.pose_in_parent
        link_pose[joint.child_link.entity.name] = in_world * joint.pose_in_child.inv()
        axes[joint.name] = in_world.to_transformation_matrix()[:3, 0]
    return axes
