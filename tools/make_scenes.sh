#!/usr/bin/env bash
# Regenerates the standard benchmark scenes of the denoise and pose work with evsim (docs/simulation.md,
# "Scene set"). Deterministic: the same evsim build gives the same bytes.
#   tools/make_scenes.sh [BUILD_DIR] [OUT_DIR]     defaults: build/release, build/scenes (not committed)
# Environment: JOBS (parallel evsim runs, default 2).
# Writes OUT_DIR/{pure-noise,denoise,pose}/... and OUT_DIR/index.csv (one row per recording).
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

rm -rf "$out/pure-noise" "$out/denoise" "$out/pose"
mkdir -p "$out/pure-noise" "$out/denoise" "$out/pose"
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

start_ns=$(date +%s%N)
# Longest jobs (the 3D scenes, listed last) first, so that the workers finish together.
tac "$joblist" | xargs -d '\n' -P "$jobs" -n 1 bash -c 'eval "$1" >/dev/null' evsim-job
end_ns=$(date +%s%N)
ms=$(( (end_ns - start_ns) / 1000000 ))
printf 'make_scenes.sh: %d recordings in %s, %d.%01d s with %d parallel jobs\n' "$(wc -l <"$joblist")" "$out" \
  $((ms / 1000)) $((ms % 1000 / 100)) "$jobs"
