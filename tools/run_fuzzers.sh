#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan+UBSan+libFuzzer) and runs each reader fuzzer (fuzz_lcm: the LCM log and
# messages) and the run-config parser's fuzzer (fuzz_config) for SECONDS (default 30) each. Exits non-zero if any fuzzer finds a crash, leak, timeout, OOM, UB or a broken reader
# invariant; the reproducer is saved under $BUILD/fuzz/artifacts/.
#
# Usage: tools/run_fuzzers.sh [SECONDS]
#   EVPIPE_FUZZ_BUILD_DIR  build directory (default: <repo>/build/fuzz, the "fuzz" CMake preset)
#   EVPIPE_FUZZERS         subset to run, e.g. "fuzz_text fuzz_config" (default: all six)
#   EVPIPE_JOBS            parallel build jobs (default 2)
#   EVPIPE_FUZZ_PARALLEL   fuzzers run at once (default: the number of cores)
# Reproduce a finding: $BUILD/tests/fuzz/fuzz_<fmt> <artifact file>
set -euo pipefail

seconds=${1:-30}
root=$(cd "$(dirname "$0")/.." && pwd)
build=${EVPIPE_FUZZ_BUILD_DIR:-$root/build/fuzz}
fuzzers=${EVPIPE_FUZZERS:-"fuzz_aedat2 fuzz_aedat31 fuzz_aedat4 fuzz_text fuzz_config fuzz_lcm"}
jobs=${EVPIPE_JOBS:-2}

for tool in clang clang++; do
  command -v "$tool" >/dev/null || { echo "$0: $tool not found (apt-get install clang libclang-rt-14-dev)" >&2; exit 1; }
done

# Line tables are all a finding's stack trace needs (file and line); full debug info made the build ~15 % slower.
reldeb="-O2 -gline-tables-only -DNDEBUG"
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" "${generator[@]}" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS_RELWITHDEBINFO="$reldeb" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$reldeb" -DEVPIPE_FUZZ=ON -DEVPIPE_BUILD_TESTS=OFF -DEVPIPE_BUILD_BENCHMARKS=OFF
fi
# shellcheck disable=SC2086
cmake --build "$build" -j"$jobs" --target $fuzzers evpipe_fuzz_seeds

work=$build/fuzz
"$root/tools/make_fuzz_corpus.sh" "$build" "$work/seeds"
mkdir -p "$work/artifacts"

max_len_of() {
  case $1 in
    fuzz_aedat4) echo 65536 ;;   # compressed packets need room
    fuzz_text | fuzz_config) echo 8192 ;;
    *) echo 16384 ;;
  esac
}

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}

# One fuzzer per core at a time (each is single-threaded); results are reported in the listed order.
parallel=${EVPIPE_FUZZ_PARALLEL:-$(nproc)}
run_one() {
  local f=$1 fmt=${1#fuzz_}
  local corpus=$work/corpus/$fmt        # grows across runs (new coverage is kept here)
  mkdir -p "$corpus"
  local rc=0
  "$build/tests/fuzz/$f" "$corpus" "$work/seeds/$fmt" \
    -max_total_time="$seconds" -max_len="$(max_len_of "$f")" -rss_limit_mb=2048 -timeout=10 \
    -dict="$root/tests/fuzz/$fmt.dict" -artifact_prefix="$work/artifacts/$f-" -print_final_stats=1 \
    >"$work/$f.log" 2>&1 || rc=$?
  echo "$rc" >"$work/$f.rc"
}
running=0
for f in $fuzzers; do
  echo "== $f: ${seconds}s, max_len $(max_len_of "$f"), corpus $work/corpus/${f#fuzz_} + seeds $work/seeds/${f#fuzz_}"
  rm -f "$work/$f.rc"
  run_one "$f" &
  running=$((running + 1))
  if [ "$running" -ge "$parallel" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait || true

failed=()
for f in $fuzzers; do
  log=$work/$f.log
  rc=$(cat "$work/$f.rc" 2>/dev/null || echo 99)
  echo "== $f: exit $rc"
  grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb|#[0-9]+ +DONE)" "$log" | sed 's/^/   /' || true
  if [ "$rc" -ne 0 ]; then
    echo "!! $f: finding (exit $rc): see $log" >&2
    grep -E "ERROR|SUMMARY|runtime error|Test unit written" "$log" | head -20 >&2 || true
    failed+=("$f")
  fi
done

if [ ${#failed[@]} -ne 0 ]; then
  echo "fuzzing found problems in: ${failed[*]}" >&2
  exit 1
fi
echo "fuzzing: no findings (${seconds}s per fuzzer: $fuzzers)"
