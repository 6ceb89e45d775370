#!/usr/bin/env bash
# Wrong confident poses on clutter and hard scenes with seeds nobody tuned on (docs/history.md, session 17): evsim
# scenes like the results page's (planar decoy 0.8 m, roadheader decoy 1 m, planar 1.0 m at 3 Hz/px, a 2 s stop at
# 5 Hz/px) with other seeds, replayed raw and with `significance` (decoys also without the prior), scored by
# evpose-eval. Prints one line per run and the totals. Uses build/release (cmake --preset release first).
# --standard adds the results page's 24 standard scenes (planar / roadheader at 0.6 / 0.8 / 1.0 m, 0-5 Hz/px, 3 s)
# made with seed 41 (planar) / 42 (roadheader) instead of the page's 1 / 2, totalled apart (48 runs more; session 23:
# 0 wrong confident of 4 106).
# --slow adds eight slow scenes (16 runs; issue 21 item 2): the planar target at 0.8 m and the roadheader at 1.0 m
# drifting at most 0.01 m/s / 1.5 deg/s and 0.04 m/s / 6 deg/s under 1 and 5 Hz/px, 3 s, seeds NN31 (planar) / NN32
# (roadheader), totalled apart with their share of valid windows (100 a run; a failed run counts 0): a change for
# slow targets must be weighed against the decoys' wrong poses in the same run (docs/history.md, session 33).
# --set NN draws the hard scenes from seeds NN01-NN23 instead of 7401-7423 (default NN = 74; session 28 made a second
# set with 75, never tuned on: check a change on a set it was not developed on). The totals count every hard scene in
# OUT_DIR (std- and slow- ones apart, with their flag), so each set has its own default (build/pose-seeds,
# build/pose-seeds-NN).
#
#   tools/pose_seeds.sh [--standard] [--slow] [--set NN] [EVPIPE_BINARY] [OUT_DIR]
set -euo pipefail
standard=0
slow=0
set_nn=74
while [ $# -gt 0 ]; do
  case $1 in
    --standard) standard=1; shift ;;
    --slow) slow=1; shift ;;
    --set)
      if ! [[ ${2:-} =~ ^[1-9][0-9]$ ]]; then
        echo "pose_seeds.sh: --set takes a two-digit seed prefix (10-99), not '${2:-}'" >&2
        exit 2
      fi
      set_nn=$2
      shift 2
      ;;
    *) break ;;
  esac
done
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$root/build/release/apps/evpipe/evpipe}
out=${2:-$root/build/pose-seeds$([ "$set_nn" = 74 ] || echo "-$set_nn")}
evsim=$root/build/release/apps/evsim/evsim
eval_bin=$root/build/release/apps/evpose-eval/evpose-eval
for b in "$bin" "$evsim" "$eval_bin"; do
  [ -x "$b" ] || { echo "pose_seeds.sh: $b not found (cmake --preset release && cmake --build --preset release)" >&2; exit 2; }
done
mkdir -p "$out/scenes" "$out/runs"

