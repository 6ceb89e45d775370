#!/usr/bin/env bash
# Quick start, command 1: install what is missing, build (release), and replay the bundled roadheader sample
# through the full pipeline (denoise → OPnL initialisation → MM tracking → LCM), printing the summary with the
# ATE against the sample's ground truth. Extra arguments go to evpipe (e.g. --speed max, --denoise none).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)" --target evpipe evpipe-view evpipe-lcm-echo evpose-eval evconvert evsim \
  evpipe_lcmtypes_jar
bin=build/release/apps
sample=tests/data/roadheader-sample
url="udpm://239.255.76.67:7667?ttl=0"

# LCM's udpm needs a multicast route even on one host (docs/operations.md, "LCM"); a fresh machine or
# container may have none. Add it on the loopback interface when missing (root only; nothing else changes).
if ! ip route show table all 2>/dev/null | grep -q '^224.0.0.0/4 ' && ! ip route show 2>/dev/null | grep -q '^default '; then
  if [ "$(id -u)" -eq 0 ]; then
    echo "demo: no multicast route: adding 224.0.0.0/4 on lo for LCM (ip route add 224.0.0.0/4 dev lo)"
    ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo
  else
    echo "demo: no multicast route and not root: evpipe will run but cannot publish on LCM" >&2
  fi
fi

# A subscriber in the background proves the poses are on the wire (what lcm-spy would show).
echo_log=$(mktemp)
trap 'rm -f "$echo_log"' EXIT
"$bin/evpipe-lcm-echo/evpipe-lcm-echo" --url "$url" --channel EVPIPE_POSE --timeout 15 --text >"$echo_log" 2>&1 &
echo_pid=$!
sleep 0.5

echo
echo "== evpipe --replay $sample.aedat4 (real-time pace, 3 s) =="
"$bin/evpipe/evpipe" --replay "$sample.aedat4" --speed 1 \
  --camera "$sample.camera.yaml" --model "$sample.model.yaml" --prior "$sample.prior.yaml" \
  --ground-truth "$sample.gt.csv" --poses-out build/release/demo-poses.csv --lcm-url "$url" --preview "$@"
sleep 0.5
kill "$echo_pid" 2>/dev/null || true
wait "$echo_pid" 2>/dev/null || true
echo
echo "== on LCM ($url): $(grep -c 'EVPIPE_POSE' "$echo_log" || true) pose messages received by evpipe-lcm-echo; the last:"
grep 'EVPIPE_POSE' "$echo_log" | tail -1 || true
cat <<TXT

Poses written to build/release/demo-poses.csv; compare with the truth and plot them:
  $bin/evpose-eval/evpose-eval build/release/demo-poses.csv $sample.gt.csv --png build/release/demo-poses.png
Watch the messages live in lcm-spy (needs a display; run it, then this demo again in another terminal):
  tools/lcm-spy.sh --url '$url'
or as text without a display:
  $bin/evpipe-lcm-echo/evpipe-lcm-echo --url '$url' --text
See what the pipeline sees (events, kept events, the model at the pose; the demo publishes the preview):
  $bin/evpipe-view/evpipe-view --lcm-url '$url'         # a window; then this demo again in another terminal
  $bin/evpipe/evpipe --replay $sample.aedat4 --camera $sample.camera.yaml --model $sample.model.yaml \
    --prior $sample.prior.yaml --speed max --no-lcm --video build/release/demo.mp4   # every window as a video
TXT
