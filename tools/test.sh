#!/usr/bin/env bash
# Quick start, command 2 (and CI): install what is missing, build with -Werror (optimised, ASan + UBSan, TSan),
# run every test once (the long accuracy tests optimised, all others under ASan + UBSan, the threaded ones also
# under TSan), a bounded fuzzing run of every reader, and the Python cross-checks of the AEDAT 4.0 writer and of the
# dv-processing-compatible denoisers (skipped with a message when the PyPI packages cannot be installed).
# Environment: EVPIPE_FUZZ_SECONDS (default 20 per reader), EVPIPE_SKIP_ASAN=1 (every test then runs optimised),
# EVPIPE_SKIP_TSAN=1, EVPIPE_SKIP_FUZZ=1.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
t_start=$(date +%s)
stamp() { echo "== [$(( $(date +%s) - t_start )) s] $*"; }

stamp "set-up"
bash tools/setup.sh

stamp "format check (.clang-format)"
bash tools/check_format.sh

# The optimised (ci) build compiles the libraries, programs and benchmarks, and only the test executables of two kinds
# of tests; every other test runs under ASan + UBSan below (running all ~740 twice, and their -O2 compile, were a
# third of CI's time):
# - the accuracy tests listed in ci_only_tests, which took 17-156 s each under the sanitizers and exercise the code
#   paths of the sanitized tests (the same estimator and binaries, on longer scenes or more seeds): optimised only.
#   HoldsAStillTargetAndResumesWithoutReinitialising, TracksFromOneCmTwoDegrees and the FirstInitialisation scenes
#   stay under ASan for the estimator and the initialiser;
# - tests that check more in an optimised build (their source tests __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__: the
#   real sequences whole and without a prior, every seed, real-time bounds, a memory limit): their executables run
#   whole here, and again under the sanitizers. A source that gains such a switch fails the check below until its
#   executable is in ci_test_targets.
ci_only_tests=(
  EvpipeClutter.WithoutAPriorLinesBesideTheBoardGiveNoConfidentWrongPose
  EvpipeDefaults.AdaptiveThresholdKeepsTheSampleTracked
  EvpipePoseErrors.NoTargetInViewGivesNoPosesAndSaysWhy
  PoseEstimator.TracksASlowTargetUnderNoise
  PoseEstimator.ADriftingTargetIsNotHeldOffItsPose
  PoseEstimator.HoldsAStillTargetUnderHeavyNoise
  PriorAlignment.RealBoardInitialisesFromThePrior
  PriorAlignment.SmallGridBoardFromAPriorOff50mm10deg
  Tracker.ConvergesFromFiveCmTenDegrees
  Initialiser.WithoutAPriorFromSampledViews
)
ci_test_targets="test_e2e_pose test_pose_estimator test_pose_prior_alignment test_pose_track test_pose_lines
  test_pose_verify test_e2e_lcm test_transport_echo test_stages"
ci_only_regex="^($(IFS='|'; echo "${ci_only_tests[*]}"))\$"  # the dots match themselves too

if [ "${EVPIPE_SKIP_ASAN:-0}" = 1 ]; then
  # Without the ASan phase every test runs here.
  stamp "build (ci preset: -O2 without debug info, -Werror)"
  cmake --preset ci -DEVPIPE_TESTS_IN_ALL=ON >/dev/null
  cmake --build --preset ci -j"$jobs"
  stamp "tests (ci preset: all)"
  ctest --preset ci -j"$jobs"
else
  stamp "build (ci preset: -O2 without debug info, -Werror; libraries, programs, benchmarks and" $ci_test_targets")"
  cmake --preset ci -DEVPIPE_TESTS_IN_ALL=OFF >/dev/null
  cmake --build --preset ci -j"$jobs"
  # shellcheck disable=SC2086
  cmake --build --preset ci -j"$jobs" --target $ci_test_targets
  # Each source with a sanitizer switch is compiled into one of ci_test_targets (compile_commands.json: its object
  # lies under <target>.dir).
  python3 - "$ci_test_targets" <<'PY'
