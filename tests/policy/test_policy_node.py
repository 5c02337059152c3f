"""policy_node over real DDS: /sample_mode and /predict_keypose called from this process, the node in
its own (started with `ros2 run`), views published here as fusion_node publishes them.

Four nodes run side by side (services remapped apart): the tiny checkpoint (with two fallback
rotations per keypose); the same with a
predictor trained on robot-visible views (two views topics), mode guidance and two operator mode labels mapped
to clusters (as fine-tuning on labelled demonstrations writes them); a checkpoint that does not exist;
one trained under another perception configuration. Every bad request gets success=false with
the reason, and each node keeps serving.
"""
from __future__ import annotations

import json
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from harness import NodeProcess, wait_for
from tiny_policy import TARGETS

SERVICES = ("/sample_mode", "/predict_keypose", "/interaction_mode")
LABEL_CLUSTER = {"push": 1, "pull": 3}  # the split checkpoint's mode labels


def start_policy(log_dir: Path, name: str, params: dict) -> NodeProcess:
    folder = log_dir / name
    folder.mkdir()
    remaps = [] if name == "policy_node" else [a for s in SERVICES for a in ("-r", f"{s}:=/{name}{s}")]
    return NodeProcess("actaim2_policy", "policy_node", {"torch_threads": 1, **params},
                       ["--ros-args", "-r", f"__node:={name}", *remaps], folder)


@pytest.fixture(scope="module")
def nodes(tiny_checkpoint, tmp_path_factory):
    logs = tmp_path_factory.mktemp("policy_nodes")
    split = logs / "split_checkpoint"
    split.mkdir()
    for suffix in (".json", ".safetensors"):
        shutil.copy(tiny_checkpoint.stem.with_suffix(suffix), split / f"policy{suffix}")
    meta = json.loads((split / "policy.json").read_text())
    meta["robot_filter"] = {"selector": True, "predictor": False}
    meta.setdefault("lineage", {})["finetune"] = {"mode_labels": {"label_cluster": LABEL_CLUSTER}}
    (split / "policy.json").write_text(json.dumps(meta))
    base = {"checkpoint": str(tiny_checkpoint.stem), "perception_config": str(tiny_checkpoint.perception_yaml)}
    started = {
        "policy_node": start_policy(logs, "policy_node", {**base, "keypose_alternatives": 2}),
        "split": start_policy(logs, "split", {**base, "checkpoint": str(split / "policy"), "views_topic": "/split/views",
                                              "predictor_views_topic": "/split/views_with_robot", "mode_guidance": 2.0,
                                              "noise_scale": 1.0}),
        "missing": start_policy(logs, "missing", {**base, "checkpoint": "/no/such/policy"}),
        "mismatch": start_policy(logs, "mismatch", {**base, "perception_config": "ring5"}),
    }
    yield started
    for node in started.values():
        node.stop()


