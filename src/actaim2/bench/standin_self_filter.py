"""`actaim2 bench standin-self-filter`: how much arm the self-filter leaves in a stand-in demonstration's
O_init / O_final under the azure rig's default calibration errors, with and without the extrinsic refined
from the robot itself (:mod:`actaim2.perception.extrinsic_refinement`).

Per held-out placement of the stand-in evaluation (its reset seeds; one drawer half-open, placement p's
drawer p mod 3, push on even placements and pull on odd ones), in the world the demonstrations were
recorded in (Kinova j2s6s200, the ``azure_kinect`` rig with its sensor model on: extrinsic jitter 5 mm /
0.5 deg and a systematic range error up to 11 mm + 0.1 %, redrawn at every reset; SAPIEN rendering), the
scripted teleoperator's demonstration is executed and a robot-visible cloud taken at START (O_init),
before each keypose and at END (O_final), with the joint positions at each. The extrinsic is refined as
``bag2dataset`` refines it (all of the episode's clouds, :meth:`ExtrinsicRefiner.calibrate`) from the
clouds, the nominal extrinsic and the joint positions alone. Ground truth is the renderer's segmentation:

* arm left: the arm's valid pixels that the self-filter (posed at the cloud's joint positions, the
  cloud through the nominal or the refined extrinsic) keeps, as a share of the arm's valid pixels;
* near removed: the other valid pixels within 5 cm of an arm pixel (camera frame) that it removes,
  as a share of those pixels; and the same for the object's pixels alone (the shelf, its drawers and
  handles: the scene the task embedding reads), since the others are the floor around the robot's base,
  which the base's grown geometry reaches by design;
* the camera pose error, nominal and refined, against the pose the simulator rendered from (its
  truth, read for this measurement alone).

One line per (placement, observation) goes into the record (``--record NAME``: ``results/NAME``,
``actaim2 report``'s ``self_filter`` table).
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from actaim2.eval.standin import share, summary_table
from actaim2.geometry import transform_points

CATEGORY, INSTANCE, ROBOT, RIG = "three_drawer_shelf", 0, "kinova_j2s6s200", "azure_kinect"
NEAR = 0.05  # m: "non-arm points within 5 cm of the arm"
VELOCITY_SCALING = 0.5  # control_node's and collection's


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--placements", type=int, default=10, help="held-out placements of the stand-in evaluation")
    parser.add_argument("--render-path", default="sapien", choices=["sapien", "raycast"],
                        help="sapien: the visual meshes, as the demonstrations were recorded")
    parser.add_argument("--out", type=Path, default=Path("runs/standin_self_filter"), help="samples.jsonl and summary")
    parser.add_argument("--record", help="also write the committed record results/RECORD (actaim2 report)")


def filter_figures(xyz: np.ndarray, arm: np.ndarray, scene: np.ndarray, T_world_optical: np.ndarray, self_filter) -> dict:
    """Arm pixels kept and near non-arm pixels removed by ``self_filter`` (posed by the caller) for the
    organized cloud ``xyz`` seen through ``T_world_optical``; ``arm``, ``scene`` (H, W) the renderer's arm and
    object pixels."""
    valid = np.isfinite(xyz).all(axis=-1)
    keep = np.ones(arm.shape, bool)
    keep[valid] = self_filter.keep_mask(transform_points(T_world_optical, xyz[valid]))
    arm_valid, other = arm & valid, ~arm & valid
    gap = np.full(arm.shape, np.inf)
    if arm_valid.any():
        gap[other] = cKDTree(xyz[arm_valid]).query(xyz[other], distance_upper_bound=NEAR)[0]
    near = gap <= NEAR
    return {"arm_pixels": int(arm_valid.sum()), "arm_left": int((arm_valid & keep).sum()),
            "near_pixels": int(near.sum()), "near_removed": int((near & ~keep).sum()),
            "near_object_pixels": int((near & scene).sum()), "near_object_removed": int((near & scene & ~keep).sum())}


def pose_error(T: np.ndarray, T_true: np.ndarray) -> dict:
    """How far the pose ``T`` is from ``T_true``: millimetres, degrees."""
    delta = np.linalg.inv(T_true) @ T
    return {"mm": round(1000 * float(np.linalg.norm(delta[:3, 3])), 2),
            "deg": round(float(np.rad2deg(Rotation.from_matrix(delta[:3, :3]).magnitude())), 3)}


def measure(placements: int, render_path: str) -> list[dict]:
    from actaim2.control.collision import CollisionChecker, Workspace
    from actaim2.control.executor import KeyposeRunner
    from actaim2.control.ik import IKOptions, IKSolver
    from actaim2.control.model import RobotModel
    from actaim2.control.planner import KeyposePlanner, PlannerOptions
    from actaim2.eval.standin import placement_seeds
    from actaim2.perception.config import load_perception_config
    from actaim2.perception.extrinsic_refinement import ExtrinsicRefiner, RobotSurface
    from actaim2.perception.self_filter import RobotSelfFilter
    from actaim2.rollout.expert import ExpertTask, PlanningError
    from actaim2.rollout.scripted_teleop import ScriptedTeleoperator
    from actaim2.rollout.sim_executor import SimEnvExecutor
    from actaim2.rollout.teleop_eval import initial_state
    from actaim2.sim.env import SimEnv

    env = SimEnv(ROBOT, cameras=RIG, render_path=render_path)  # the rig's own sensor model: its calibration errors on
    robot = RobotModel(env.spec)
    checker = CollisionChecker(robot, Workspace())
    planner = KeyposePlanner(robot, checker, IKSolver(robot, checker, IKOptions()), PlannerOptions())
    teleoperator = ScriptedTeleoperator(env, seed=0)
    self_filter = RobotSelfFilter(env.spec, load_perception_config(RIG).self_filter_margin)
    refiner = ExtrinsicRefiner(RobotSurface(env.spec))
    robot_ids = list(env.sim.robot_entity_ids())
    samples = []
    for p, seed in enumerate(placement_seeds(placements)):
        drawer, mode = p % 3, ("push", "pull")[p % 2]
        info = env.reset(CATEGORY, INSTANCE, seed=seed, dof_fraction=initial_state(3, drawer))
        nominal = env.rig.cameras[RIG].T_world_optical  # what /tf_static says
        truth = env.rig.render_poses[RIG]

        def capture() -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, float]]:
            names, q, _ = env.joint_state()
            frame = env.observe(with_robot=True).frames[RIG]
            return (frame.xyz, np.isin(frame.segmentation, robot_ids), np.isin(frame.segmentation, list(env.sim.object_entity_ids())),
                    dict(zip(names, q.astype(float))))

        clouds = {"init": capture()}
        try:
            plan = teleoperator.demo(ExpertTask(info.dof_names[drawer], +1 if mode == "pull" else -1),
                                     np.random.default_rng(seed))
            runner = KeyposeRunner(planner, SimEnvExecutor(env), rng=np.random.default_rng(seed))
            for keypose in plan.keyposes:
                clouds[f"o{keypose.phase}"] = capture()
                runner.run(keypose, VELOCITY_SCALING)
        except PlanningError as exc:
            print(f"placement {p}: {exc}; O_final where the arm stopped")
        clouds["final"] = capture()
        calibration = refiner.calibrate(nominal, [(xyz, joints) for xyz, _, _, joints in clouds.values()])
        refined = calibration.T_world_optical
        for name in ("init", "final"):
            xyz, arm, scene, joints = clouds[name]
            self_filter.set_joint_positions(list(joints), list(joints.values()))
            samples.append({"placement": p, "seed": seed, "drawer": drawer, "mode": mode, "observation": name,
                            "refined": bool(calibration.accepted), "fits": len(calibration.fits),
                            "fits_accepted": len(calibration.accepted),
                            "correction_mm": round(1000 * calibration.to_json()["translation_m"], 2),
                            "correction_deg": calibration.to_json()["rotation_deg"],
                            "pose_error": {"before": pose_error(nominal, truth), "after": pose_error(refined, truth)},
                            "before": filter_figures(xyz, arm, scene, nominal, self_filter),
                            "after": filter_figures(xyz, arm, scene, refined, self_filter)})
        print(json.dumps({k: samples[-1][k] for k in ("placement", "refined", "correction_mm", "correction_deg", "pose_error")}),
              *(f"{s['observation']}: arm left {share(s['before'], 'arm'):.1%} -> {share(s['after'], 'arm'):.1%}"
                for s in samples[-2:]), flush=True)
    return samples


def main(args: argparse.Namespace) -> int:
    from actaim2.eval.results import machine_description
    from actaim2.report.records import record_from_samples

    started = time.time()
    samples = measure(args.placements, args.render_path)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "samples.jsonl").write_text("".join(json.dumps(s, sort_keys=True) + "\n" for s in samples))
    table = "\n".join(summary_table(samples))
    (args.out / "summary.md").write_text(table + "\n")
    print(table)
    if args.record:
        command = (f"actaim2 bench standin-self-filter --placements {args.placements} --render-path {args.render_path} "
                   f"--record {args.record}")
        meta = {"kind": "self_filter", "command": command, "checkpoints": {}, "samples": len(samples),
                "seconds": round(time.time() - started), "workers": 1, "load_average": round(os.getloadavg()[0], 1),
                "machine": machine_description(), "cores": os.cpu_count(), "note": "", "source": str(args.out)}
        print(f"wrote {record_from_samples(Path.cwd(), args.record, meta, samples)}")
    return 0
