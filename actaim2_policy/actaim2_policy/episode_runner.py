"""episode_runner: manipulation episodes through the node graph, exactly DESIGN.md's sim loop.

One episode, through rclpy clients only:
  /reset_scene -> the mode: /sample_mode, asked again until its views are stamped at or after the
  reset's ``stamp`` (views of the old scene are never used) -> for INIT, REACH, GRASP, MANIPULATE:
  /predict_keypose(not_before = end of the last motion; the reset's stamp for INIT) ->
  /execute_keypose -> success when some object DoF moved by more than 30 % of its range
  (/object_state against the reset's ``dof_initial`` and limits).
``keyposes:=sampler`` replaces the two policy services by the heuristic grasp sampler on a
/fused_points cloud stamped at or after the reset (the non-learned baseline).

Episodes run over categories x instances (or object folders) and clusters
(:func:`actaim2.policy.episodes.plan_episodes`). START / END go out on /episode (transient local,
for recorders), every episode is one line of a JSONL file, and a summary table (SSR per object
and cluster) ends the run.

Nothing waits forever: every call has a timeout. Servers are awaited, and calls retried, with
backoff up to ``server_timeout`` until the episode's first motion (a restarted node comes back);
a server lost after the arm has moved fails that episode with the reason, and the run goes on
with the next. A goal that times out is cancelled.
Ctrl-C (SIGINT) and SIGTERM only set a flag: rclpy's own handler would shut the context down
before the running goal could be cancelled. The runner then cancels the goal, records the
episode as interrupted, prints the summary and exits with code 130.
"""
from __future__ import annotations

import threading
import time
from datetime import datetime
from pathlib import Path
from typing import Callable

import numpy as np
from actaim2_msgs.action import ExecuteKeypose
from actaim2_msgs.msg import EpisodeEvent, Keypose
from actaim2_msgs.srv import PredictKeypose, ResetScene, SampleMode
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.task import Future
from sensor_msgs.msg import JointState, PointCloud2

from actaim2.keypose import PHASE_NAMES
from actaim2.policy.episodes import (
    EpisodeLog,
    EpisodeRecord,
    EpisodeSpec,
    PhaseRecord,
    catalogue_paths,
    is_success,
    largest_change,
    plan_episodes,
    summary_table,
)
from actaim2.policy.requests import is_transient
from actaim2.policy.retry import BACKOFF_CAP, Backoff, wait_until
from actaim2_policy.grasp_baseline import GraspBaseline
from actaim2_ros.action_client import LockedActionClient
from actaim2_ros.keypose import keypose_data, keypose_msg
from actaim2_ros.main import run_client
from actaim2_ros.params import declare_parameters
from actaim2_ros.stamps import stamp_msg, stamp_ns

EPISODE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
EVENT_ACK_TIMEOUT = 2.0  # s (wall) for /episode subscribers to acknowledge the last events before exit
CANCEL_WAIT = 3.0  # s (wall) for the answer to a cancel request
POLL = 0.05  # s (wall) between looks at a flag or a retried request
INTERRUPTED = 130  # exit code after Ctrl-C, as a shell reports a SIGINT-ended command
MODES = ("policy", "sampler")

