#!/usr/bin/env bash
# Release check of the Debian package (docs/operations.md, "Install" and "Checking the package before a release"): builds evpipe_<v>_<arch>.deb
# with the deb preset, checks it statically (contents, conffiles, Depends from dpkg-shlibdeps, lintian: no errors),
# then installs it the way operations.md says into a fresh Debian 12 root made by debootstrap and checks it there:
# `apt-get install ./evpipe_*.deb`, `evpipe --version`, a replay of the bundled sample through the installed
# configuration (LCM to a log file, read back with evpipe-lcm-echo), `systemd-analyze verify` on the installed
# unit, what postinst did (group, service not enabled), an update that keeps the operator's edited evpipe.yaml,
# and `dpkg --purge` leaving nothing behind. Takes 8-28 minutes (debootstrap and the package's dependencies
# are downloaded from the Debian mirror): not part of tools/test.sh.
#
# Usage: sudo tools/check_deb.sh [--libcaer ON|AUTO|OFF] [--static-only] [--keep] [--mirror URL] [--work DIR]
#   --libcaer      EVPIPE_WITH_LIBCAER of the package build (default AUTO: the real libcaer when installed, else
#                  the stub, whose package cannot read a camera; a release package is checked with ON). With a
#                  real libcaer, the chroot gets the same libcaer files first, as the operator installs it first.
#   --static-only  build, contents and lintian only (no root, no debootstrap)
#   --keep         keep the Debian root (default: removed at the end)
#   --mirror URL   Debian mirror for debootstrap (default: the first .../debian URI in /etc/apt/sources.list*)
#   --work DIR     work folder (default build/deb-check)
set -euo pipefail
cd "$(dirname "$0")/.."
src=$(pwd)

libcaer=AUTO static_only=0 keep=0 mirror="" work="$src/build/deb-check"
while [ $# -gt 0 ]; do
  case $1 in
    --libcaer) libcaer=$2; shift 2 ;;
    --static-only) static_only=1; shift ;;
    --keep) keep=1; shift ;;
    --mirror) mirror=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -e/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "check_deb.sh: unknown argument $1 (--help)" >&2; exit 2 ;;
  esac
done

mkdir -p build "$work"
t_start=$(date +%s)
stamp() { echo "== [$(( $(date +%s) - t_start )) s] $*"; }
fails=0
fail() { echo "FAIL: $*" >&2; fails=$((fails + 1)); }
need() { command -v "$1" >/dev/null 2>&1 || { echo "check_deb.sh: $1 not found (Debian package $2; tools/setup.sh installs it)" >&2; exit 2; }; }
need cpack cmake; need dpkg-shlibdeps dpkg-dev; need lintian lintian

# ---- 1. build the package (operations.md, "Build the package") -----------------------------------------------------
stamp "build: cmake --preset deb -DEVPIPE_WITH_LIBCAER=$libcaer, cmake --build, cpack"
cmake --preset deb -DEVPIPE_WITH_LIBCAER="$libcaer" >"$src/build/deb-configure.log" 2>&1 || {
  cat "$src/build/deb-configure.log" >&2; echo "FAIL: configure (deb preset)" >&2; exit 1; }
cmake --build --preset deb -j"$(nproc)"
rm -f build/deb/evpipe_*.deb
cpack --preset deb >"$src/build/deb-cpack.log" 2>&1 || { cat "$src/build/deb-cpack.log" >&2; echo "FAIL: cpack" >&2; exit 1; }
deb=$(ls build/deb/evpipe_*.deb)
version=$(dpkg-deb -f "$deb" Version)
echo "package: $deb ($(du -h "$deb" | cut -f1))"