class Client:
    """Calls the services of one policy node and publishes its views."""

    def __init__(self, node, prefix: str = "", views_topic: str = "/ortho_views"):
        from actaim2_msgs.msg import InteractionMode, OrthoViews
        from actaim2_msgs.srv import PredictKeypose, SampleMode

        from actaim2_policy.policy_node import MODE_QOS, VIEWS_QOS

        self.node = node
        self.sample = node.create_client(SampleMode, f"{prefix}/sample_mode")
        self.predict = node.create_client(PredictKeypose, f"{prefix}/predict_keypose")
        self.publishers = {}
        self.views_topic = views_topic
        self._views_qos, self._views_type = VIEWS_QOS, OrthoViews
        self.modes: list = []
        node.create_subscription(InteractionMode, f"{prefix}/interaction_mode", self.modes.append, MODE_QOS)
        assert self.sample.wait_for_service(timeout_sec=120.0) and self.predict.wait_for_service(timeout_sec=30.0)

    def publish(self, data: np.ndarray, config, stamp: float, digest: str | None = None, topic: str | None = None) -> None:
        from actaim2.perception.ortho_views import VIEWS

        topic = topic or self.views_topic
        if topic not in self.publishers:
            self.publishers[topic] = self.node.create_publisher(self._views_type, topic, self._views_qos)
            assert wait_for(lambda: self.publishers[topic].get_subscription_count() > 0, 30.0)
        msg = self._views_type(height=data.shape[2], width=data.shape[3], views=list(VIEWS), channels=list(config.channels),
                               data=data.astype(np.float32).ravel().tolist(), config_digest=digest or config.digest())
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp), int(round((stamp % 1) * 1e9))
        msg.header.frame_id = "world"
        self.publishers[topic].publish(msg)

    def _call(self, client, request):
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        assert done.wait(30.0), "no answer"
        return future.result()

    def sample_mode(self, cluster: int = -1, seed: int = 0, mode_label: str = ""):
        from actaim2_msgs.srv import SampleMode

        return self._call(self.sample, SampleMode.Request(cluster=cluster, seed=seed, mode_label=mode_label))

    def predict_keypose(self, embedding, phase: int = 0, gripper_closed: bool = False, not_before: float = 0.0):
        from actaim2_msgs.srv import PredictKeypose

        request = PredictKeypose.Request(embedding=[float(v) for v in embedding], phase=phase, gripper_closed=gripper_closed)
        request.not_before.sec, request.not_before.nanosec = int(not_before), int(round((not_before % 1) * 1e9))
        return self._call(self.predict, request)


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def test_services_answer_from_the_latest_views_stamped_with_them(ros_node, nodes, tiny_checkpoint):
    client = Client(ros_node)
    for answer in (client.sample_mode(), client.predict_keypose(np.zeros(20))):
        assert not answer.success and answer.message.startswith("no views yet: nothing received on /ortho_views")
    assert "policy_node ready" in nodes["policy_node"].output() and "warm-up" in nodes["policy_node"].output()

    config, views = tiny_checkpoint.config, tiny_checkpoint.views
    client.publish(views[0], config, stamp=5.0)
    assert wait_for(lambda: client.sample_mode(seed=7).success, 20.0)
    first, again, chosen = client.sample_mode(seed=7), client.sample_mode(seed=7), client.sample_mode(cluster=2, seed=7)
    assert first.success and seconds(first.observation_stamp) == 5.0 and len(first.embedding) == 20
    assert list(first.embedding) == list(again.embedding) and chosen.cluster == 2 and 0 <= first.cluster < 4
    # noise_scale 0 by default: one eps per cluster and views whatever the seed
    assert list(client.sample_mode(cluster=2, seed=8).embedding) == list(chosen.embedding)
    assert np.isclose(sum(first.cluster_probabilities), 1.0, atol=1e-5)
    assert str(tiny_checkpoint.stem) in first.message  # what is served, said in every answer
    # The mode in use goes out on /interaction_mode, stamped with its views.
    assert wait_for(lambda: any(m.cluster == 2 and seconds(m.header.stamp) == 5.0 for m in client.modes), 10.0)
    assert list(client.modes[-1].embedding) == list(chosen.embedding)

    for phase, target in enumerate(TARGETS):
        answer = client.predict_keypose(first.embedding, phase, phase == 3, not_before=5.0)
        assert answer.success, answer.message
        kp = answer.keypose
        assert kp.header.frame_id == "world" and seconds(kp.header.stamp) == 5.0 and kp.phase == phase
        position = [kp.pose.position.x, kp.pose.position.y, kp.pose.position.z]
        assert np.linalg.norm(np.subtract(position, target[:3])) < 0.04 and kp.gripper_closed == bool(target[7])
        q = kp.pose.orientation
        assert np.isclose(np.linalg.norm([q.x, q.y, q.z, q.w]), 1.0) and 0.0 < answer.confidence <= 1.0
        # keypose_alternatives 2: the same point, stamp and gripper with other rotations, for control_node's fallback
        assert len(answer.alternatives) == 2
        for alt in answer.alternatives:
            assert alt.header == kp.header and alt.phase == phase and alt.gripper_closed == kp.gripper_closed
            assert alt.pose.position == kp.pose.position and alt.pose.orientation != kp.pose.orientation

    # Newer views replace the old ones: the keypose carries their stamp.
    client.publish(views[1], config, stamp=6.5)
    assert wait_for(lambda: seconds(client.predict_keypose(first.embedding, not_before=6.5).keypose.header.stamp) == 6.5, 20.0)


def test_every_bad_request_is_answered_with_its_reason_and_the_node_keeps_serving(ros_node, nodes, tiny_checkpoint):
    from actaim2.perception.config import load_perception_config

    client = Client(ros_node)
    config, views = tiny_checkpoint.config, tiny_checkpoint.views
    client.publish(views[0], config, stamp=10.0)
    assert wait_for(lambda: client.predict_keypose(np.zeros(20), not_before=10.0).success, 20.0)
    eps = client.sample_mode(seed=1).embedding
    refusals = {
        "embedding has 3 values, the checkpoint's predictor expects 20": client.predict_keypose([0.1, 0.2, 0.3]),
        "embedding contains NaN or infinite values (1 of 20)": client.predict_keypose([*eps[:19], float("nan")]),
        "embedding contains NaN or infinite values (2 of 20)": client.predict_keypose([float("inf"), -float("inf"), *eps[2:]]),
        "unknown phase 9: expected one of 0 (INIT)": client.predict_keypose(eps, phase=9),
        "unknown cluster 4: the mode selector has 4 clusters (0..3)": client.sample_mode(cluster=4),
        "unknown cluster -5": client.sample_mode(cluster=-5),
        "unknown mode label 'pull': it maps no mode labels": client.sample_mode(mode_label="pull"),
        "stale observation: the latest views are stamped 10.000 s, before not_before 10.500 s":
            client.predict_keypose(eps, not_before=10.5),
    }
    for reason, answer in refusals.items():
        assert not answer.success and reason in answer.message, (reason, answer.message)
    # Views of another perception configuration are refused, and requests say so until good views come.
    other = load_perception_config("ring5")
    client.publish(views[0], config, stamp=11.0, digest=other.digest())
    assert wait_for(lambda: "were refused" in client.predict_keypose(eps).message, 20.0)
    assert f"views made under perception configuration {other.digest()} but the checkpoint expects {config.digest()}" \
        in client.sample_mode().message
    client.publish(views[0], config, stamp=12.0)
    assert wait_for(lambda: client.predict_keypose(eps, not_before=12.0).success, 20.0)
    assert nodes["policy_node"].alive()