PARAMETERS = {
    "keyposes": ("policy", "policy: /sample_mode + /predict_keypose (the learned policy) | sampler: the heuristic grasp "
                           "sampler on /fused_points (the non-learned baseline)"),
    "episodes": (3, "number of episodes, then exit"),
    "categories": (["storage_furniture"], "object categories; episode k runs object k mod n of categories x instances"),
    "instances": ([-1], "instances of every category (-1: drawn by the simulator from the episode's seed)"),
    "object_paths": ([""], "PartNet-Mobility folders (mobility.urdf inside); when given they replace categories x "
                           "instances; [\"\"] = none (rclpy cannot declare an empty list)"),
    "catalogue": ("generated", "generated: categories x instances (or object_paths) | partnet: "
                               "the real folders of the splits below, from partnet_root"),
    "partnet_root": ("", "the partnet catalogue's folder (object folders + splits.yaml); "
                         "\"\" = $ACTAIM2_PARTNET"),
    "splits": ([""], "partnet splits to run (train, val, extra; [\"\"] = val); test splits are "
                     "refused"),
    "clusters": ([-1], "clusters asked of /sample_mode, one per round over the objects (-1: drawn from the learned prior)"),
    "seed": (0, "seed of episode 0; episode k uses seed + k (scene, mode sample, grasp sampler)"),
    "dof_fraction": (0.5, "initial state of every object DoF as a fraction of its range"),
    "velocity_scaling": (0.5, "ExecuteKeypose velocity_scaling (0, 1]"),
    "jsonl_file": ("", "one JSON line per episode; empty = runs/episode_runner/episodes-<date>-<time>.jsonl"),
    "fused_points_topic": ("/fused_points", "sampler: the fused, robot-filtered cloud in world"),
    "workspace_center": ([0.75, 0.0, 0.4], "sampler: m, world: the cube the object cloud is taken from"),
    "workspace_half_extent": (0.6, "sampler: m"),
    "samples_per_episode": (20, "sampler: grasp draws before the episode is declared unsampleable"),
    "robot": ("panda", "sampler: robot preset or robot YAML (its reach and hand), as control_node's"),
    "server_timeout": (60.0, "s (wall): how long servers are awaited and calls retried, with backoff, before an "
                              "episode's first motion (a restarting node comes back)"),
    "reset_timeout": (60.0, "s (wall) for the /reset_scene answer (loading an object can take a while)"),
    "call_timeout": (10.0, "s (wall) for a /sample_mode or /predict_keypose answer and for a goal's acceptance"),
    "views_timeout": (30.0, "s (wall) for an observation stamped at or after the reset or the end of the last motion"),
    "goal_timeout": (120.0, "s (wall) for one ExecuteKeypose result; then the goal is cancelled and the episode fails"),
    "settle_time": (1.0, "s (sim) after the last motion before the object state is read"),
}


class EpisodeFailure(Exception):
    """The episode cannot go on; the message is recorded as its reason and the run continues."""


class Interrupted(Exception):
    """Ctrl-C or SIGTERM."""