# ---- 2. static checks -----------------------------------------------------------------------------------------------
stamp "static: contents, conffiles, Depends, maintainer scripts, lintian"
contents=$(dpkg-deb --contents "$deb" | awk '{print $6}' | sed 's|^\./|/|')
for f in /usr/bin/evpipe /usr/bin/evconvert /usr/bin/evsim /usr/bin/evdenoise /usr/bin/evpose-eval \
         /usr/bin/evpipe-lcm-echo /usr/bin/evpipe-lcm-spy /etc/evpipe/evpipe.yaml /etc/evpipe/evpipe.yaml.default \
         /etc/evpipe/davis346.yaml /lib/systemd/system/evpipe.service /lib/udev/rules.d/70-evpipe-inivation.rules \
         /usr/share/evpipe/lcmtypes/pose_t.lcm /usr/share/evpipe/lcmtypes/evpipe_lcmtypes.jar \
         /usr/share/doc/evpipe/operations.md /usr/share/doc/evpipe/copyright /usr/share/doc/evpipe/changelog.gz; do
  grep -qxF "$f" <<<"$contents" || fail "package lacks $f"
done
grep -E '^/usr/local|^/usr/lib/systemd|^/usr/etc' <<<"$contents" && fail "package has files outside the FHS layout above"
ctl="$work/control"
rm -rf "$ctl" && mkdir -p "$ctl" && dpkg-deb -e "$deb" "$ctl"
etc_files=$(grep '^/etc/.*[^/]$' <<<"$contents" | sort)
[ "$etc_files" = "$(sort "$ctl/conffiles")" ] || fail "conffiles $(tr '\n' ' ' <"$ctl/conffiles") != files in /etc $(tr '\n' ' ' <<<"$etc_files")"
depends=$(dpkg-deb -f "$deb" Depends)
for d in libc6 liblcm1 libsystemd0; do grep -q "$d" <<<"$depends" || fail "Depends lacks $d (dpkg-shlibdeps): $depends"; done
for s in postinst prerm postrm; do [ -x "$ctl/$s" ] || fail "no executable $s"; done
lintian --fail-on error "$deb" >"$work/lintian.txt" 2>&1 || { cat "$work/lintian.txt" >&2; fail "lintian reports errors"; }
echo "lintian: $(grep -c '^E:' "$work/lintian.txt" || true) errors, $(grep -c '^W:' "$work/lintian.txt" || true) warnings ($(grep '^W:' "$work/lintian.txt" | awk '{print $3}' | sort | uniq -c | tr -s ' ' | paste -sd, -))"

if [ "$static_only" = 1 ]; then
  [ "$fails" -eq 0 ] || { echo "$fails check(s) failed" >&2; exit 1; }
  stamp "static checks passed ($deb)"
  exit 0
fi

# ---- 3. a fresh Debian 12 root (operations.md, "Install") ---------------------------------------------------------
[ "$(id -u)" -eq 0 ] || { echo "check_deb.sh: the chroot part needs root (or use --static-only)" >&2; exit 2; }
need debootstrap debootstrap
sources=$(cat /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources 2>/dev/null |
          grep -E '^[[:space:]]*(deb[[:space:]]|URIs:)' || true)
if [ -z "$mirror" ]; then
  mirror=$(grep -oE '(https?|file)://[^[:space:]]*/debian/?([[:space:]]|$)' <<<"$sources" | head -1 | tr -d '[:space:]')
fi
security=$(grep -oE '(https?|file)://[^[:space:]]*/debian-security/?([[:space:]]|$)' <<<"$sources" | head -1 | tr -d '[:space:]')
[ -n "$mirror" ] || { echo "check_deb.sh: no Debian mirror in /etc/apt/sources.list*: give --mirror URL" >&2; exit 2; }

root="$work/root"
cleanup() {
  for m in dev/pts proc sys; do if mountpoint -q "$root/$m" 2>/dev/null; then umount -l "$root/$m"; fi; done
  if [ "$keep" = 0 ]; then rm -rf --one-file-system "$root"; fi
}
trap cleanup EXIT
for m in dev/pts proc sys; do if mountpoint -q "$root/$m" 2>/dev/null; then umount -l "$root/$m"; fi; done
rm -rf --one-file-system "$root"
stamp "debootstrap --variant=minbase --include=systemd,udev bookworm ($mirror)"
debootstrap --variant=minbase --include=systemd,udev bookworm "$root" "$mirror" >"$work/debootstrap.log" 2>&1 || {
  tail -20 "$work/debootstrap.log" >&2; echo "FAIL: debootstrap" >&2; exit 1; }
{
  echo "deb $mirror bookworm main"
  echo "deb $mirror bookworm-updates main"
  [ -z "$security" ] || echo "deb $security bookworm-security main"
} >"$root/etc/apt/sources.list"
mount -t proc proc "$root/proc"
mount -t sysfs sys "$root/sys"
mkdir -p "$root/dev/pts" && mount --bind /dev/pts "$root/dev/pts"   # apt wants a pty for its log
in_root() { chroot "$root" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 DEBIAN_FRONTEND=noninteractive "$@"; }
in_root apt-get update -qq

