"""policy_node: /sample_mode (mode selector) and /predict_keypose (action predictor) from a checkpoint.

A thin adapter over :class:`actaim2.policy.inference.PolicyModel`: it keeps the latest
/ortho_views each model accepts (same perception configuration digest as the checkpoint's,
else refused with the reason), answers the two services from them, stamps every keypose with the
stamp of the views it used, and publishes the mode in use on /interaction_mode.

Start-up: load and check the checkpoint against the serving perception configuration, warm the
models up, then create the services and log "policy_node ready", so a client that found the
services gets answers at full speed. A checkpoint that cannot be loaded does not stop the node:
every request is answered ``success=false`` with "checkpoint failed to load: <why>", as every
other bad request (wrong embedding length, NaN, unknown cluster, mode label or phase, a mode label
that disagrees with the requested cluster, no views yet, views older than ``not_before``) is
answered with its reason while the node keeps serving. A ``mode_label`` is served by the cluster
the checkpoint's fine-tuning mapped it to (``PolicyModel.mode_labels``).

Threads: views arrive in their own callback group, so receiving a 2.6 MB message never waits
for an inference, and the two services share one group (one inference at a time).
"""
from __future__ import annotations

import array
import threading

import numpy as np
import torch
from actaim2_msgs.msg import InteractionMode, OrthoViews
from actaim2_msgs.srv import PredictKeypose, SampleMode
from builtin_interfaces.msg import Time
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.service_introspection import ServiceIntrospectionState

from actaim2.artifact.serving import DEFAULT_SERVING, ServingConfig
from actaim2.perception.config import load_perception_config
from actaim2.perception.ortho_views import VIEWS
from actaim2.policy.inference import ROLES, PolicyLoadError, PolicyModel
from actaim2.policy.locate import COMMITTED, installed_folders, resolve_checkpoint
from actaim2.policy.requests import (
    NO_VIEWS,
    RequestError,
    check_cluster,
    check_embedding,
    check_fresh,
    check_phase,
    resolve_mode_label,
)
from actaim2.policy.views import Views, accept_views
from actaim2_ros.keypose import keypose_msg
from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.stamps import stamp_msg, stamp_ns

VIEWS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)  # as fusion_node publishes them
# The mode in use is state: a recorder that starts later still learns it.
MODE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# The predicted position heatmaps, for people (viz_node): the latest one is what matters.
HEATMAPS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
# Service events of /sample_mode and /predict_keypose (requests and responses), rclpy's default.
INTROSPECTION_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
HEATMAP_CHANNEL = "position_probability"

PARAMETERS = {
    "checkpoint": (COMMITTED, "checkpoint stem (<stem>.json + <stem>.safetensors): a path, or a name looked up in "
                                    "share/actaim2_policy/checkpoints (the committed checkpoints)"),
    "perception_config": ("ring5", "the serving perception configuration, as fusion_node's: rig name or PerceptionConfig "
                                   "YAML; a checkpoint trained under another one is refused, naming the differing fields"),
    "device": ("auto", "auto (CUDA when present, else CPU) | cpu | cuda"),
    "torch_threads": (1, "CPU threads for inference; 1 next to the simulator and fusion on 2 cores (a second "
                         "spinning OpenMP thread made each call 10x slower under load)"),
    "views_topic": ("/ortho_views", "views for the mode selector, and for the predictor unless predictor_views_topic is set"),
    "keypose_alternatives": (DEFAULT_SERVING.keypose_alternatives, "fallbacks answered with each keypose: its point with the next likeliest "
                                                   "rotations, 30 deg apart, which control_node plans in turn when it refuses "
                                                   "the keypose (0 = none)"),
    "mode_guidance": (DEFAULT_SERVING.mode_guidance, "weight w of the mode guidance of the predicted point: each view's heatmap log-probabilities "
                                     "l(eps) + w (l(eps) - l(0)), l(0) the predictor fed the mean mode (classifier-free "
                                     "guidance); 0 = the plain predictor, one forward pass"),
    "noise_scale": (DEFAULT_SERVING.noise_scale, "spread of /sample_mode's latent draw relative to the trained selector's (sampling "
                                 "temperature): 1 = as trained, 0 = each cluster's noise-free eps (one eps per cluster and views)"),
    "predictor_views_topic": ("", "views for the action predictor when it was trained with the other robot-filter "
                                  "setting than the selector (fusion_node's alternate_views_topic); empty = views_topic"),
    "service_introspection": (True, "publish the requests and responses of /sample_mode and "
                                    "/predict_keypose on <service>/_service_event (ROS 2 service "
                                    "introspection; viz_node shows the mode probabilities and the "
                                    "predicted keypose from them)"),
}


