#!/usr/bin/env bash
# Regenerates the bundled recordings in tests/data with evsim (the project's own simulator: they may be shipped,
# unlike the third-party files in ../shared/data/real):
#   demo-sample.aedat4        a 2D scene (bars and rectangles) for the denoisers
#   roadheader-sample.*       the roadheader wireframe moving 1 m in front of the DAVIS346 with 1 Hz/px noise:
#                             the recording, its ground truth (.gt.csv), camera, model and prior (the demo's input)
#   tools/make_sample.sh [BUILD_DIR]          rewrite the samples
#   tools/make_sample.sh --check [BUILD_DIR]  regenerate into a temp folder and fail if any file differs
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
build=${1:-build/release}
evsim="$build/apps/evsim/evsim"
[ -x "$evsim" ] || { echo "make_sample.sh: $evsim not built" >&2; exit 1; }
# --no-manifest: this script itself records how the samples are made.
demo_args=(--scene demo --duration-ms 1500 --noise-hz 0.5 --hot-pixels 2 --seed 20261121 --no-manifest)
roadheader_args=(--camera config/davis346.yaml --model config/roadheader-wireframe.yaml --distance-m 1.0
                 --noise-hz 1 --hot-pixels 2 --duration-ms 3000 --seed 20261121 --no-manifest)
out=tests/data
if [ $check = 1 ]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
"$evsim" "${demo_args[@]}" --out "$out/demo-sample.aedat4" >/dev/null
"$evsim" "${roadheader_args[@]}" --out "$out/roadheader-sample.aedat4" >/dev/null
if [ $check = 1 ]; then
  status=0
  for f in "$out"/*; do
    name=$(basename "$f")
    if ! cmp -s "$f" "tests/data/$name"; then
      echo "make_sample.sh: tests/data/$name differs from what evsim generates now; run tools/make_sample.sh" >&2
      status=1
    fi
  done
  [ $status = 0 ] && echo "make_sample.sh: the samples in tests/data are up to date"
  exit $status
fi
echo "make_sample.sh: wrote $(ls tests/data | tr '\n' ' ')"