gen() {  # name model distance noise seed duration_ms [evsim options]
  local name=$1 model=$2 dist=$3 noise=$4 seed=$5 dur=$6
  shift 6
  [ -f "$out/scenes/$name.aedat4" ] && return 0
  "$evsim" --camera "$root/config/davis346.yaml" --model "$root/config/$model" --distance-m "$dist" \
    --duration-ms "$dur" --noise-hz "$noise" --seed "$seed" "$@" --out "$out/scenes/$name.aedat4" --no-manifest \
    > /dev/null
}
for s in ${set_nn}01 ${set_nn}02 ${set_nn}03 ${set_nn}04 ${set_nn}05 ${set_nn}06; do gen "planar-decoy-$s" target-planar.yaml 0.8 1 "$s" 3000 --distractor decoy; done
for s in ${set_nn}01 ${set_nn}02 ${set_nn}03; do gen "roadheader-decoy-$s" roadheader-wireframe.yaml 1.0 1 "$s" 3000 --distractor decoy; done
for s in ${set_nn}11 ${set_nn}12 ${set_nn}13; do gen "planar-d1.0-n3-$s" target-planar.yaml 1.0 3 "$s" 3000; done
for s in ${set_nn}21 ${set_nn}22 ${set_nn}23; do gen "stop-rh-s2-n5-$s" roadheader-wireframe.yaml 1.0 5 "$s" 4700 --stop 1.2:2; done
if [ "$slow" = 1 ]; then
  for vw in 0.01:1.5 0.04:6; do
    IFS=: read -r v w <<<"$vw"
    for n in 1 5; do
      gen "slow-planar-v$v-n$n-${set_nn}31" target-planar.yaml 0.8 "$n" "${set_nn}31" 3000 --max-speed-m-s "$v" \
        --max-angular-speed-deg-s "$w"
      gen "slow-roadheader-v$v-n$n-${set_nn}32" roadheader-wireframe.yaml 1.0 "$n" "${set_nn}32" 3000 \
        --max-speed-m-s "$v" --max-angular-speed-deg-s "$w"
    done
  done
fi
if [ "$standard" = 1 ]; then
  for d in 0.6 0.8 1.0; do
    for n in 0 1 3 5; do
      gen "std-planar-d$d-n$n-41" target-planar.yaml "$d" "$n" 41 3000
      gen "std-roadheader-d$d-n$n-42" roadheader-wireframe.yaml "$d" "$n" 42 3000
    done
  done
fi

run() {  # scene filter [noprior]
  local s=$out/scenes/$1 tag=$1.$2${3:+.noprior}
  local args=(--replay "$s.aedat4" --speed max --camera "$s.camera.yaml" --model "$s.model.yaml" --no-lcm
    --no-progress --poses-out "$out/runs/$tag.csv" --denoise "$2")
  [ -z "${3:-}" ] && args+=(--prior "$s.prior.yaml")
  "$bin" "${args[@]}" > /dev/null 2>&1 || { echo "$tag evpipe failed"; return 0; }
  "$eval_bin" "$out/runs/$tag.csv" "$s.gt.csv" --json --only-tracking 2> /dev/null |
    python3 -c "import json,sys; d=json.load(sys.stdin); print('$tag', d['wrong_confident'], d['confident_evaluated'])" \
    2> /dev/null || echo "$tag 0 0"
}
export -f run
export bin out eval_bin
for s in $(cd "$out/scenes" && ls ./*.aedat4 | sed 's|^\./||; s|\.aedat4$||'); do
  case $s in std-*) [ "$standard" = 1 ] || continue ;; slow-*) [ "$slow" = 1 ] || continue ;; esac
  for f in none significance; do
    echo "$s $f"
    case $s in *decoy*) echo "$s $f noprior" ;; esac
  done
done | xargs -P 2 -L 1 bash -c 'run "$@"' _ | sort | tee "$out/summary.txt"
awk '!/^(std|slow)-/ {w += $2; c += $3; n++} END {printf "total: %d wrong confident of %d confident poses, %d runs\n", w, c, n}' \
  "$out/summary.txt"
if [ "$slow" = 1 ]; then
  # 3 s scenes cut into 30 ms windows: 100 windows a run; the confident poses are the valid (published) windows.
  awk '/^slow-/ {w += $2; c += $3; n++} END {printf "slow scenes: %d wrong confident of %d confident poses, %d runs, %.1f %% of their windows valid\n", w, c, n, n ? c / n : 0}' \
    "$out/summary.txt"
fi
if [ "$standard" = 1 ]; then
  awk '/^std-/ {w += $2; c += $3; n++} END {printf "standard scenes: %d wrong confident of %d confident poses, %d runs\n", w, c, n}' \
    "$out/summary.txt"
fi