class EpisodeRunner(Node):
    def __init__(self, stop: threading.Event) -> None:
        # Observation and object-state stamps are sim time (/clock): the runner only makes sense on it.
        super().__init__("episode_runner", parameter_overrides=[Parameter("use_sim_time", value=True)])
        self.p = declare_parameters(self, PARAMETERS)
        if self.p["keyposes"] not in MODES:
            raise ValueError(f"keyposes '{self.p['keyposes']}' is not one of {list(MODES)}")
        folders = catalogue_paths(self.p["catalogue"], self.p["partnet_root"], self.p["splits"])
        self.plan = plan_episodes(int(self.p["episodes"]), self.p["categories"],
                                  self.p["instances"], folders or self.p["object_paths"],
                                  self.p["clusters"], int(self.p["seed"]))
        self.stop = stop
        self.policy = self.p["keyposes"] == "policy"
        self._reset_client = self.create_client(ResetScene, "/reset_scene")
        self._sample_client = self.create_client(SampleMode, "/sample_mode")
        self._predict_client = self.create_client(PredictKeypose, "/predict_keypose")
        self._execute_client = LockedActionClient(self, ExecuteKeypose, "/execute_keypose")  # rclpy#1123: no lost goal answers
        self._episode_pub = self.create_publisher(EpisodeEvent, "/episode", EPISODE_QOS)
        self._lock = threading.Lock()
        self._object_state: JointState | None = None
        self._cloud: PointCloud2 | None = None
        self.create_subscription(JointState, "/object_state", self._keep("_object_state"), 10)
        self._baseline = None
        if not self.policy:
            self.create_subscription(PointCloud2, self.p["fused_points_topic"], self._keep("_cloud"), qos_profile_sensor_data)
            self._baseline = GraspBaseline(tuple(float(c) for c in self.p["workspace_center"]),
                                           float(self.p["workspace_half_extent"]), int(self.p["samples_per_episode"]),
                                           self.p["robot"])
        self._described = False
        self._moved = False  # the running episode has sent a goal: from then on a lost server fails it

    def _keep(self, attribute: str) -> Callable:
        def store(msg) -> None:
            with self._lock:
                setattr(self, attribute, msg)
        return store

    def _latest(self, attribute: str, not_before: int):
        """The latest message of ``attribute`` stamped at or after ``not_before`` (ns), else None."""
        with self._lock:
            msg = getattr(self, attribute)
        return msg if msg is not None and stamp_ns(msg.header.stamp) >= not_before else None

    # -- waiting, never forever --------------------------------------------------------------
    def _pause(self, seconds: float) -> None:
        if self.stop.wait(seconds):
            raise Interrupted()

    def _wait(self, future: Future, timeout: float, what: str, ready: Callable[[], bool], forget: Callable[[], None]):
        """The future's result within ``timeout`` s; EpisodeFailure when it does not come or its
        server went away (``forget`` drops the pending request), Interrupted on Ctrl-C."""
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        deadline = time.monotonic() + timeout
        while not done.wait(POLL):
            if self.stop.is_set():
                forget()
                raise Interrupted()
            if time.monotonic() > deadline:
                forget()
                raise EpisodeFailure(f"{what}: no answer within {timeout:.0f} s (its node stopped or restarted?)")
            if not ready():
                forget()
                raise EpisodeFailure(f"{what}: the server went away before answering (its node stopped or restarted?)")
        return future.result()

    def _call(self, client, request, name: str, timeout: float | None = None):
        """One answer within ``timeout`` (default call_timeout). Before the episode's first motion a
        lost server is retried with backoff up to server_timeout (a restarting node comes back, and
        a killed one can still look present to discovery for a while); after it, the episode fails."""
        timeout = timeout or float(self.p["call_timeout"])
        deadline = time.monotonic() + float(self.p["server_timeout"])
        delays = iter(Backoff().delays(float(self.p["server_timeout"])))
        while True:
            try:
                if not client.service_is_ready():
                    raise EpisodeFailure(f"{name} is not available (its node stopped or restarted?)")
                future = client.call_async(request)
                return self._wait(future, timeout, name, client.service_is_ready,
                                  lambda: client.remove_pending_request(future))
            except EpisodeFailure as exc:
                if self._moved or time.monotonic() > deadline:
                    raise
                self.get_logger().warning(f"{exc}; retrying", throttle_duration_sec=5.0)
                self._pause(next(delays, BACKOFF_CAP))

    def _servers(self) -> dict[str, Callable[[], bool]]:
        servers = {"/reset_scene (sim_node)": self._reset_client.service_is_ready,
                   "/execute_keypose (control_node)": self._execute_client.server_is_ready}
        if self.policy:
            servers["/sample_mode (policy_node)"] = self._sample_client.service_is_ready
            servers["/predict_keypose (policy_node)"] = self._predict_client.service_is_ready
        return servers

    def _wait_for_servers(self) -> None:
        """Every server, awaited with backoff up to server_timeout: a restarted node gets time to come back."""
        servers = self._servers()
        ready = wait_until(lambda: all(ok() for ok in servers.values()), float(self.p["server_timeout"]),
                           self.stop.is_set, sleep=self.stop.wait)
        if self.stop.is_set():
            raise Interrupted()
        if not ready:
            missing = [name for name, ok in servers.items() if not ok()]
            raise EpisodeFailure(f"not available after {self.p['server_timeout']:.0f} s: {', '.join(missing)}")

    def _retry(self, ask: Callable[[], tuple[object | None, str]], what: str):
        """Ask until ``ask`` returns a value (its reason says why not) or views_timeout passes."""
        deadline = time.monotonic() + float(self.p["views_timeout"])
        while True:
            value, reason = ask()
            if value is not None:
                return value
            if time.monotonic() > deadline:
                raise EpisodeFailure(f"{what} within {self.p['views_timeout']:.0f} s: {reason}")
            self._pause(POLL)

    # -- one episode --------------------------------------------------------------------------
    def _event(self, spec: EpisodeSpec, event: int, object_id: str, success: bool = False, note: str = "") -> None:
        msg = EpisodeEvent(episode=spec.index, event=event, object_id=object_id, success=success, note=note)
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "world"
        self._episode_pub.publish(msg)

    def _sample_mode(self, spec: EpisodeSpec, reset_ns: int, record: EpisodeRecord) -> SampleMode.Response:
        def ask():
            response = self._call(self._sample_client, SampleMode.Request(cluster=spec.cluster, seed=spec.seed), "/sample_mode")
            if not response.success:
                if not is_transient(response.message):
                    raise EpisodeFailure(f"/sample_mode refused: {response.message}")
                return None, response.message
            if stamp_ns(response.observation_stamp) < reset_ns:  # the old scene: wait for the new one
                return None, f"views stamped {stamp_ns(response.observation_stamp) / 1e9:.3f} s precede the reset"
            return response, ""

        response = self._retry(ask, "no views of the new scene")
        if not self._described:
            self.get_logger().info(f"keyposes from the learned policy: {response.message}")
            self._described = True
        record.cluster = int(response.cluster)
        record.cluster_probabilities = [float(v) for v in response.cluster_probabilities]
        record.mode_observation_stamp = stamp_ns(response.observation_stamp) / 1e9
        return response

    def _predict(self, embedding, phase: int, gripper_closed: bool, not_before: int) -> PredictKeypose.Response:
        request = PredictKeypose.Request(embedding=embedding, phase=phase, gripper_closed=gripper_closed)
        request.not_before = stamp_msg(not_before)

        def ask():
            response = self._call(self._predict_client, request, "/predict_keypose")
            if response.success:
                if stamp_ns(response.keypose.header.stamp) < not_before:
                    raise EpisodeFailure("/predict_keypose answered from views older than not_before")
                return response, ""
            if not is_transient(response.message):
                raise EpisodeFailure(f"/predict_keypose refused ({PHASE_NAMES[phase]}): {response.message}")
            return None, response.message

        return self._retry(ask, f"no {PHASE_NAMES[phase]} keypose from views after the last motion")

    def _baseline_keyposes(self, spec: EpisodeSpec, reset_ns: int) -> tuple[list[Keypose], int]:
        cloud = self._retry(lambda: (self._latest("_cloud", reset_ns), f"no {self.p['fused_points_topic']} cloud yet"),
                            f"no {self.p['fused_points_topic']} cloud of the new scene")
        try:
            keyposes = self._baseline.keyposes(cloud, np.random.default_rng(spec.seed))
        except ValueError as exc:
            raise EpisodeFailure(str(exc)) from exc
        return [keypose_msg(kp, cloud.header.stamp) for kp in keyposes], stamp_ns(cloud.header.stamp)

    def _execute(self, keypose: Keypose, alternatives: list[Keypose]) -> ExecuteKeypose.Result:
        """Run one goal (control_node falls back on ``alternatives`` when it refuses ``keypose``); on a
        timeout or Ctrl-C the goal is cancelled before the error goes up."""
        client = self._execute_client
        if not client.server_is_ready():
            raise EpisodeFailure("/execute_keypose is not available (control_node stopped or restarted?)")
        goal = ExecuteKeypose.Goal(keypose=keypose, velocity_scaling=float(self.p["velocity_scaling"]), alternatives=alternatives)
        sent = client.send_goal_async(goal)
        try:
            handle = self._wait(sent, float(self.p["call_timeout"]), "/execute_keypose goal", client.server_is_ready,
                                lambda: None)
        except (EpisodeFailure, Interrupted):
            # The server may have accepted the goal already (its answer on the way): cancel it once it is known.
            arrived = threading.Event()
            sent.add_done_callback(lambda _: arrived.set())
            if arrived.wait(CANCEL_WAIT) and sent.result() is not None and sent.result().accepted:
                self._cancel(sent.result())
            raise
        if not handle.accepted:
            raise EpisodeFailure("/execute_keypose rejected the goal")
        try:
            return self._wait(handle.get_result_async(), float(self.p["goal_timeout"]), "/execute_keypose result",
                              client.server_is_ready, lambda: None).result
        except (EpisodeFailure, Interrupted):
            self._cancel(handle)
            raise

    def _cancel(self, handle) -> None:
        done = threading.Event()
        handle.cancel_goal_async().add_done_callback(lambda _: done.set())
        answered = done.wait(CANCEL_WAIT)
        self.get_logger().warning("cancelled the running /execute_keypose goal" if answered else
                                  f"cancel of the running /execute_keypose goal unanswered after {CANCEL_WAIT:.0f} s")

    def _run_episode(self, spec: EpisodeSpec, record: EpisodeRecord) -> None:
        self._moved = False
        request = ResetScene.Request(category=spec.category, instance=spec.instance, seed=spec.seed,
                                     dof_fraction=float(self.p["dof_fraction"]), object_path=spec.object_path)
        reset = self._call(self._reset_client, request, "/reset_scene", float(self.p["reset_timeout"]))
        if not reset.success:
            raise EpisodeFailure(f"/reset_scene refused: {reset.message}")
        record.object_id, reset_ns = reset.object_id, stamp_ns(reset.stamp)
        record.reset_stamp = reset_ns / 1e9
        source = f"learned policy, cluster {spec.cluster}" if self.policy else "heuristic grasp sampler"
        self._event(spec, EpisodeEvent.START, reset.object_id, note=source)
        if self.policy:
            embedding = self._sample_mode(spec, reset_ns, record).embedding
        else:
            planned, cloud_ns = self._baseline_keyposes(spec, reset_ns)
        not_before, gripper_closed = reset_ns, False
        for phase in range(len(PHASE_NAMES)):
            if self.policy:
                answer = self._predict(embedding, phase, gripper_closed, not_before)
                candidates, confidence = [answer.keypose, *answer.alternatives], float(answer.confidence)
                observed = stamp_ns(answer.keypose.header.stamp)
            else:
                candidates, confidence, observed = [planned[phase]], -1.0, cloud_ns
            self._moved = True
            result = self._execute(candidates[0], candidates[1:])
            ended = self.get_clock().now().nanoseconds
            keypose = candidates[max(result.candidate, 0)]  # the one executed (the prediction when none was)
            record.phases.append(PhaseRecord(phase, keypose_data(keypose).to_json(), confidence, observed / 1e9,
                                             not_before / 1e9, bool(result.success), result.message,
                                             float(result.position_error), float(result.orientation_error),
                                             int(result.candidate)))
            if not result.success:
                # The object decides success, not the arm: a drawer at its end stop keeps the hand
                # from p2, and a REACH that bumps a door may already have opened it.
                record.note = f"stopped at {PHASE_NAMES[phase]}: {result.message}"
                break
            not_before, gripper_closed = ended, bool(keypose.gripper_closed)
        settled = self.get_clock().now().nanoseconds + int(float(self.p["settle_time"]) * 1e9)
        state = self._retry(lambda: (self._latest("_object_state", settled), "no /object_state yet"),
                            "no /object_state after the motion")
        try:
            record.largest_change = largest_change(reset.dof_names, reset.dof_initial, reset.dof_lower, reset.dof_upper,
                                                   state.name, state.position)
        except ValueError as exc:
            raise EpisodeFailure(str(exc)) from exc
        record.success = is_success(record.largest_change)

    def _finish(self, spec: EpisodeSpec, record: EpisodeRecord, log: EpisodeLog) -> None:
        self._event(spec, EpisodeEvent.END, record.object_id, record.success, record.note)
        log.append(record)
        cluster = f" cluster {record.cluster}" if self.policy else ""
        self.get_logger().info(
            f"episode {spec.index} {record.object_id or '(no object)'}{cluster}: {'SUCCESS' if record.success else 'failure'} "
            f"(largest DoF change {100 * record.largest_change:.0f}% of its range, {record.seconds:.1f} s)"
            f"{': ' + record.note if record.note else ''}")

    def run(self) -> tuple[list[EpisodeRecord], bool]:
        """Every planned episode; returns the records and whether Ctrl-C ended the run."""
        path = Path(self.p["jsonl_file"] or f"runs/episode_runner/episodes-{datetime.now():%Y%m%d-%H%M%S}.jsonl")
        log = EpisodeLog(path)
        self.get_logger().info(f"{len(self.plan)} episodes, keyposes from the "
                               f"{'learned policy' if self.policy else 'heuristic grasp sampler (baseline)'}; records: {path}")
        records, interrupted = [], False
        for spec in self.plan:
            record = EpisodeRecord(spec.index, self.p["keyposes"], spec.category, spec.instance, spec.object_path, spec.seed,
                                   spec.cluster)
            started = time.monotonic()
            try:
                self._wait_for_servers()
                started = time.monotonic()  # an episode's time starts once its servers are there
                self._run_episode(spec, record)
            except EpisodeFailure as exc:
                record.note = str(exc)
            except Interrupted:
                record.note, interrupted = "interrupted (Ctrl-C)", True
            record.seconds = time.monotonic() - started
            self._finish(spec, record, log)
            records.append(record)
            if interrupted:
                break
        successes = sum(r.success for r in records)
        self.get_logger().info(f"SSR {successes}/{len(records)}; records in {path}\n{summary_table(records)}")
        self._episode_pub.wait_for_all_acked(Duration(seconds=EVENT_ACK_TIMEOUT))
        return records, interrupted


def episodes(node: EpisodeRunner, _stop: threading.Event) -> int:
    """The run: 0 when episodes ran, INTERRUPTED after Ctrl-C, 1 when none could run."""
    records, interrupted = node.run()
    return INTERRUPTED if interrupted else (0 if records else 1)


def main(args: list[str] | None = None) -> int:
    # SIGINT / SIGTERM only set stop: the context must stay up until the running goal is cancelled.
    return run_client(EpisodeRunner, episodes, "episode_runner", args)


if __name__ == "__main__":
    raise SystemExit(main())
