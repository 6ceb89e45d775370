#!/usr/bin/env bash
# Installs the build tree twice and checks every expected file lands:
#  1. DESTDIR=<work>/root at the configured prefix: the paths baked into the unit (ExecStart=) and the production
#     evpipe.yaml (camera, model, prior) must exist in the staged tree; a second install keeps a changed
#     evpipe.yaml (conffile behaviour) and refreshes evpipe.yaml.default.
#  2. cmake --install --prefix <work>/prefix: everything relative to the prefix lands under it.
# Usage: check_install.sh <build dir> <work dir> <prefix> <full bindir> <full confdir> <unitdir> <udevdir> <docdir>
#   (unitdir, udevdir, docdir relative to the prefix or absolute, as configured)
set -euo pipefail
build=$1 work=$2 prefix=$3 bindir=$4 confdir=$5 unitdir=$6 udevdir=$7 docdir=$8
fails=0
fail() { echo "FAIL: $*" >&2; fails=$((fails + 1)); }
full() { case $1 in /*) echo "$1" ;; *) echo "$prefix/$1" ;; esac; }
expect_files() {  # root, then paths
  local root=$1; shift
  for f in "$@"; do [ -f "$root$f" ] || fail "not installed: $root$f"; done
}

rm -rf "$work" && mkdir -p "$work"
root="$work/root"
DESTDIR="$root" cmake --install "$build" >"$work/install1.log" 2>&1 || { cat "$work/install1.log" >&2; fail "cmake --install (DESTDIR) failed"; exit 1; }

unit="$(full "$unitdir")/evpipe.service"
expected=(
  "$bindir/evpipe" "$bindir/evconvert" "$bindir/evsim" "$bindir/evdenoise"
  "$unit" "$(full "$udevdir")/70-evpipe-inivation.rules"
  "$confdir/evpipe.yaml" "$confdir/evpipe.yaml.default" "$confdir/davis346.yaml" "$confdir/prior-example.yaml"
  "$confdir/roadheader-wireframe.yaml" "$confdir/roadheader-wireframe.dxf" "$confdir/target-planar.yaml"
  "$(full "$docdir")/operations.md" "$(full "$docdir")/README.md"
)
expect_files "$root" "${expected[@]}"
for b in evpipe evconvert evsim evdenoise; do [ -x "$root$bindir/$b" ] || fail "$bindir/$b not executable"; done

# The unit's ExecStart and the production config must point at files that were installed.
if [ -f "$root$unit" ]; then
  exec_line=$(sed -n 's/^ExecStart=//p' "$root$unit")
  exec_bin=${exec_line%% *}
  exec_cfg=$(sed -n 's/.*--config \([^ ]*\).*/\1/p' <<<"$exec_line")
  [ "$exec_bin" = "$bindir/evpipe" ] || fail "ExecStart program $exec_bin, expected $bindir/evpipe"
  [ "$exec_cfg" = "$confdir/evpipe.yaml" ] || fail "ExecStart --config $exec_cfg, expected $confdir/evpipe.yaml"
fi
if [ -f "$root$confdir/evpipe.yaml" ]; then
  for key in camera model prior; do
    path=$(sed -n "s/^  $key: \"\\([^\"]*\\)\".*/\\1/p" "$root$confdir/evpipe.yaml")
    [ -n "$path" ] || { fail "production evpipe.yaml: pose.$key is empty"; continue; }
    [ -f "$root$path" ] || fail "production evpipe.yaml: pose.$key = $path is not installed"
  done
  grep -q '^  replay: ""' "$root$confdir/evpipe.yaml" || fail "production evpipe.yaml must read the live camera"
  # Conffile behaviour: the site's edit survives a re-install, the default is refreshed.
  echo "# site edit" >>"$root$confdir/evpipe.yaml"
  echo "# stale" >>"$root$confdir/evpipe.yaml.default"
  DESTDIR="$root" cmake --install "$build" >"$work/install2.log" 2>&1 || fail "second cmake --install failed"
  tail -1 "$root$confdir/evpipe.yaml" | grep -qx '# site edit' || fail "re-install overwrote the site's evpipe.yaml"
  grep -qx '# stale' "$root$confdir/evpipe.yaml.default" && fail "re-install did not refresh evpipe.yaml.default"
  grep -q "Keeping: .*evpipe.yaml" "$work/install2.log" || fail "re-install did not say it kept evpipe.yaml"
fi

# 2. Relocated install: everything that is relative to the prefix follows --prefix.
DESTDIR= cmake --install "$build" --prefix "$work/prefix" >"$work/install3.log" 2>&1 || { cat "$work/install3.log" >&2; fail "cmake --install --prefix failed"; }
rel() { local p=$1; echo "${p#"$prefix"/}"; }
relocated=()
for f in "${expected[@]}"; do
  case $f in "$prefix"/*) relocated+=("$work/prefix/$(rel "$f")") ;; esac
done
expect_files "" "${relocated[@]}"

if [ "$fails" -ne 0 ]; then
  echo "$fails check(s) failed; installed tree:" >&2
  (cd "$work" && find root prefix -type f | sort) >&2
  exit 1
fi
echo "install: all ${#expected[@]} expected files installed (DESTDIR at $prefix, and relocated with --prefix: ${#relocated[@]} files)"
