#!/usr/bin/env bash
# The main job: set everything up (idempotent), start the node graph and run sim-loop episodes
# through the learned policy.
#   bash scripts/demo.sh [episode_runner parameters as name:=value ...]
#   e.g. bash scripts/demo.sh episodes:=5 categories:=[refrigerator] clusters:=[0,1,2]
#   real objects: bash scripts/demo.sh catalogue:=partnet partnet_root:=$HOME/pm splits:=[val]
#
# `actaim2 launch sim_panda_ring5` starts sim_node (SAPIEN, Panda, ring5 cameras), fusion_node,
# control_node and policy_node (the committed checkpoint, actaim2_policy/checkpoints/actaim2_ring5);
# episode_runner then runs DESIGN.md's loop: /reset_scene -> /sample_mode (a cluster drawn from the
# learned prior) -> /predict_keypose + /execute_keypose for the four phases -> success from the
# object's DoF. It prints each episode's outcome and an SSR table at the end.
# Without a committed checkpoint the runner falls back to the heuristic grasp sampler
# (keyposes:=sampler, the non-learned baseline) and the output says so.
# Logs: runs/demo/sim_panda_ring5/<node>.log, runs/demo/episode_runner.log, runs/demo/episodes.jsonl.
# Live view: viz_node serves the graph to Foxglove on ws://127.0.0.1:8765 (open the layout
# docs/foxglove/actaim2_layout.json); ACTAIM2_VIZ=false leaves it out.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
LOGS="$ROOT/runs/demo"; mkdir -p "$LOGS"

if checkpoint="$(python -m actaim2.policy.locate)"; then
  keyposes=policy
  echo "[demo] keyposes: the learned policy (policy_node) from checkpoint $checkpoint"
else
  keyposes=sampler
  echo "[demo] ######################################################################################"
  echo "[demo] NO COMMITTED CHECKPOINT: $checkpoint"
  echo "[demo] This run uses the HEURISTIC GRASP SAMPLER (keyposes:=sampler, the non-learned baseline),"
  echo "[demo] NOT the learned policy. policy_node starts anyway and refuses every request with the reason."
  echo "[demo] ######################################################################################"
fi

viz="${ACTAIM2_VIZ:-true}"
actaim2 launch sim_panda_ring5 "viz:=$viz" --logs "$LOGS" >"$LOGS/launch.log" 2>&1 &
launch_pid=$!
stop_graph() {  # actaim2 launch stops every node on SIGTERM (a background job here ignores SIGINT)
  kill -TERM "$launch_pid" 2>/dev/null || true
  wait "$launch_pid" 2>/dev/null || true
  echo "[demo] graph stopped (node logs: runs/demo/sim_panda_ring5/)"
}
trap stop_graph EXIT
echo "[demo] started the graph sim_panda_ring5 (log: runs/demo/launch.log); the runner waits for its services"
[ "$viz" = true ] && echo "[demo] live view: connect Foxglove to ws://127.0.0.1:8765, open docs/foxglove/actaim2_layout.json"

runner_args=(-p "keyposes:=$keyposes" -p "jsonl_file:=$LOGS/episodes.jsonl" -p "server_timeout:=180.0")
for a in "$@"; do runner_args+=(-p "$a"); done
ros2 run actaim2_policy episode_runner --ros-args --params-file actaim2_policy/config/episode_runner.yaml \
  "${runner_args[@]}" 2>&1 | tee "$LOGS/episode_runner.log"
[ "$keyposes" = policy ] || echo "[demo] reminder: these episodes used the heuristic grasp sampler, not the learned policy ($checkpoint)"
