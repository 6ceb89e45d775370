#!/usr/bin/env bash
# Regenerates the bundled demo recording tests/data/demo-sample.aedat4 with evsim (the project's own
# simulator: the recording may be shipped, unlike the third-party files in ../shared/data/real).
#   tools/make_sample.sh [BUILD_DIR]          rewrite the sample
#   tools/make_sample.sh --check [BUILD_DIR]  regenerate to a temp file and fail if it differs
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
build=${1:-build/release}
evsim="$build/apps/evsim/evsim"
[ -x "$evsim" ] || { echo "make_sample.sh: $evsim not built" >&2; exit 1; }
# --no-manifest: the script itself records how the sample is made.
args=(--scene demo --duration-ms 1500 --noise-hz 0.5 --hot-pixels 2 --seed 20261121 --no-manifest)
if [ $check = 1 ]; then
  tmp=$(mktemp --suffix=.aedat4)
  trap 'rm -f "$tmp"' EXIT
  "$evsim" "${args[@]}" --out "$tmp" >/dev/null
  if cmp -s "$tmp" tests/data/demo-sample.aedat4; then
    echo "make_sample.sh: tests/data/demo-sample.aedat4 is up to date"
  else
    echo "make_sample.sh: tests/data/demo-sample.aedat4 differs from what evsim generates now; run tools/make_sample.sh" >&2
    exit 1
  fi
else
  "$evsim" "${args[@]}" --out tests/data/demo-sample.aedat4
fi
