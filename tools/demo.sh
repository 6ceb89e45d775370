#!/usr/bin/env bash
# Quick start, command 1: install what is missing, build (release), and replay the bundled sample
# recording through evpipe, printing its summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)" --target evpipe evconvert evsim
echo
echo "== evpipe --replay tests/data/demo-sample.aedat4 (real-time pace) =="
./build/release/apps/evpipe/evpipe --replay tests/data/demo-sample.aedat4 --speed 1 "$@"
