#!/usr/bin/env bash
# Generates the seed corpora of the reader fuzzers into OUT_DIR/{aedat2,aedat31,aedat4,text}/: small valid
# files written by evpipe's own writers, hand-built AEDAT 2.0 files, and small crops of the third-party
# recordings when ../shared/data/real is present (crops are made here, at fuzz time, and never committed);
# and of the run-configuration fuzzer into OUT_DIR/config/: the shipped YAML files of config/ (evpipe.yaml, every
# key with its default, and the camera/model/prior files for more YAML shapes) and one config per section; and of the
# LCM fuzzer into OUT_DIR/lcm/: evpipe's pose_t, stats_t and preview_t messages alone and as a log.
#
# Usage: tools/make_fuzz_corpus.sh BUILD_DIR OUT_DIR
#   BUILD_DIR: a build with the evpipe_fuzz_seeds target (configured with -DEVPIPE_FUZZ=ON)
#   EVPIPE_SHARED_DATA_DIR: where the real recordings are (default: <repo>/../shared/data/real)
set -euo pipefail

if [ $# -ne 2 ]; then
  echo "usage: $0 BUILD_DIR OUT_DIR" >&2
  exit 2
fi
build=$1
out=$2
root=$(cd "$(dirname "$0")/.." && pwd)
real=${EVPIPE_SHARED_DATA_DIR:-$root/../shared/data/real}

seeds_bin=$build/tests/fuzz/evpipe_fuzz_seeds
if [ ! -x "$seeds_bin" ]; then
  echo "$0: $seeds_bin not found: build the evpipe_fuzz_seeds target first" >&2
  exit 1
fi

rm -rf "$out"
mkdir -p "$out"
if [ -d "$real" ]; then
  "$seeds_bin" "$out" "$real"
else
  echo "$0: $real absent: seeds from evpipe's writers only" >&2
  "$seeds_bin" "$out"
fi
mkdir -p "$out/config"
cp "$root"/config/*.yaml "$out/config/"
awk '/^[a-z]+:/ { n++ } { print > (dir "/section-" n ".yaml") }' dir="$out/config" "$root/config/evpipe.yaml"
for d in "$out"/*/; do
  echo "seeds: $(basename "$d"): $(find "$d" -type f | wc -l) files"
done