@pytest.mark.parametrize("name, reason", [
    ("missing", "checkpoint failed to load: checkpoint '/no/such/policy' not found"),
    ("mismatch", "checkpoint failed to load: "),
])
def test_a_checkpoint_that_failed_to_load_is_the_answer_to_every_request(ros_node, nodes, name, reason):
    client = Client(ros_node, prefix=f"/{name}")
    for answer in (client.sample_mode(), client.predict_keypose(np.zeros(20), phase=1)):
        assert not answer.success and answer.message.startswith(reason), answer.message
    if name == "mismatch":  # the checkpoint's 64 px views are not the serving ring5 configuration's 128
        assert "resolution: 64 != 128" in answer.message
    assert nodes[name].alive() and reason in nodes[name].output()


def test_selector_and_predictor_each_get_views_with_their_robot_filter_setting(ros_node, nodes, tiny_checkpoint):
    client = Client(ros_node, prefix="/split", views_topic="/split/views")
    config, views = tiny_checkpoint.config, tiny_checkpoint.views
    with_robot = config.replace(remove_robot_views=False)
    client.publish(views[0], config, stamp=20.0)
    client.publish(views[1], with_robot, stamp=21.0, topic="/split/views_with_robot")
    assert wait_for(lambda: client.sample_mode().success and client.predict_keypose(np.zeros(20)).success, 20.0)
    assert seconds(client.sample_mode().observation_stamp) == 20.0
    assert seconds(client.predict_keypose(np.zeros(20)).keypose.header.stamp) == 21.0
    # mode_guidance 2.0: the node answers the library's guided prediction, which is not the plain one
    from actaim2.policy.inference import PolicyModel
    from actaim2.policy.views import Views

    library = PolicyModel.load(Path(nodes["split"].params["checkpoint"]), config, "cpu")
    eps = np.asarray(client.sample_mode(seed=3).embedding, np.float32)
    answer = client.predict_keypose(eps, phase=1)
    served = Views(0, views[1].astype(np.float32))
    guided, plain = (library.predict_keypose(served, eps, 1, False, guidance=w) for w in (2.0, 0.0))
    kp = answer.keypose.pose.position
    assert np.allclose([kp.x, kp.y, kp.z], guided.keypose.position, atol=1e-5)
    assert np.isclose(answer.confidence, guided.confidence, rtol=1e-4) and not np.isclose(guided.confidence, plain.confidence)
    # noise_scale 1.0: the seed draws the library's sample of the trained distribution, not the noise-free eps
    first, second = (np.asarray(client.sample_mode(cluster=2, seed=s).embedding) for s in (1, 2))
    selector_views = Views(0, views[0].astype(np.float32))
    drawn, noise_free = (library.sample_mode(selector_views, 2, 1, noise_scale=s).eps for s in (1.0, 0.0))
    assert np.allclose(first, drawn, atol=1e-5) and not np.allclose(first, second, atol=1e-3)
    assert not np.allclose(drawn, noise_free, atol=1e-3)
    # Robot-hidden views on the predictor's topic are not what it was trained on.
    client.publish(views[0], config, stamp=22.0, topic="/split/views_with_robot")
    assert wait_for(lambda: "were refused" in client.predict_keypose(np.zeros(20)).message, 20.0)
    assert with_robot.digest() in client.predict_keypose(np.zeros(20)).message
    assert client.sample_mode().success


def test_sample_mode_by_mode_label_serves_the_labels_cluster_and_refuses_unknown_or_disagreeing_labels(ros_node, nodes,
                                                                                                       tiny_checkpoint):
    client = Client(ros_node, prefix="/split", views_topic="/split/views")
    client.publish(tiny_checkpoint.views[0], tiny_checkpoint.config, stamp=30.0)
    assert wait_for(lambda: client.sample_mode(mode_label="pull").success, 20.0)
    for label, cluster in LABEL_CLUSTER.items():
        by_label, by_cluster = client.sample_mode(seed=4, mode_label=label), client.sample_mode(cluster=cluster, seed=4)
        assert by_label.success and by_label.cluster == cluster, by_label.message
        assert list(by_label.embedding) == list(by_cluster.embedding)  # the same draw as asking for its cluster
        assert client.sample_mode(cluster=cluster, seed=4, mode_label=label).success  # agreeing: answered
        # /interaction_mode names the label of the cluster in use
        assert wait_for(lambda: any(m.cluster == cluster and m.label == label for m in client.modes), 10.0)
    refusals = {
        "unknown mode label 'open': it maps pull, push": client.sample_mode(mode_label="open"),
        "mode label 'push' is cluster 1, the request asks for cluster 3": client.sample_mode(cluster=3, mode_label="push"),
    }
    for reason, answer in refusals.items():
        assert not answer.success and reason in answer.message, (reason, answer.message)
    assert client.sample_mode(mode_label="push").success and nodes["split"].alive()