# A build against the real libcaer: the operator installed libcaer first (operations.md); the check copies the files
# of the library the package was linked with, and installs what libcaer itself needs (libusb).
if dpkg-deb --fsys-tarfile "$deb" | tar -xO ./usr/bin/evpipe >"$work/evpipe.bin" && grep -q "libcaer\.so" "$work/evpipe.bin"; then
  so=$(ldd build/deb/apps/evpipe/evpipe | awk '/libcaer\.so/ {print $3}')
  [ -n "$so" ] || { echo "FAIL: the package links libcaer but build/deb/apps/evpipe/evpipe does not resolve it" >&2; exit 1; }
  echo "libcaer: copying $(dirname "$so")/libcaer.so* into the root (the operator's libcaer install)"
  mkdir -p "$root$(dirname "$so")"
  cp -a "$(dirname "$so")"/libcaer.so* "$root$(dirname "$so")/"
  in_root apt-get install -y -qq libusb-1.0-0 >/dev/null
  in_root ldconfig
fi

# ---- 4. install as operations.md says --------------------------------------------------------------------------------
stamp "apt-get install ./$(basename "$deb") in the root"
cp "$deb" "$root/tmp/"
in_root sh -c "cd /tmp && apt-get install -y -q ./$(basename "$deb")" >"$work/install.log" 2>&1 || {
  tail -30 "$work/install.log" >&2; echo "FAIL: apt-get install" >&2; exit 1; }
echo "installed with $(grep -oE '[0-9]+ newly installed' "$work/install.log" || echo '? newly installed') packages"

stamp "evpipe --version, replay of the bundled sample, evpipe-lcm-echo, systemd-analyze verify, postinst effects"
ver=$(in_root evpipe --version) || fail "evpipe --version failed"
echo "$ver"
[ "$(sed -n 1p <<<"$ver")" = "evpipe $version" ] || fail "evpipe --version: first line is not 'evpipe $version'"
if [ "$libcaer" = ON ]; then
  grep -qE '^libcaer: [0-9]+\.[0-9]+\.[0-9]+$' <<<"$ver" || fail "--libcaer ON but evpipe --version says: $ver"
else
  grep -qE '^libcaer: ' <<<"$ver" || fail "evpipe --version names no libcaer"
fi

sample=tests/data/roadheader-sample
mkdir -p "$root/tmp/sample"
cp "$sample".aedat4 "$sample".camera.yaml "$sample".model.yaml "$sample".prior.yaml "$sample".gt.csv "$root/tmp/sample/"
s=/tmp/sample/roadheader-sample
if in_root evpipe --config /etc/evpipe/evpipe.yaml --replay $s.aedat4 --speed max --no-progress \
     --camera $s.camera.yaml --model $s.model.yaml --prior $s.prior.yaml --ground-truth $s.gt.csv \
     --lcm-url 'file:///tmp/run.lcmlog?mode=w' >"$work/replay.txt" 2>"$work/replay.err"; then
  grep -E '^  (events|poses|LCM|ATE) ' "$work/replay.txt"
  grep -qE '^  poses +[1-9][0-9]* valid' "$work/replay.txt" || fail "the replay produced no valid pose"
else
  cat "$work/replay.err" "$work/replay.txt" >&2; fail "evpipe --replay of the sample failed in the root"
fi
n=$(in_root evpipe-lcm-echo --log /tmp/run.lcmlog --text | grep -c '^EVPIPE_POSE ' || true)
echo "evpipe-lcm-echo --log: $n pose messages"
[ "$n" -gt 0 ] || fail "evpipe-lcm-echo read no pose from the replay's LCM log"

