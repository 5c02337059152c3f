"""The scripted teleoperator: what a person at the keyboard would mark, planned with privileged state.

A human teleoperator (``teleop_node``) chooses a mode ("pull" a drawer open, "push" it shut,
"open" or "close" a hinged part), moves the hand to a grasp point of their choosing, and marks
the four keyposes INIT, REACH, GRASP, MANIPULATE, each executed through ``/execute_keypose``.
This module stands in for that person in simulation: the :class:`ScriptedExpert` plans the
keyposes from the object's true state (link poses, joint axes, handle annotations), with the
handle annotation moved where this operator takes it (:func:`operator_handle`): a random point
along the handle (a person does not always grasp a drawer edge in its middle), the approach
pitched down, a push made lower on the panel. The person's judgement of success is the
object's DoF: it moved the asked way by more than 30 % of its range.

Everything here is ROS-free. ``scripted_teleop`` (actaim2_control) runs it against a live
simulator through the node graph, on a mirror :class:`SimEnv` loaded with the same scene;
:mod:`actaim2.rollout.teleop_eval` runs the same keyposes through the control package's planner
in-process to measure how often the teleoperator succeeds.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.geometry import matrix_to_pose
from actaim2.keypose import Keypose
from actaim2.rollout.expert import ExpertTask, PlanningError, ScriptedExpert
from actaim2.sim.env import SimEnv
from actaim2.sim.objects.model import Handle
from actaim2.sim.success import SUCCESS_FRACTION, moved_fraction

# The mode a task is, as an operator labels it (InteractionMode.label): by joint type and direction.
MODE_LABELS = {("prismatic", +1): "pull", ("prismatic", -1): "push", ("revolute", +1): "open", ("revolute", -1): "close"}
EDGE_MARGIN = 0.03  # m kept between a randomised grasp point and the handle's ends (half a finger pad and some)
PUSH_DROP = 0.05  # m: the most a push contact point moves from the handle towards the panel's centre


@dataclass(frozen=True)
class TeleopDemo:
    """One demonstration as the teleoperator marks it."""

    task: ExpertTask
    label: str  # "push", "pull", "open" or "close"
    grasp_offset: float  # m along the handle (tcp x) from its annotated centre
    strategy: str  # the expert's: "grasp" or "push"
    keyposes: list[Keypose]  # INIT, REACH, GRASP, MANIPULATE


def mode_label(joint_type: str, direction: int) -> str:
    """The operator's name for moving a ``joint_type`` joint towards its upper (+1) or lower (-1) limit."""
    return MODE_LABELS[("prismatic" if joint_type == "prismatic" else "revolute", int(np.sign(direction)))]


def task_for_label(env: SimEnv, joint: str, label: str) -> ExpertTask:
    """The task a label asks of ``joint`` ("pull"/"open": towards the upper limit; "push"/"close": the lower)."""
    joint_type = env.object.joints[env.object.dof_index(joint)].type
    for direction in (+1, -1):
        if mode_label(joint_type, direction) == label:
            return ExpertTask(joint, direction)
    allowed = [mode_label(joint_type, d) for d in (+1, -1)]
    raise ValueError(f"mode '{label}' does not apply to the {joint_type} joint {joint}: use one of {allowed}")


def operator_handle(handle: Handle, T_world_link: np.ndarray, offset: float, pitch: float, push: bool,
                    push_drop: float = PUSH_DROP) -> Handle:
    """The handle annotation moved to where this operator takes it.

    * ``offset`` m from its centre along its length (the tcp x axis): the grasp point;
    * the approach pitched by ``pitch`` rad about that axis, downwards in ``world`` (a person
      reaching for a drawer edge comes from slightly above; a Jaco's curved fingers pinch a thin
      lip that way, and straight on they close on the panel beside it);
    * ``push``: the contact point moved from the handle towards the part's origin (a drawer's
      front centre) within the panel, by half the way and at most ``push_drop`` m: a hand
      pushing just below a top edge slides off it.
    """
    T = handle.tcp_in_link()
    position = np.asarray(handle.position, float) + offset * T[:3, 0]
    if push:
        inward = -position - (-position @ T[:3, 2]) * T[:3, 2] - (-position @ T[:3, 0]) * T[:3, 0]
        distance = float(np.linalg.norm(inward))
        if distance > 1e-9:
            position = position + inward / distance * min(0.5 * distance, push_drop)
    candidates = []
    for sign in (+1.0, -1.0):
        R = Rotation.from_rotvec(sign * pitch * T[:3, 0]).as_matrix()
        approach, closing = R @ np.asarray(handle.approach, float), R @ np.asarray(handle.closing, float)
        candidates.append(((T_world_link[:3, :3] @ approach)[2], approach, closing))
    _, approach, closing = min(candidates, key=lambda c: c[0])  # the one pointing further down
    return dataclasses.replace(handle, position=tuple(position), approach=tuple(approach), closing=tuple(closing))


class ScriptedTeleoperator:
    """Plans demonstrations on ``env``, a SimEnv holding the scene the arm works in (or a mirror of it).

    ``grasp_spread`` scales the random grasp offset: 0 grasps the handle's centre, 1 anywhere
    along it up to ``EDGE_MARGIN`` from its ends. ``pitch`` (rad): see :func:`operator_handle`.
    """

    def __init__(self, env: SimEnv, grasp_spread: float = 1.0, pitch: float = np.radians(20.0), seed: int = 0):
        if not 0.0 <= grasp_spread <= 1.0:
            raise ValueError(f"grasp_spread must be within [0, 1], got {grasp_spread}")
        self.env = env
        self.grasp_spread = grasp_spread
        self.pitch = pitch
        self.expert = ScriptedExpert(env, seed=seed)

    def demo(self, task: ExpertTask, rng: np.random.Generator) -> TeleopDemo:
        """Plan the four keyposes of ``task`` from the scene's current state, grasping at a random
        point along the handle; raises :class:`PlanningError` when no grasp variant works."""
        obj = self.env.object
        index = next((i for i, h in enumerate(obj.handles) if h.joint == task.joint), None)
        if index is None:
            raise PlanningError(f"no handle annotation for {task.joint}")
        original = obj.handles[index]
        label = mode_label(obj.joints[obj.dof_index(task.joint)].type, task.direction)
        half = max(0.0, original.span / 2 - EDGE_MARGIN)
        offset = float(rng.uniform(-half, half)) * self.grasp_spread
        T_world_link = obj.link(original.link).entity_pose.to_transformation_matrix()
        # the expert grasps (or pushes beside) the annotation: move it where this operator goes
        obj.handles[index] = operator_handle(original, T_world_link, offset, self.pitch, push=label == "push")
        try:
            plan = self.expert.plan(task)
        finally:
            obj.handles[index] = original
        keyposes = []
        for phase, T, closed in plan.keyposes:
            position, quat = matrix_to_pose(T)
            keyposes.append(Keypose(int(phase), position, quat, bool(closed)))
        return TeleopDemo(task, label, offset, plan.strategy, keyposes)


def judged_success(task: ExpertTask, dof_names: list[str], initial: np.ndarray, final: np.ndarray,
                   lower: np.ndarray, upper: np.ndarray) -> tuple[bool, float]:
    """The operator's verdict: did the task's DoF move the asked way by more than 30 % of its
    range? Returns (success, signed change as a fraction of the range)."""
    i = dof_names.index(task.joint)
    moved = float(moved_fraction(initial, final, lower, upper)[i])
    return moved * task.direction > SUCCESS_FRACTION, moved
