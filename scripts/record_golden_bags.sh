#!/usr/bin/env bash
# Records the golden bags of bags/ and their golden outputs, in one command:
#   bash scripts/record_golden_bags.sh
# Re-run it whenever the simulator, the robot models or the perception configuration change
# what the bags show; then commit bags/sim_azure_kinect_* and tests/bags/golden/ (the .npz and policy_azure_kinect.*).
#
# The cell: sim_node (Kinova j2s6s200, the azure_kinect rig with its sensor realism, SAPIEN
# rendering, one cloud per sim second) + control_node + scripted_teleop (the scripted
# teleoperator: one drawer half-open, the others shut, as in the paper's fine-tuning data) +
# bag_recorder (one bag per episode, zstd chunks, sim-time receive stamps). Episode 0 pulls the
# top drawer open, episode 1 pushes the middle one shut. The golden outputs are what
# fusion_node must publish for each bag (computed in-process by actaim2.perception.bag_views:
# tests/bags/golden.py). Node logs go to runs/golden_bags/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh"
cd "$ROOT"
# its own DDS domain, outside the tests' 1..100 (tests/harness.py): no other graph on this machine is recorded
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$((RANDOM % 100 + 101))}"
ROBOT=kinova_j2s6s200
SEED=7
LOGS="$ROOT/runs/golden_bags"; rm -rf "$LOGS"; mkdir -p "$LOGS"
TMP="$LOGS/episodes"
# shellcheck source=/dev/null
. "$ROOT/scripts/cell.sh"
start actaim2_sim sim_node -p robot:=$ROBOT -p rig:=azure_kinect -p render_path:=sapien -p camera_rate:=1.0 \
  -p category:=three_drawer_shelf -p instance:=0 -p seed:=$SEED
start actaim2_control control_node -p robot:=$ROBOT
start actaim2_policy bag_recorder -p use_sim_time:=true -p output:="$TMP" -p split_by_episode:=true -p compression:=zstd \
  -p discovery_period:=0.2 -p summary_file:="$LOGS/recorder_summary.json"
wait_for_clouds
ros2 run actaim2_control scripted_teleop --ros-args -p robot:=$ROBOT -p episodes:=2 -p seed:=$SEED \
  -p category:=three_drawer_shelf -p instance:=0 -p dof_fraction:=0.5 -p others_fraction:=0.0 \
  -p 'modes:=[pull, push]' -p 'joints:=[drawer_2_joint, drawer_1_joint]' 2>&1 | tee "$LOGS/scripted_teleop.log"
grep -q "2/2 episodes succeeded" "$LOGS/scripted_teleop.log" || { echo "[golden] an episode failed: not replacing the bags"; exit 1; }
stop_nodes
rm -rf bags/sim_azure_kinect_pull bags/sim_azure_kinect_push
mv "$TMP/episode_0000" bags/sim_azure_kinect_pull
mv "$TMP/episode_0001" bags/sim_azure_kinect_push
python tests/bags/golden.py write bags/sim_azure_kinect_pull bags/sim_azure_kinect_push
python scripts/make_golden_checkpoint.py  # the policy_node half: a test checkpoint trained on the new bags
python tests/bags/golden_policy.py write
du -sh bags/sim_azure_kinect_* tests/bags/golden