verify=$(in_root systemd-analyze verify /lib/systemd/system/evpipe.service 2>&1) || fail "systemd-analyze verify failed: $verify"
[ -z "$verify" ] || { echo "$verify" >&2; fail "systemd-analyze verify printed diagnostics"; }
[ -n "$verify" ] || echo "systemd-analyze verify /lib/systemd/system/evpipe.service: OK"
in_root getent group plugdev >/dev/null || fail "group plugdev missing (the unit's SupplementaryGroups=)"
state=$(in_root systemctl is-enabled evpipe.service 2>/dev/null || true)
[ "$state" = disabled ] || fail "evpipe.service is '$state' after install, expected disabled (not enabled on install)"
echo "evpipe.service after install: $state; group plugdev: present"

# ---- 5. update: an edited evpipe.yaml survives (conffile) ----------------------------------------------------------
stamp "update to a rebuilt $version+check1 whose evpipe.yaml changed too: the operator's edit is kept"
echo "# site edit (check_deb.sh)" >>"$root/etc/evpipe/evpipe.yaml"
re="$work/repack"
rm -rf "$re" && dpkg-deb -R "$deb" "$re"
sed -i "s/^Version: .*/Version: $version+check1/" "$re/DEBIAN/control"
echo "# a change of the new version (check_deb.sh)" >>"$re/etc/evpipe/evpipe.yaml"
(cd "$re" && find . -type f ! -path './DEBIAN/*' -printf '%P\0' | sort -z | xargs -0 md5sum) >"$re/DEBIAN/md5sums"
dpkg-deb --root-owner-group -b "$re" "$root/tmp/evpipe_${version}+check1_update.deb" >/dev/null
in_root sh -c "cd /tmp && apt-get install -y -q -o Dpkg::Options::=--force-confold ./evpipe_${version}+check1_update.deb" \
  >"$work/update.log" 2>&1 || { tail -20 "$work/update.log" >&2; fail "apt-get install of the update failed"; }
grep -qx '# site edit (check_deb.sh)' "$root/etc/evpipe/evpipe.yaml" || fail "the update overwrote the edited evpipe.yaml"
[ -f "$root/etc/evpipe/evpipe.yaml.dpkg-dist" ] || fail "the update's new evpipe.yaml is not in evpipe.yaml.dpkg-dist"
[ "$(in_root dpkg-query -W -f='${Version}' evpipe)" = "$version+check1" ] || fail "the update did not install"
echo "update: edited evpipe.yaml kept, the new one is evpipe.yaml.dpkg-dist"

# ---- 6. purge: nothing left -----------------------------------------------------------------------------------------
stamp "dpkg --purge evpipe"
files=$(in_root dpkg -L evpipe | sort)
in_root dpkg --purge evpipe >"$work/purge.log" 2>&1 || { cat "$work/purge.log" >&2; fail "dpkg --purge failed"; }
grep -i "warning" "$work/purge.log" && fail "dpkg --purge warned"
left=""
while IFS= read -r f; do
  [ -n "$f" ] || continue
  if [ -e "$root$f" ] && [ ! -d "$root$f" ]; then left+="$f "; fi
done <<<"$files"
[ -z "$left" ] || fail "files of the package left after purge: $left"
for d in /etc/evpipe /var/lib/evpipe /var/lib/private/evpipe /usr/share/evpipe /usr/share/doc/evpipe; do
  [ ! -e "$root$d" ] || fail "$d left after purge"
done
# Anything else named after evpipe, outside the logs, apt's state and our own files in /tmp.
stray=$(cd "$root" && find . -xdev \( -path ./proc -o -path ./sys -o -path ./tmp -o -path ./var/log \) -prune -o \
          -iname '*evpipe*' -print)
[ -z "$stray" ] || fail "left after purge: $stray"
echo "purge: no file of the package and nothing named evpipe left (outside /tmp and /var/log)"

if [ "$fails" -ne 0 ]; then
  echo "$fails check(s) failed (work folder $work$([ "$keep" = 1 ] && echo ", root kept in $root"))" >&2
  exit 1
fi
stamp "all package checks passed: $deb ($(sed -n 2p <<<"$ver"))"
