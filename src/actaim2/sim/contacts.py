"""Whether the robot has touched the object: a :class:`SimEnv` step observer.

A trajectory whose part did not move either never reached the object or pushed it where it
could not go (a door pushed against its stop, a handle squeezed without pulling); the DoF change
alone cannot tell these apart, a contact can. PhysX's contact list (the last step's contacts)
is read after every :meth:`SimEnv.step` call, about 2 us, and no more once a touch was seen;
keyposes execute one physics step per call (a settling chunk is read at its last step).
"""
from __future__ import annotations

from actaim2.sim.env import SimEnv


class ContactMonitor:
    """``touched``: some robot link has pressed on some object link since :meth:`reset`."""

    def __init__(self, env: SimEnv):
        self.env = env
        self.touched = False
        self._robot: set[int] = set()
        self._object: set[int] = set()
        env.step_observers.append(self)

    def reset(self) -> None:
        """Forget earlier touches; call after each reset (the object's links may be new)."""
        self.touched = False
        self._robot = self.env.sim.robot_entity_ids()
        self._object = self.env.sim.object_entity_ids()

    def __call__(self, env: SimEnv) -> None:
        if self.touched:
            return
        for contact in env.scene.get_contacts():
            a, b = (body.entity.per_scene_id for body in contact.bodies)
            if (a in self._robot and b in self._object) or (a in self._object and b in self._robot):
                if any(abs(point.impulse).sum() > 0.0 for point in contact.points):
                    self.touched = True
                    return
