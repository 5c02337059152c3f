#!/usr/bin/env bash
# One idempotent setup step for the actaim2 workspace, shared by both README commands:
#   1. Debian packages (build tools, libusb for Open3D, the Vulkan loader, chromium for the viewer test),
#   2. Mesa lavapipe from the backports suite, unpacked under .deps/ (SAPIEN renders on CPU),
#   3. a venv at .venv with requirements.txt (the venv is the ROS 2 Jazzy prefix) + src/actaim2,
#   4. colcon build of the ROS packages into install/.
# Each step checks whether it is already done; a second run with nothing to do takes seconds.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
log() { printf '[setup] %s\n' "$*"; }
SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"

# ---- 1. Debian packages ---------------------------------------------------------------
APT_PACKAGES=(cmake g++ make git python3-venv libusb-1.0-0 libvulkan1 libgl1 libegl1 libxrender1
              libllvm15 libdrm2 libdrm-amdgpu1 libelf1 libwayland-client0 libx11-xcb1 libxcb-dri3-0
              libxcb-present0 libxcb-randr0 libxcb-shm0 libxcb-sync1 libxcb-xfixes0 libxshmfence1
              libzstd1 chromium)
missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  log "apt-get install ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# ---- 2. Mesa lavapipe >= 25 (Debian 12's 22.3 lacks descriptorBindingPartiallyBound) ----
MESA_DIR="$ROOT/.deps/mesa"
if [ ! -f "$MESA_DIR/lvp_icd.json" ]; then
  . /etc/os-release
  if [ "${VERSION_CODENAME:-}" = "bookworm" ]; then
    log "unpacking Mesa lavapipe from ${VERSION_CODENAME}-backports into .deps/mesa"
    # Reuse the Debian mirror this machine already uses; a private apt state keeps /etc/apt untouched.
    uri=$(awk '/^URIs:/{print $2; exit}' /etc/apt/sources.list.d/debian.sources 2>/dev/null || true)
    [ -n "$uri" ] || uri=$(awk '$1=="deb" && $3=="bookworm" {print $2; exit}' /etc/apt/sources.list 2>/dev/null || true)
    [ -n "$uri" ] || { echo "[setup] no Debian mirror found in /etc/apt" >&2; exit 1; }
    work="$ROOT/.deps/apt"; rm -rf "$work"; mkdir -p "$work/lists/partial" "$work/parts" "$work/debs"
    printf 'Types: deb\nURIs: %s\nSuites: %s-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
      "$uri" "$VERSION_CODENAME" > "$work/parts/backports.sources"
    APT_OPTS=(-o Dir::Etc::SourceList=/dev/null -o "Dir::Etc::SourceParts=$work/parts"
              -o "Dir::State::Lists=$work/lists" -o "Dir::Cache=$work/cache" -o Debug::NoLocking=1)
    apt-get "${APT_OPTS[@]}" update -qq
    (cd "$work/debs" && apt-get "${APT_OPTS[@]}" download -qq "mesa-vulkan-drivers/${VERSION_CODENAME}-backports")
    rm -rf "$MESA_DIR.tmp"; mkdir -p "$MESA_DIR.tmp"
    dpkg -x "$work"/debs/mesa-vulkan-drivers_*.deb "$MESA_DIR.tmp/root"
    lib=$(find "$MESA_DIR.tmp/root" -name libvulkan_lvp.so | head -n 1)
    icd=$(find "$MESA_DIR.tmp/root" -name 'lvp_icd*.json' | head -n 1)
    python3 - "$icd" "$lib" "$MESA_DIR.tmp/lvp_icd.json" <<'PY'
import json, sys
src, lib, dst = sys.argv[1:]
data = json.load(open(src))
data["ICD"]["library_path"] = lib.replace(".tmp/", "/")
json.dump(data, open(dst, "w"), indent=2)
PY
    rm -rf "$MESA_DIR" "$work"; mv "$MESA_DIR.tmp" "$MESA_DIR"
  else
    log "not Debian 12: using the system's Vulkan driver (no lavapipe unpacked)"
    mkdir -p "$MESA_DIR"
  fi
fi

# ---- 3. venv --------------------------------------------------------------------------
VENV="$ROOT/.venv"
[ -x "$VENV/bin/python" ] || { log "creating .venv"; python3 -m venv "$VENV"; touch "$VENV/COLCON_IGNORE"; }
stamp="$VENV/.requirements.sha256"
want=$(cat requirements.txt constraints.txt src/actaim2/pyproject.toml src/actaim2/setup.py | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  log "pip install -r requirements.txt -c constraints.txt (a fresh venv takes a few minutes)"
  "$VENV/bin/pip" install -q --disable-pip-version-check -r requirements.txt -c constraints.txt 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation -e src/actaim2 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/python" -c "import rclpy, sapien, open3d, pinocchio, ruckig, torch, rosbags, rerun, actaim2" \
    || { echo "[setup] venv is incomplete" >&2; exit 1; }
  echo "$want" > "$stamp"
fi

# ---- 4. colcon build ------------------------------------------------------------------
# One build at a time in this workspace (several shells may run setup.sh at once).
mkdir -p log; exec 9>log/.setup.lock; flock 9
# shellcheck source=/dev/null
. "$ROOT/scripts/env.sh" --no-workspace
PACKAGES=(actaim2_msgs actaim2_ros actaim2_sim actaim2_perception actaim2_policy actaim2_control)
# The compat interfaces are built only where the environment lacks them (a real ROS keeps its own).
have_underlay_package() {  # is $1 registered in an ament index outside this workspace?
  local prefix; IFS=: read -ra prefixes <<< "${AMENT_PREFIX_PATH:-}"
  for prefix in "${prefixes[@]}"; do
    case "$prefix" in "$ROOT/install"*|"") continue;; esac
    [ -e "$prefix/share/ament_index/resource_index/packages/$1" ] && return 0
  done
  return 1
}
for compat in tf2_msgs control_msgs; do
  if [ -f "$ROOT/compat/$compat/package.xml" ] && ! have_underlay_package "$compat"; then
    PACKAGES+=("$compat")
  fi
done
src_hash=$( (for p in "${PACKAGES[@]}"; do d=$p; [ -d "$d" ] || d="compat/$p"; find "$d" -type f -not -path '*/__pycache__/*' -print0; done \
             | sort -z | xargs -0 sha256sum; cat cmake/* colcon.meta) | sha256sum | cut -d' ' -f1)
if [ "$(cat install/.actaim2_build.sha256 2>/dev/null)" != "$src_hash" ]; then
  log "colcon build ${PACKAGES[*]}"
  base_paths=(); for p in "${PACKAGES[@]}"; do [ -d "$p" ] && base_paths+=("$p") || base_paths+=("compat/$p"); done
  # --symlink-install leaves links to deleted source files behind, and setup.py then fails to copy them
  find build install -xtype l -delete 2>/dev/null || true
  colcon --log-base log build --base-paths "${base_paths[@]}" --symlink-install \
    --event-handlers console_direct- \
    >log/colcon-build.txt 2>&1 || { tail -n 60 log/colcon-build.txt >&2; exit 1; }
  echo "$src_hash" > install/.actaim2_build.sha256
fi
log "ready (source scripts/env.sh to use the workspace)"
