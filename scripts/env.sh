# Source this file to use the actaim2 workspace in the current shell:   . scripts/env.sh
# It activates .venv (the ROS 2 Jazzy prefix here), keeps DDS on this machine, selects the
# unpacked Mesa lavapipe for SAPIEN's CPU rendering, sources install/setup.bash, and puts the
# project's `ros2 run` shim on PATH when no real ros2 CLI is installed.
# `--no-workspace` skips install/setup.bash (used by setup.sh before the first build).
_actaim2_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# DDS stays on loopback: the project default for every process that starts rclpy.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
# Several nodes share few cores: OpenBLAS spreading a (76800,3)@(3,3) product over threads took
# 85-100 ms instead of 1 ms under load. One BLAS thread per process (torch keeps its own setting).
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
# Fast DDS with a 32 MB shared-memory segment: clouds of a few MB are not dropped (see actaim2/runtime.py).
export FASTRTPS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE:-$_actaim2_root/src/actaim2/config/fastdds.xml}"

if [ -x "$_actaim2_root/.venv/bin/python" ] && [ "${VIRTUAL_ENV:-}" != "$_actaim2_root/.venv" ]; then
  # shellcheck source=/dev/null
  . "$_actaim2_root/.venv/bin/activate"
fi
if [ -n "${VIRTUAL_ENV:-}" ]; then
  case ":${AMENT_PREFIX_PATH:-}:" in *":$VIRTUAL_ENV:"*) ;; *) export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}";; esac
  case ":${CMAKE_PREFIX_PATH:-}:" in *":$VIRTUAL_ENV:"*) ;; *) export CMAKE_PREFIX_PATH="$VIRTUAL_ENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}";; esac
  case ":${LD_LIBRARY_PATH:-}:" in *":$VIRTUAL_ENV/lib:"*) ;; *) export LD_LIBRARY_PATH="$VIRTUAL_ENV/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}";; esac
fi

if [ -f "$_actaim2_root/.deps/mesa/lvp_icd.json" ] && [ -z "${VK_ICD_FILENAMES:-}" ]; then
  export VK_ICD_FILENAMES="$_actaim2_root/.deps/mesa/lvp_icd.json"
fi

if [ "${1:-}" != "--no-workspace" ] && [ -f "$_actaim2_root/install/setup.bash" ]; then
  # colcon's setup scripts read unset variables: allow that even when the caller uses `set -u`.
  case $- in *u*) set +u; . "$_actaim2_root/install/setup.bash"; set -u;; *) . "$_actaim2_root/install/setup.bash";; esac
fi

if ! command -v ros2 >/dev/null 2>&1 || [ "$(command -v ros2)" = "$_actaim2_root/tools/bin/ros2" ]; then
  case ":$PATH:" in *":$_actaim2_root/tools/bin:"*) ;; *) export PATH="$_actaim2_root/tools/bin:$PATH";; esac
fi
unset _actaim2_root