import json, pathlib, re, sys
targets = set(sys.argv[1].split())
root = pathlib.Path("tests").resolve()
switched = {p.resolve() for p in root.rglob("*.cpp") if re.search(r"__SANITIZE_(ADDRESS|THREAD)__", p.read_text())}
owners = {}
for e in json.load(open("build/ci/compile_commands.json")):
    out = e.get("output") or re.search(r" -o (\S+)", e["command"]).group(1)
    m = re.search(r"([^/]+)\.dir/", out)
    if m:
        owners.setdefault(pathlib.Path(e["file"]).resolve(), set()).add(m.group(1))
bad = sorted(str(f.relative_to(root.parent)) for f in switched if not owners.get(f, set()) & targets)
if bad:
    sys.exit("tools/test.sh: these test sources check more in an optimised build, but their executables are not in "
             "ci_test_targets: " + ", ".join(bad))
PY
  found=$(ctest --preset ci -N -R "$ci_only_regex" | grep -c '^ *Test *#' || true)
  if [ "$found" -ne "${#ci_only_tests[@]}" ]; then
    echo "tools/test.sh: ctest lists $found of the ${#ci_only_tests[@]} ci-only tests" \
      "(is each one's executable in ci_test_targets?)" >&2
    exit 1
  fi
  stamp "tests (ci preset: every test of" $ci_test_targets")"
  ctest --preset ci -j"$jobs" -E '_NOT_BUILT$'
fi

stamp "end-to-end: bundled sample regenerates bit-identically"
bash tools/make_sample.sh --check build/ci

if [ "${EVPIPE_SKIP_ASAN:-0}" != 1 ]; then
  stamp "build (asan preset: ASan + UBSan)"
  cmake --preset asan >/dev/null
  cmake --build --preset asan -j"$jobs"
  stamp "tests (asan preset)"
  # tools/lsan.supp: leaks inside the GUI libraries evpipe-view's window loads (dbus, fontconfig, Qt), not ours.
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    LSAN_OPTIONS="suppressions=$(pwd)/tools/lsan.supp" ctest --preset asan -j"$jobs" -E "$ci_only_regex"
fi

# ThreadSanitizer: only the executables with threads are built (keeps CI short); EVPIPE_SKIP_TSAN=1 skips it.
# Add the name of any further threaded test executable / test-name pattern here.
if [ "${EVPIPE_SKIP_TSAN:-0}" != 1 ]; then
  stamp "build (tsan preset: ThreadSanitizer, threaded tests only)"
  cmake --preset tsan >/dev/null
  cmake --build --preset tsan -j"$jobs" --target test_runtime test_stages
  stamp "tests (tsan preset: runtime queues, stage loop, task pool; the graph; the pose stage with its worker)"
  TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 \
    ctest --preset tsan -j"$jobs" -R '^(PacedSource|SpscRing|NamedQueue|Histogram|StageRunner|Outlet|PipelineGraph|SequentialRunner|BackgroundTask|TaskPool)\.'
fi

if [ "${EVPIPE_SKIP_FUZZ:-0}" != 1 ]; then
  stamp "fuzzing every reader (${EVPIPE_FUZZ_SECONDS:-20} s each)"
  bash tools/run_fuzzers.sh "${EVPIPE_FUZZ_SECONDS:-20}"
fi

# A Python cross-check: exit 77 means "skipped" (PyPI unreachable; the script says why), anything else non-zero fails.
cross_check() {
  set +e
  python3 "$@"
  local rc=$?
  set -e
  if [ $rc -eq 77 ]; then echo "cross-check skipped (see message above)"; elif [ $rc -ne 0 ]; then exit $rc; fi
}

stamp "cross-check: AEDAT 4.0 written by evpipe, read by dv-processing and aedat"
cross_check tools/check_aedat4_python.py --build build/ci

stamp "cross-check: baf / knoise decisions vs dv-processing 2.0.4, event by event"
cross_check tools/check_denoise_dv.py --build build/ci

stamp "all tests passed"
