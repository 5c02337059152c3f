#!/usr/bin/env bash
# Prove that DDS stays on loopback: capture every non-loopback interface while a command runs
# (default: the test suite) and count RTPS/DDS packets: UDP datagrams whose payload starts with
# the RTPS magic "RTPS" (any domain id, any port, unicast or multicast). Prints the count per
# interface; exits 1 if any was seen.
# Loopback is captured too, as the control: it must show DDS traffic, else the filter is wrong.
#   bash scripts/check_dds_loopback.sh [command ...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
command -v tcpdump >/dev/null || { $SUDO apt-get update -qq; $SUDO apt-get install -y -qq tcpdump >/dev/null; }
[ $# -gt 0 ] || set -- bash "$ROOT/scripts/test.sh"
out=$(mktemp -d)
ifaces=$(ip -o link show | awk -F': ' '{print $2}' | cut -d@ -f1 | grep -v '^lo$')
pids=()
for i in lo $ifaces; do
  $SUDO tcpdump -i "$i" -n -U -w "$out/$i.pcap" 'udp and udp[8:4] = 0x52545053' 2>/dev/null &
  pids+=($!)
done
sleep 1
status=0; "$@" || status=$?
sleep 1
for p in "${pids[@]}"; do $SUDO kill -INT "$p" 2>/dev/null || true; done
wait "${pids[@]}" 2>/dev/null || true
seen=0
for i in $ifaces; do
  n=0; [ -s "$out/$i.pcap" ] && n=$( (tcpdump -r "$out/$i.pcap" -n 2>/dev/null || true) | wc -l)
  echo "[dds-check] interface $i: $n DDS packets"
  seen=$((seen + n))
done
lo_n=$( (tcpdump -r "$out/lo.pcap" -n 2>/dev/null || true) | wc -l)
echo "[dds-check] control: $lo_n DDS packets on lo"
[ "$lo_n" -gt 0 ] || { echo "[dds-check] no DDS traffic seen even on lo: the capture did not work"; exit 1; }
[ "$seen" -eq 0 ] && echo "[dds-check] no DDS packet left loopback (command exit $status)" || echo "[dds-check] DDS traffic left loopback!"
[ "$seen" -eq 0 ] || exit 1
exit "$status"
