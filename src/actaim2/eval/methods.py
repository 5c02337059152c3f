"""The rows of the evaluation tables: what each method is, how its samples are grouped for Mode SSR.

Grouping (``mode_ssr.py`` chooses a group per mode on half of the samples):
  cluster  the method is asked for each of its K clusters (codes) in turn: ActAIM2 and its input
           ablations, VQVAE-RVT
  goal     the group is the goal (DoF, direction) the oracle was given: Goal-RVT
  pseudo   no discrete modes: each run of 8 consecutive slots visits the 8 pseudo-clusters in a
           seeded random order (``sources.pseudo_group``), a random partition into 8 equal ones: the
           yardstick for what Mode SSR gives without any mode structure (Data Collection,
           random sampler, ActAIM's CVAE).
"""
from __future__ import annotations

from dataclasses import dataclass

PSEUDO_CLUSTERS = 8  # the paper's K
# How samples fall into pseudo-clusters (``sources.pseudo_group``), recorded in run.json: results
# grouped another way ("slot mod 8") must not be mixed with these.
PSEUDO_GROUPING = "shuffled per repetition"


@dataclass(frozen=True)
class Method:
    name: str  # key in task keys, the CLI and results
    title: str  # row title in the tables
    grouping: str  # "cluster" | "goal" | "pseudo"
    needs: str  # what the CLI must be given
    about: str  # one line for the tables' notes


METHODS: dict[str, Method] = {m.name: m for m in (
    Method("actaim2", "ActAIM2", "cluster", "--checkpoint",
           "CGMVAE mode selector + action predictor; samples drawn uniformly over the K clusters"),
    Method("data_collection", "Data Collection", "pseudo", "--data",
           "the GMM-adaptive sampler of data collection (fitted on the object's random + heuristic-grasp trajectories), "
           "IK-screened as in collection"),
    Method("random", "Random sampler", "pseudo", "",
           "the random sampler of data collection (uniform point, rotation and motion), IK-screened as in collection"),
    Method("goal_rvt", "Goal-RVT (oracle)", "goal", "--goal-rvt and --data (its encoder E)",
           "the action predictor fed z = E(O_init) - E(O_goal), O_goal a robot-hidden render of the object set to "
           "the goal's end state (privileged)"),
    Method("vqvae_rvt", "VQVAE-RVT", "cluster", "--vqvae",
           "VQ-VAE mode selector (K codes) + action predictor; samples drawn uniformly over the codes"),
    Method("actaim_cvae", "ActAIM (CVAE)", "pseudo", "--cvae",
           "CVAE mode selector (continuous latent) + action predictor"),
    Method("actaim2_depth", "ActAIM2, depth-only predictor", "cluster", "--ablation-depth",
           "ablation: ActAIM2's mode selector + a predictor retrained on depth (with its occupancy mask) and pixel "
           "location only, no RGB or XYZ; sampled as ActAIM2"),
    Method("actaim2_single_view", "ActAIM2, single-view predictor", "cluster", "--ablation-single-view",
           "ablation: ActAIM2's mode selector + a predictor retrained on one orthographic view (its checkpoint names "
           "which), the point from that view's heatmap and a predicted depth cell; sampled as ActAIM2"),
)}
# Input ablations of ActAIM2 (the paper's appendix): sampled exactly as the ActAIM2 row.
ABLATIONS = ("actaim2_depth", "actaim2_single_view")


def ablation_problem(method: str, inputs: list[str], view: str) -> str | None:
    """Why a checkpoint whose predictor reads ``inputs`` of ``view`` cannot be ``method``'s row (None: it can)."""
    if method == "actaim2_depth" and ("depth" not in inputs or {"rgb", "xyz"} & set(inputs) or view != "all"):
        return f"its predictor reads {inputs} of view {view!r}: the depth-only row needs depth without rgb and xyz, all views"
    if method == "actaim2_single_view" and view == "all":
        return "its predictor reads all five views: the single-view row needs one (train config ablation_single_view)"
    return None

NOT_REPRODUCED = {
    "Where2Act": "needs per-point affordance and action-proposal networks trained on short-horizon "
                 "floating-gripper pokes with the complete object cloud; our data are full-arm four-keypose "
                 "trajectories, so there is nothing to train it on without a second collection",
    "Goal-ActAIM": "ActAIM's goal-conditioned Perceiver predictor is not implemented; the goal-conditioned oracle "
                   "is measured with our predictor instead (Goal-RVT)",
}
