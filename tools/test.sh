#!/usr/bin/env bash
# Quick start, command 2 (and CI): install what is missing, build with -Werror (optimised, ASan + UBSan, TSan),
# run every test at least once (the long accuracy tests optimised, all others under ASan + UBSan, those that check
# more when optimised in both, the threaded ones also under TSan), a bounded fuzzing run of every reader, and the
# Python cross-checks of the AEDAT 4.0 writer and of the dv-processing-compatible denoisers (skipped with a message
# when the PyPI packages cannot be installed).
# Environment: EVPIPE_FUZZ_SECONDS (default 10 per reader), EVPIPE_SKIP_ASAN=1 (every test then runs optimised),
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

# The optimised (ci) build compiles the libraries, programs and benchmarks, and only the test executables of three
# kinds of tests; every test runs under ASan + UBSan below except the first kind (running all ~740 twice, and their
# -O2 compile, were a third of CI's time; the other test sources are compiled at -O0 with -Werror there):
# - the accuracy tests in ci_only_tests, which took 17-156 s each under the sanitizers and exercise the code paths of
#   the sanitized tests (the same estimator and binaries, on longer scenes or more seeds): optimised only. Also
#   NoTargetInView (no target: an attempt refused in each of the sample's windows, 34 s under ASan), whose refusals
#   the PoseVerify and PriorAlignment tests and RealBoard seq_0003's first windows take under ASan.
#   HoldsAStillTargetAndResumesWithoutReinitialising, TracksFromOneCmTwoDegrees and the FirstInitialisation scenes
#   stay under ASan for the estimator and the initialiser;
# - tests that check more in an optimised build (their source tests __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__: the
#   real sequences whole and without a prior, every seed, real-time bounds, a memory limit). The check below fails
#   when a test source gains such a switch and its executable is not in ci_test_targets;
# - test_transport_wire, whose allocation probe is meant to see allocations an optimising compiler could remove.
# Each executable listed runs whole here (selected by its label; stale executables of earlier builds in the folder
# are not run), so those tests run twice; every test runs at least once.
ci_only_tests=(
  EvpipeClutter.WithoutAPriorLinesBesideTheBoardGiveNoConfidentWrongPose
  EvpipePoseErrors.NoTargetInViewGivesNoPosesAndSaysWhy
  EvpipeDefaults.AdaptiveThresholdKeepsTheSampleTracked
  PoseEstimator.TracksASlowTargetUnderNoise
  PoseEstimator.ADriftingTargetIsNotHeldOffItsPose
  PoseEstimator.HoldsAStillTargetUnderHeavyNoise
  PriorAlignment.RealBoardInitialisesFromThePrior
  Tracker.ConvergesFromFiveCmTenDegrees
  Initialiser.WithoutAPriorFromSampledViews
)
ci_test_targets="test_e2e_pose test_pose_estimator test_pose_prior_alignment test_pose_track test_pose_lines
  test_pose_verify test_e2e_lcm test_transport_echo test_stages test_transport_wire"
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
  # Each test source with a sanitizer switch is compiled into one of ci_test_targets (compile_commands.json: its
  # object lies under <target>.dir); a switch in a shared header is refused (put it in the test source).
  python3 - "$ci_test_targets" <<'PY'
import json, pathlib, re, sys
targets = set(sys.argv[1].split())
root = pathlib.Path("tests").resolve()
switch = re.compile(r"__SANITIZE_(ADDRESS|THREAD)__")
sources = [p for p in root.rglob("*") if p.suffix in (".cpp", ".hpp", ".h") and p.parent.name not in ("fuzz", "bench")]
switched = [p for p in sources if switch.search(p.read_text(encoding="utf-8"))]
owners = {}
for e in json.load(open("build/ci/compile_commands.json", encoding="utf-8")):
    out = e.get("output") or re.search(r" -o (\S+)", e["command"]).group(1)
    m = re.search(r"([^/]+)\.dir/", out)
    if m:
        owners.setdefault(pathlib.Path(e["file"]).resolve(), set()).add(m.group(1))
bad = sorted(str(p.relative_to(root.parent)) for p in switched
             if p.suffix != ".cpp" or not owners.get(p, set()) & targets)
if bad:
    sys.exit("tools/test.sh: these test files check more in an optimised build, but are headers or are not compiled "
             "into an executable of ci_test_targets: " + ", ".join(bad))
PY
  # shellcheck disable=SC2086
  cmake --build --preset ci -j"$jobs" --target all $ci_test_targets
  found=$(ctest --preset ci -N -R "$ci_only_regex" | grep -c '^ *Test *#' || true)
  if [ "$found" -ne "${#ci_only_tests[@]}" ]; then
    echo "tools/test.sh: ctest lists $found of the ${#ci_only_tests[@]} ci-only tests" \
      "(is each one's executable in ci_test_targets?)" >&2
    exit 1
  fi
  stamp "tests (ci preset: every test of" $ci_test_targets")"
  ctest --preset ci -j"$jobs" -L "^($(echo $ci_test_targets | tr ' ' '|'))\$"
  # Back to the default: a later `cmake --build --preset ci` by hand builds every test executable again.
  cmake --preset ci -DEVPIPE_TESTS_IN_ALL=ON >/dev/null
fi

stamp "end-to-end: bundled sample regenerates bit-identically"
bash tools/make_sample.sh --check build/ci

if [ "${EVPIPE_SKIP_ASAN:-0}" != 1 ]; then
  stamp "build (asan preset: ASan + UBSan)"
  cmake --preset asan -DEVPIPE_TESTS_IN_ALL=ON >/dev/null
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
  stamp "fuzzing every reader (${EVPIPE_FUZZ_SECONDS:-10} s each)"
  bash tools/run_fuzzers.sh "${EVPIPE_FUZZ_SECONDS:-10}"
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