class PolicyNode(Node):
    def __init__(self) -> None:
        super().__init__("policy_node")
        p = declare_parameters(self, PARAMETERS)
        torch.set_num_threads(int(p["torch_threads"]))
        self._serving = ServingConfig(int(p["keypose_alternatives"]), float(p["mode_guidance"]), float(p["noise_scale"]))
        self._model: PolicyModel | None = None
        self._description = ""  # the model's describe(), answered with every mode: computed once
        self._load_error = ""
        try:
            serving = load_perception_config(p["perception_config"])
            stem = resolve_checkpoint(p["checkpoint"], installed_folders())
            self._model = PolicyModel.load(stem, serving, p["device"])
            warm = self._model.warm_up()
            self._description = self._model.describe()
        except (PolicyLoadError, FileNotFoundError, ValueError) as exc:
            self._load_error = f"checkpoint failed to load: {exc}"

        self._lock = threading.Lock()
        self._views: dict[str, Views | None] = dict.fromkeys(ROLES)
        self._refusal: dict[str, str] = {}
        self._topics = {"selector": p["views_topic"], "predictor": p["predictor_views_topic"] or p["views_topic"]}
        self._last_mode: np.ndarray | None = None
        self._mode_pub = self.create_publisher(InteractionMode, "/interaction_mode", MODE_QOS)
        # /policy/heatmaps: each prediction's per-view position probabilities (OrthoViews),
        # taken from the predictor's own forward pass, and only while someone subscribes.
        self._heatmaps_pub = self.create_publisher(OrthoViews, "/policy/heatmaps", HEATMAPS_QOS)
        self._heatmaps: torch.Tensor | None = None
        if self._model is not None and self._model.predictor is not None:
            self._model.predictor.register_forward_hook(self._keep_heatmaps)
        if self._model is not None:
            views_group = MutuallyExclusiveCallbackGroup()
            for topic in sorted(set(self._topics.values())):
                roles = [r for r in ROLES if self._topics[r] == topic]
                self.create_subscription(OrthoViews, topic, lambda msg, roles=roles: self._on_views(msg, roles), VIEWS_QOS,
                                         callback_group=views_group)
        services = MutuallyExclusiveCallbackGroup()
        servers = [self.create_service(SampleMode, "/sample_mode", self._on_sample_mode,
                                       callback_group=services),
                   self.create_service(PredictKeypose, "/predict_keypose", self._on_predict_keypose,
                                       callback_group=services)]
        if p["service_introspection"]:
            for server in servers:
                server.configure_introspection(self.get_clock(), INTROSPECTION_QOS,
                                               ServiceIntrospectionState.CONTENTS)
        if self._model is None:
            self.get_logger().error(f"{self._load_error}; every request is answered success=false with this reason")
        else:
            self.get_logger().info(f"policy_node ready: {self._description}; "
                                   f"warm-up {1000 * warm:.0f} ms; views: "
                                   f"selector {self._topics['selector']}, predictor {self._topics['predictor']}")

    # -- views ------------------------------------------------------------------------------
    def _on_views(self, msg: OrthoViews, roles: list[str]) -> None:
        for role in roles:
            try:
                views = accept_views(stamp_ns(msg.header.stamp), msg.height, msg.width, msg.views, msg.channels, msg.data,
                                     msg.config_digest, self._model.views_config(role))
            except RequestError as exc:
                with self._lock:
                    self._refusal[role] = f"the latest {self._topics[role]} were refused: {exc}"
                self.get_logger().warning(f"{role}: {exc}", throttle_duration_sec=10.0)
                continue
            with self._lock:
                self._views[role] = views
                self._refusal.pop(role, None)

    def _views_for(self, role: str) -> Views:
        with self._lock:
            views, refusal = self._views[role], self._refusal.get(role)
        if refusal:
            raise RequestError(refusal)
        if views is None:
            raise RequestError(f"{NO_VIEWS}: nothing received on {self._topics[role]} (is fusion_node running?)")
        return views

    def _require_model(self) -> PolicyModel:
        if self._model is None:
            raise RequestError(self._load_error)
        return self._model

    # -- services ---------------------------------------------------------------------------
    def _on_sample_mode(self, request: SampleMode.Request, response: SampleMode.Response) -> SampleMode.Response:
        try:
            model = self._require_model()
            check_cluster(request.cluster, model.clusters)
            cluster = resolve_mode_label(request.mode_label, request.cluster, model.mode_labels)
            views = self._views_for("selector")
            sample = model.sample_mode(views, cluster, request.seed, self._serving.noise_scale)
        except RequestError as exc:
            return self._refuse(response, str(exc))
        except Exception as exc:  # noqa: BLE001 - answered and logged: the node must keep serving
            return self._refuse(response, f"internal error: {type(exc).__name__}: {exc}", error=True)
        response.success = True
        response.message = self._description
        response.cluster = sample.cluster
        response.embedding = sample.eps.tolist()
        response.cluster_probabilities = sample.probabilities.tolist()
        response.observation_stamp = stamp_msg(views.stamp_ns)
        labels = {c: label for label, c in model.mode_labels.items()}
        self._publish_mode(views.stamp_ns, sample.cluster, sample.eps, labels.get(sample.cluster, ""))
        return response

    def _on_predict_keypose(self, request: PredictKeypose.Request,
                            response: PredictKeypose.Response) -> PredictKeypose.Response:
        try:
            model = self._require_model()
            eps = check_embedding(request.embedding, model.embedding_dim)
            check_phase(request.phase)
            views = self._views_for("predictor")
            check_fresh(views.stamp_ns, stamp_ns(request.not_before))
            prediction = model.predict_keypose(views, eps, request.phase, request.gripper_closed, self._serving.keypose_alternatives,
                                               guidance=self._serving.mode_guidance)
        except RequestError as exc:
            return self._refuse(response, str(exc))
        except Exception as exc:  # noqa: BLE001 - answered and logged: the node must keep serving
            return self._refuse(response, f"internal error: {type(exc).__name__}: {exc}", error=True)
        if self._last_mode is None or not np.array_equal(eps, self._last_mode):
            self._publish_mode(views.stamp_ns, -1, eps)  # a mode /sample_mode did not give: cluster unknown
        stamp = stamp_msg(views.stamp_ns)
        self._publish_heatmaps(stamp)
        response.keypose = keypose_msg(prediction.keypose, stamp)
        response.alternatives = [keypose_msg(k, stamp) for k in prediction.alternatives]
        response.success = True
        response.confidence = prediction.confidence
        return response

    def _refuse(self, response, reason: str, error: bool = False):
        response.success = False
        response.message = reason
        (self.get_logger().error if error else self.get_logger().warning)(reason, throttle_duration_sec=5.0)
        return response

    def _keep_heatmaps(self, _module: torch.nn.Module, _inputs: tuple, output) -> None:
        """Forward hook of the predictor: the first row's heatmap logits, kept while someone
        reads /policy/heatmaps."""
        watched = self._heatmaps_pub.get_subscription_count() > 0
        self._heatmaps = output.heatmaps[0].detach() if watched else None

    def _publish_heatmaps(self, stamp: Time) -> None:
        logits, self._heatmaps = self._heatmaps, None
        if logits is None:
            return
        v, h, w = logits.shape
        probabilities = torch.softmax(logits.float().reshape(v, -1), dim=-1).cpu().numpy()
        view = self._model.predictor.config.view_index
        config = self._model.views_config("predictor")
        msg = OrthoViews(height=h, width=w, views=list(VIEWS) if view is None else [VIEWS[view]],
                         channels=[HEATMAP_CHANNEL], half_extent=float(config.half_extent),
                         config_digest=config.digest())
        msg.header.stamp = stamp
        msg.header.frame_id = "world"
        msg.center.x, msg.center.y, msg.center.z = (float(c) for c in config.center)
        msg.data = array.array("f", probabilities.astype(np.float32).tobytes())
        self._heatmaps_pub.publish(msg)

    def _publish_mode(self, stamp: int, cluster: int, eps: np.ndarray, label: str = "") -> None:
        msg = InteractionMode(cluster=int(cluster), embedding=eps.astype(np.float32).tolist(), label=label)
        msg.header.stamp = stamp_msg(stamp)
        msg.header.frame_id = "world"
        self._mode_pub.publish(msg)
        self._last_mode = np.asarray(eps, np.float32).copy()


def main(args: list[str] | None = None) -> int:
    return spin(PolicyNode, "policy_node", args, threads=2)  # one thread per callback group (module docstring)


if __name__ == "__main__":
    raise SystemExit(main())
