#!/usr/bin/env bash
# The main job: set everything up (idempotent), start the node graph and run sim-loop episodes.
#   bash scripts/demo.sh [episode_runner parameters as name:=value ...]
#   e.g. bash scripts/demo.sh episodes:=5 category:=refrigerator
#
# Nodes: sim_node (SAPIEN, ring5 cameras) -> fusion_node (fused, robot-filtered cloud, ortho
# views) -> control_node (/execute_keypose: Pinocchio IK + Ruckig) <- episode_runner.
# The episode runner chooses keyposes with the heuristic grasp sampler on the fused cloud: the
# learned mode selector / action predictor (/sample_mode, /predict_keypose) replace it once the
# policy is trained; until then this is the most complete real path of the system.
# Node logs go to runs/demo/<node>.log; Ctrl-C stops everything cleanly.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
LOGS="$ROOT/runs/demo"; mkdir -p "$LOGS"
pids=()
stop_nodes() {
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
}
trap stop_nodes EXIT
start() {  # start <package> <executable> <params file>
  ros2 run "$1" "$2" --ros-args --params-file "$3" >"$LOGS/$2.log" 2>&1 &
  pids+=($!)
  echo "[demo] started $1/$2 (log: runs/demo/$2.log)"
}
start actaim2_sim sim_node actaim2_sim/config/sim_node.yaml
start actaim2_perception fusion_node actaim2_perception/config/fusion_node_sim_ring5.yaml
start actaim2_control control_node actaim2_control/config/control_node.yaml
echo "[demo] keyposes: heuristic grasp sampler on /fused_points (the learned policy is not trained yet)"
runner_args=()
for a in "$@"; do runner_args+=(-p "$a"); done
ros2 run actaim2_sim episode_runner --ros-args --params-file actaim2_sim/config/episode_runner.yaml "${runner_args[@]}" \
  2>&1 | tee "$LOGS/episode_runner.log"
