# Sourced by the scripts that record through a running node graph (record_golden_bags.sh,
# record_standin_demos.sh): start nodes in the background with their logs in $LOGS, and stop them
# all on exit (SIGINT first, so bag_recorder closes its bag; SIGKILL after 10 s).
# The caller sets LOGS and sources scripts/env.sh first.
pids=()
stop_nodes() {
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  pids=()
}
trap stop_nodes EXIT
start() {  # start <package> <executable> <parameters...>
  local package=$1 executable=$2; shift 2
  ros2 run "$package" "$executable" --ros-args "$@" >"$LOGS/$executable.log" 2>&1 &
  pids+=($!)
  echo "[cell] started $package/$executable (log: $LOGS/$executable.log)"
}
wait_for_clouds() {  # the recorder subscribes once sim_node publishes (SAPIEN's first picture takes a while)
  for _ in $(seq 600); do
    grep -q "/points2 \[" "$LOGS/bag_recorder.log" && return 0
    sleep 0.2
  done
  echo "[cell] the recorder never saw /points2"
  return 1
}
