#!/usr/bin/env bash
# Records the three-drawer stand-in's demonstrations through the node graph, in one command:
#   bash scripts/record_standin_demos.sh [OUT]        (default runs/teleop; resumes nothing: OUT is replaced)
# 60 episodes as the paper's real-world data: the three-drawer shelf at randomised placements, one
# drawer half-open and the others shut; per initial state (bottom, middle, top half-open) 10 pushes
# and 10 pulls, grasp points random along the drawer's handle. The cell: sim_node (Kinova j2s6s200,
# the azure_kinect rig with its sensor realism, SAPIEN rendering, one cloud per sim second) +
# control_node + bag_recorder (one bag per episode) + scripted_teleop. Placement seeds: drawer d's
# episode k uses seed 1000 d + k (the stand-in evaluation draws its placements elsewhere). Failed
# episodes stay recorded with the operator's verdict false (training skips them) and are counted
# at the end. Node logs go to OUT/logs/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$((RANDOM % 100 + 101))}"  # outside the tests' 1..100 (tests/harness.py)
ROBOT=kinova_j2s6s200
OUT="${1:-$ROOT/runs/teleop}"
PER_STATE=20
rm -rf "$OUT"; mkdir -p "$OUT/logs"
LOGS="$OUT/logs"
# shellcheck source=/dev/null
. "$ROOT/scripts/cell.sh"
start actaim2_sim sim_node -p robot:=$ROBOT -p rig:=azure_kinect -p render_path:=sapien -p camera_rate:=1.0 \
  -p category:=three_drawer_shelf -p instance:=0
start actaim2_control control_node -p robot:=$ROBOT
start actaim2_policy bag_recorder -p use_sim_time:=true -p output:="$OUT" -p split_by_episode:=true -p compression:=zstd \
  -p discovery_period:=0.2 -p summary_file:="$LOGS/recorder_summary.json"
wait_for_clouds
for drawer in 0 1 2; do  # drawer_0 is the lowest
  ros2 run actaim2_control scripted_teleop --ros-args -p robot:=$ROBOT -p episodes:=$PER_STATE \
    -p seed:=$((1000 * drawer)) -p first_episode:=$((PER_STATE * drawer)) -p category:=three_drawer_shelf \
    -p instance:=0 -p dof_fraction:=0.5 -p others_fraction:=0.0 -p 'modes:=[push, pull]' \
    -p "joints:=[drawer_${drawer}_joint]" 2>&1 | tee "$LOGS/scripted_teleop_drawer_$drawer.log"
done
stop_nodes
grep -h "episodes succeeded" "$LOGS"/scripted_teleop_drawer_*.log
