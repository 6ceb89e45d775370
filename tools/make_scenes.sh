#!/usr/bin/env bash
# Regenerates the standard benchmark scenes of the denoise and pose work with evsim (docs/simulation.md,
# "Scene set"). Deterministic: the same evsim build gives the same bytes.
#   tools/make_scenes.sh [BUILD_DIR] [OUT_DIR]     defaults: build/release, build/scenes (not committed)
# Environment: JOBS (parallel evsim runs, default 2).
# Writes OUT_DIR/{pure-noise,denoise,pose,pose-trust}/... and OUT_DIR/index.csv (one row per recording).
set -euo pipefail
here=$(pwd)
cd "$(dirname "$0")/.."
root=$(pwd)
abs() { case "$1" in /*) printf '%s' "$1" ;; *) printf '%s/%s' "$here" "$1" ;; esac; }
build=$(abs "${1:-$root/build/release}")
out=$(abs "${2:-$root/build/scenes}")
jobs=${JOBS:-2}
evsim="$build/apps/evsim/evsim"
[ -x "$evsim" ] || { echo "make_scenes.sh: $evsim not built (cmake --build $build --target evsim)" >&2; exit 1; }

rm -rf "$out/pure-noise" "$out/denoise" "$out/pose" "$out/pose-trust"
mkdir -p "$out/pure-noise" "$out/denoise" "$out/pose" "$out/pose-trust"
joblist=$(mktemp)
trap 'rm -f "$joblist"' EXIT
index="$out/index.csv"
echo "set,name,events,labels,scene,speed,distance_m,noise_hz,hot_pixels,seed,duration_ms" >"$index"

# One evsim run per line of the job list; index rows name the files relative to OUT_DIR.
job() { printf '%q ' "$evsim" "$@" >>"$joblist"; printf '\n' >>"$joblist"; }

# (a) The paper's pure-noise protocol (section 4.1): exactly N events within 30 ms, 5 seeds each.
for n in 500 3000 6000 9000; do
  for seed in 1 2 3 4 5; do
    name="pn-N$n-seed$seed"
    job --pure-noise "$n" --seed "$seed" --out "$out/pure-noise/$name.aedat4" --labels "$out/pure-noise/$name.txt"
    echo "pure-noise,$name,pure-noise/$name.aedat4,pure-noise/$name.txt,pure-noise,,,,0,$seed,30" >>"$index"
  done
done

# (b) Labelled 2D scenes for denoising, 1 s each: every scene at 5 noise rates, without and with 5 hot pixels.
# Seed 1 throughout: for one scene the signal events are the same at every noise rate, and the hot-pixel
# variant holds the same background activity plus the hot pixels.
for spec in rotating-bar:1:rotating-bar rotating-bar:0.2:rotating-bar-slow \
            translating-rect:1:translating-rect translating-rect:0.2:translating-rect-slow; do
  IFS=: read -r scene speed label <<<"$spec"
  for noise in 0.1 1 3 5 10; do
    for hot in 0 5; do
      name="$label-n$noise"
      [ "$hot" = 0 ] || name="$name-hot$hot"
      job --scene "$scene" --speed "$speed" --duration-ms 1000 --noise-hz "$noise" --hot-pixels "$hot" --seed 1 \
          --out "$out/denoise/$name.aedat4" --labels "$out/denoise/$name.txt" --png "$out/denoise/$name.png"
      echo "denoise,$name,denoise/$name.aedat4,denoise/$name.txt,$scene,$speed,,$noise,$hot,1,1000" >>"$index"
    done
  done
done

# (b2) Slow edges (3-15 px/s) for denoising, 1 s each, seed 1, no noise (the structure bound) and the 5 rates:
# translating-rect x0.025 / x0.0625 / x0.125 = 3 / 7.5 / 15 px/s, rotating-bar x0.05 = tip at 12 px/s.
for spec in translating-rect:0.025:rect-3pxs translating-rect:0.0625:rect-7.5pxs translating-rect:0.125:rect-15pxs \
            rotating-bar:0.05:bar-12pxs; do
  IFS=: read -r scene speed label <<<"$spec"
  for noise in 0 0.1 1 3 5 10; do
    name="slow-$label-n$noise"
    job --scene "$scene" --speed "$speed" --duration-ms 1000 --noise-hz "$noise" --hot-pixels 0 --seed 1 \
        --out "$out/denoise/$name.aedat4" --labels "$out/denoise/$name.txt" --png "$out/denoise/$name.png"
    echo "denoise,$name,denoise/$name.aedat4,denoise/$name.txt,$scene,$speed,,$noise,0,1,1000" >>"$index"
  done
done

# (c) Pose scenes, 3 s each: the planar target and the roadheader wireframe at 3 distances and 4 noise rates,
# default views (docs/simulation.md) and generated motion. One seed per model: at one distance the motion,
# the signal events and the prior are the same at every noise rate.
for spec in planar:target-planar.yaml:1 roadheader:roadheader-wireframe.yaml:2; do
  IFS=: read -r label model seed <<<"$spec"
  for distance in 0.6 0.8 1.0; do
    for noise in 0 1 3 5; do
      name="$label-d$distance-n$noise"
      job --camera "$root/config/davis346.yaml" --model "$root/config/$model" --distance-m "$distance" \
          --duration-ms 3000 --noise-hz "$noise" --seed "$seed" \
          --out "$out/pose/$name.aedat4" --labels "$out/pose/$name.txt" --png "$out/pose/$name.png" --png-model
      echo "pose,$name,pose/$name.aedat4,pose/$name.txt,$label,,$distance,$noise,0,$seed,3000" >>"$index"
    done
  done
done

# (d) Issue 21's pose scenes (tools/pose_results_trust.py makes the same ones): own seeds, not the standard 1 / 2.
# Standstill: roadheader at 1.0 m, moves 1.2 s, stands still D s, moves 1.5 s more (seed 2101).
cam="$root/config/davis346.yaml"
for stop in 0.5 2 10; do
  for noise in 0 1 5; do
    name="stop-rh-s$stop-n$noise"
    dur=$(awk -v s="$stop" 'BEGIN { printf "%d", (1.2 + s + 1.5) * 1000 + 0.5 }')
    job --camera "$cam" --model "$root/config/roadheader-wireframe.yaml" --distance-m 1.0 --duration-ms "$dur" \
        --noise-hz "$noise" --seed 2101 --stop "1.2:$stop" --out "$out/pose-trust/$name.aedat4" \
        --labels "$out/pose-trust/$name.txt"
    echo "pose-trust,$name,pose-trust/$name.aedat4,pose-trust/$name.txt,roadheader,,1.0,$noise,0,2101,$dur" >>"$index"
  done
done
# Slow: max speed V m/s and angular speed W deg/s, 3 s (seeds 2201 planar, 2202 roadheader); clutter: each
# distractor kind at 1 Hz/px, 3 s (seeds 2301, 2302).
for spec in planar:target-planar.yaml:0.8 roadheader:roadheader-wireframe.yaml:1.0; do
  IFS=: read -r label model distance <<<"$spec"
  seed=2201; [ "$label" = planar ] || seed=2202
  for vw in 0.01:1.5 0.04:6 0.08:12; do
    IFS=: read -r v w <<<"$vw"
    for noise in 0 1 5; do
      name="slow-$label-v$v-n$noise"
      job --camera "$cam" --model "$root/config/$model" --distance-m "$distance" --duration-ms 3000 \
          --noise-hz "$noise" --seed "$seed" --max-speed-m-s "$v" --max-angular-speed-deg-s "$w" \
          --out "$out/pose-trust/$name.aedat4" --labels "$out/pose-trust/$name.txt"
      echo "pose-trust,$name,pose-trust/$name.aedat4,pose-trust/$name.txt,$label,,$distance,$noise,0,$seed,3000" \
        >>"$index"
    done
  done
  seed=2301; [ "$label" = planar ] || seed=2302
  for kind in none lines moving-lines decoy decoy-static flicker; do
    name="clutter-$label-$kind"
    extra=(); [ "$kind" = none ] || extra=(--distractor "$kind")
    job --camera "$cam" --model "$root/config/$model" --distance-m "$distance" --duration-ms 3000 --noise-hz 1 \
        --seed "$seed" "${extra[@]}" --out "$out/pose-trust/$name.aedat4" --labels "$out/pose-trust/$name.txt" \
        --png "$out/pose-trust/$name.png" --png-model
    echo "pose-trust,$name,pose-trust/$name.aedat4,pose-trust/$name.txt,$label,,$distance,1,0,$seed,3000" >>"$index"
  done
done

start_ns=$(date +%s%N)
# Longest jobs (the 3D scenes, listed last) first, so that the workers finish together.
tac "$joblist" | xargs -d '\n' -P "$jobs" -n 1 bash -c 'eval "$1" >/dev/null' evsim-job
end_ns=$(date +%s%N)
ms=$(( (end_ns - start_ns) / 1000000 ))
printf 'make_scenes.sh: %d recordings in %s, %d.%01d s with %d parallel jobs\n' "$(wc -l <"$joblist")" "$out" \
  $((ms / 1000)) $((ms % 1000 / 100)) "$jobs"
