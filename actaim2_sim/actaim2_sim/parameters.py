"""sim_node's parameters: declared with defaults and descriptions (the same defaults as
config/sim_node.yaml), checked once at start-up so a bad value stops the node with a clear
message instead of failing later inside SAPIEN."""
from __future__ import annotations

from dataclasses import dataclass

from rclpy.node import Node

from actaim2.gripper import POSITION_UNITS
from actaim2.sim.cameras import RIGS
from actaim2.sim.render_path import RENDER_PATHS
from actaim2.sim.sensor_noise import SENSOR_NOISE_PRESETS
from actaim2_ros import params


@dataclass(frozen=True)
class SimParameters:
    robot: str
    rig: str
    render_path: str
    camera_width: int
    camera_height: int
    camera_rate: float
    sensor_noise: str
    physics_rate: float
    real_time_factor: float
    tick_period: float
    joint_state_rate: float
    action_monitor_rate: float
    arm_controller: str
    gripper_controller: str
    gripper_position_unit: str
    goal_tolerance: float
    goal_time_tolerance: float
    gripper_goal_tolerance: float
    gripper_stall_velocity: float
    gripper_stall_timeout: float
    gripper_allow_stalling: bool
    category: str
    instance: int
    seed: int
    dof_fraction: float
    hull_cache: str
    prepare_objects: str


# name -> (default, description); read-only except where noted in DYNAMIC.
DEFAULTS: dict[str, tuple[object, str]] = {
    "robot": ("panda", "robot preset (actaim2.robots) or a robot YAML file"),
    "rig": ("ring5", f"camera rig: {' | '.join(RIGS)} (ring5: /cameras/cam<k>/points; azure_kinect: /points2)"),
    "render_path": ("auto", f"{' | '.join(RENDER_PATHS)}: auto uses SAPIEN when a Vulkan device exists, else ray casting"),
    "camera_width": (0, "image width, 0 = rig default (ring5 320; azure_kinect 320 binned or 640 unbinned)"),
    "camera_height": (0, "image height, 0 = rig default (ring5 240; azure_kinect 288 binned or 576 unbinned)"),
    "camera_rate": (5.0, "cloud publishing rate in sim-time Hz (0 = no clouds)"),
    "sensor_noise": ("rig", f"sensor realism preset: {' | '.join(SENSOR_NOISE_PRESETS)} (rig: azure_kinect for the "
                            "azure_kinect rig, none for ring5; azure_kinect: the documented sensor - range noise, "
                            "flying pixels, invalid grazing/dark/specular returns, 75x65 deg NFOV, colour camera "
                            "registration; tof: generic ToF noise; extrinsic jitter redrawn at every reset)"),
    "physics_rate": (240.0, "physics steps per simulated second"),
    "real_time_factor": (1.0, "sim seconds per wall second; 0 = as fast as possible"),
    "tick_period": (0.01, "wall seconds between loop ticks (each tick steps physics up to the target sim time)"),
    "joint_state_rate": (50.0, "/joint_states and /object_state rate in sim-time Hz; controllers check goals at this rate"),
    "action_monitor_rate": (20.0, "FollowJointTrajectory feedback rate in sim-time Hz"),
    "arm_controller": ("joint_trajectory_controller", "namespace of the arm's action and topic (real drivers differ)"),
    "gripper_controller": ("gripper_controller", "namespace of the GripperCommand action"),
    "gripper_position_unit": ("gap_width", "GripperCommand position: gap_width (m between the fingers, as the message "
                                           "says and franka_gripper takes it) | finger_joint (the joint position, as "
                                           "ros2_control's gripper_action_controller takes it)"),
    "goal_tolerance": (0.05, "default per-joint goal tolerance (rad) when a goal gives none; 0 = not checked"),
    "goal_time_tolerance": (0.5, "seconds after a trajectory's end to reach the goal tolerance"),
    "gripper_goal_tolerance": (0.002, "position error that counts as reached (in gripper_position_unit)"),
    "gripper_stall_velocity": (0.001, "mean speed (gripper_position_unit/s) over gripper_stall_timeout below which the gripper counts as "
                                      "stopped (judged on position progress: PhysX reports a velocity for squeezing fingers)"),
    "gripper_stall_timeout": (1.0, "sim seconds the fingers must stay stopped (within gripper_stall_velocity x this "
                                   "window) before a gripper goal ends stalled"),
    "gripper_allow_stalling": (True, "a stalled gripper (closed on a handle) succeeds instead of aborting"),
    "category": ("storage_furniture", "object category loaded at start-up"),
    "instance": (0, "object instance loaded at start-up"),
    "seed": (0, "placement and sensor-noise seed of the start-up scene"),
    "dof_fraction": (0.5, "start-up DoF position as a fraction of each joint's range (0.5 = half-open)"),
    "hull_cache": ("", "folder of real objects' convex decompositions (actaim2 prepare-objects --cache); "
                       "empty: $ACTAIM2_CACHE/hulls or ~/.cache/actaim2/hulls"),
    "prepare_objects": ("", "an object folder or a folder of object folders whose collision meshes are decomposed "
                            "into hull_cache at start-up, before the node serves (empty: none; cached meshes are skipped)"),
}
DYNAMIC: dict[str, tuple[object, str]] = {
    "hide_robot": (False, "render clouds without the robot (neither drawn nor occluding), as the paper's O_init / O_final"),
}


def declare_parameters(node: Node) -> SimParameters:
    """Declare every parameter and return the read-only ones, validated."""
    p = SimParameters(**params.declare_parameters(node, DEFAULTS, read_only=True))
    params.declare_parameters(node, DYNAMIC)
    choices = {"rig": RIGS, "render_path": RENDER_PATHS, "sensor_noise": SENSOR_NOISE_PRESETS,
               "gripper_position_unit": POSITION_UNITS}
    for name, allowed in choices.items():
        if getattr(p, name) not in allowed:
            raise ValueError(f"parameter {name}='{getattr(p, name)}' is not one of {list(allowed)}")
    for name in ("physics_rate", "tick_period", "joint_state_rate", "action_monitor_rate"):
        if not getattr(p, name) > 0:
            raise ValueError(f"parameter {name} must be > 0, got {getattr(p, name)}")
    for name in ("real_time_factor", "camera_rate", "goal_tolerance", "goal_time_tolerance", "gripper_stall_velocity",
                 "gripper_stall_timeout"):
        if getattr(p, name) < 0:
            raise ValueError(f"parameter {name} must be >= 0, got {getattr(p, name)}")
    return p
