"""One evaluation sample in the simulator, executed the way data collection executes trajectories.

reset the object (half-open, the task's reset seed) -> robot-hidden pictures O_init and the
object cloud -> the method begins its sample -> for INIT, REACH, GRASP, MANIPULATE: the method
gives the keypose (a policy from the pictures taken just before, with its fallback rotations when
asked for), the keypose runner plans it (IK, collision checks with the object cloud as in
collection, straight lines) and the simulator executes it -> the object's DoFs are read
(privileged) and judged (``outcome.py``).

A keypose the planner refuses is replaced by its first fallback the planner accepts (the record's
``candidate``: the index executed per phase, 0 the keypose itself); with none left the sample ends
there, and the DoFs are judged all the same, so a part already moved counts. Nothing executed is
retried: one task, one sample.
"""
from __future__ import annotations

import time
from typing import Sequence

import numpy as np

from actaim2.control.executor import KeyposeRunner
from actaim2.control.planner import KeyposePlanner
from actaim2.data.object_cloud import CloudConfig, object_cloud
from actaim2.eval.outcome import NO_SAMPLE, measure
from actaim2.eval.sim_views import pictures
from actaim2.eval.sources import NoSample, Scene
from actaim2.eval.tasks import EvalTask
from actaim2.keypose import PHASE_NAMES
from actaim2.sim.env import SimEnv


def run_sample(env: SimEnv, planner: KeyposePlanner, executor, cloud_config: CloudConfig, source, task: EvalTask,
               dof_fraction: float | Sequence[float], velocity_scaling: float) -> dict:
    """Execute one sample of ``source`` for ``task``, the object's DoFs reset to ``dof_fraction`` of their ranges
    (one for all, or one each); the result record (JSON types)."""
    started, cpu = time.perf_counter(), time.process_time()
    obj = task.obj
    info = env.reset(obj.category if not obj.folder else None, max(obj.instance, 0), seed=task.reset_seed,
                     dof_fraction=dof_fraction, folder=obj.folder or None)
    rng = np.random.default_rng(task.sample_seed)
    init = pictures(env, with_robot=False)
    scene = Scene(env, info, init, object_cloud(init, cloud_config, rng), rng, task)
    record = {"key": task.key, "method": task.method, "split": obj.split, "category": obj.category or info.category,
              "object": obj.key, "slot": task.slot, "reset_seed": task.reset_seed, "sample_seed": task.sample_seed,
              "requested_cluster": task.cluster}
    executed, note = 0, ""
    try:
        plan = source.begin(scene)
        record.update(group=plan.group, repetition=plan.repetition, **plan.details)
        planner.set_cloud(scene.cloud.points)
        runner = KeyposeRunner(planner, executor, rng)
        gripper_closed, candidates = False, record.setdefault("candidate", [])
        for phase in range(len(PHASE_NAMES)):
            keyposes = plan.next(phase, gripper_closed)
            result, index = runner.run_first(keyposes, velocity_scaling)
            candidates.append(index)
            if not result.success:
                note = f"{PHASE_NAMES[phase]}: {result.reason or 'failed'}: {result.message}"
                break
            executed += 1
            gripper_closed = bool(keyposes[index].gripper_closed)
    except NoSample as exc:
        note = f"{NO_SAMPLE}: {exc}"
        record.update(group=exc.group, repetition=exc.repetition)
    outcome = measure(list(info.dof_names), info.dof_initial, env.object_dof(), info.dof_lower, info.dof_upper)
    record.update(success=outcome.success, largest_change=round(outcome.largest_change, 5),
                  mode=list(outcome.mode) if outcome.mode else None, fractions=outcome.fractions, initial=outcome.initial,
                  phases_executed=executed, note=note, seconds=round(time.perf_counter() - started, 3),
                  cpu_seconds=round(time.process_time() - cpu, 3))  # all threads of the worker (renderer too): the idle-machine cost
    return record
