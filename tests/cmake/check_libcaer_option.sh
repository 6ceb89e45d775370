#!/usr/bin/env bash
# EVPIPE_WITH_LIBCAER (cmake/EvpipeLibcaer.cmake) with libcaer hidden, and with fake pkg-config installs of an old
# and of a current libcaer in a non-system prefix: ON without libcaer fails at configure with the message saying
# how to get it, AUTO falls back to the stub, a 2.x is refused, and a libcaer outside the linker's default folders
# gets an install RPATH unless EVPIPE_LIBCAER_RPATH=OFF (the package's choice). Runs the small project in
# libcaer_option/ (no compiler), about 0.3 s per configure.
# Usage: check_libcaer_option.sh <work dir>
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=$1
rm -rf "$work" && mkdir -p "$work/pc-empty"
fails=0
fail() { echo "FAIL: $*" >&2; fails=$((fails + 1)); }

# configure <name> <pkg-config dir> [cmake args...]: output in $out, status in $rc.
configure() {
  local name=$1 pcdir=$2; shift 2
  set +e
  out=$(env -u CMAKE_PREFIX_PATH -u PKG_CONFIG_PATH PKG_CONFIG_LIBDIR="$pcdir" \
        cmake -S "$here/libcaer_option" -B "$work/$name" -DCMAKE_DISABLE_FIND_PACKAGE_libcaer=ON "$@" 2>&1)
  rc=$?
  set -e
}
expect() {  # <what> <fixed string>
  grep -qF -- "$2" <<<"$out" || { fail "$1: output lacks '$2'"; echo "$out" >&2; }
}

# No libcaer at all.
configure on-missing "$work/pc-empty" -DEVPIPE_WITH_LIBCAER=ON
[ "$rc" -ne 0 ] || fail "ON without libcaer configured successfully"
expect "ON without libcaer" "EVPIPE_WITH_LIBCAER=ON, but libcaer >= 3.3 was not found"
expect "ON without libcaer" "docs/operations.md"
expect "ON without libcaer" "-DEVPIPE_WITH_LIBCAER=AUTO or OFF"
configure auto-missing "$work/pc-empty" -DEVPIPE_WITH_LIBCAER=AUTO
[ "$rc" -eq 0 ] || fail "AUTO without libcaer failed"
expect "AUTO without libcaer" "resolved: EVPIPE_WITH_LIBCAER=OFF"
configure off "$work/pc-empty" -DEVPIPE_WITH_LIBCAER=OFF
[ "$rc" -eq 0 ] || fail "OFF failed"
expect "OFF" "resolved: EVPIPE_WITH_LIBCAER=OFF"
configure bad "$work/pc-empty" -DEVPIPE_WITH_LIBCAER=MAYBE
[ "$rc" -ne 0 ] || fail "EVPIPE_WITH_LIBCAER=MAYBE accepted"
expect "MAYBE" "must be ON, OFF or AUTO"

# fake_libcaer <prefix> <version>: a pkg-config file and an (empty) libcaer.so under <prefix>.
fake_libcaer() {
  mkdir -p "$1/lib/pkgconfig" "$1/include/libcaer"
  : >"$1/lib/libcaer.so"
  cat >"$1/lib/pkgconfig/libcaer.pc" <<PC
prefix=$1
libdir=\${prefix}/lib
includedir=\${prefix}/include
Name: libcaer
Description: fake libcaer for evpipe's configure test
Version: $2
Libs: -L\${libdir} -lcaer
Cflags: -I\${includedir}
PC
}

# An old libcaer is not taken.
fake_libcaer "$work/old" 2.4.2
configure on-old "$work/old/lib/pkgconfig" -DEVPIPE_WITH_LIBCAER=ON
[ "$rc" -ne 0 ] || fail "ON with only libcaer 2.4.2 configured successfully"
expect "ON with libcaer 2.4.2" "found only libcaer 2.4.2 (pkg-config)"
configure auto-old "$work/old/lib/pkgconfig" -DEVPIPE_WITH_LIBCAER=AUTO
expect "AUTO with libcaer 2.4.2" "resolved: EVPIPE_WITH_LIBCAER=OFF"

# A current libcaer in a non-system prefix: found, RPATH to it (or none when the package's ld.so.conf.d entry is used).
fake_libcaer "$work/opt" 3.3.15
configure on-opt "$work/opt/lib/pkgconfig" -DEVPIPE_WITH_LIBCAER=ON
[ "$rc" -eq 0 ] || fail "ON with libcaer 3.3.15 failed"
expect "ON with libcaer 3.3.15" "resolved: EVPIPE_WITH_LIBCAER=ON version=3.3.15 libdir=$work/opt/lib extra=ON rpath=$work/opt/lib"
configure on-opt-norpath "$work/opt/lib/pkgconfig" -DEVPIPE_WITH_LIBCAER=ON -DEVPIPE_LIBCAER_RPATH=OFF
grep -q "extra=ON rpath=\$" <<<"$out" || { fail "EVPIPE_LIBCAER_RPATH=OFF still sets an RPATH"; echo "$out" >&2; }
configure auto-opt "$work/opt/lib/pkgconfig"
expect "AUTO with libcaer 3.3.15" "resolved: EVPIPE_WITH_LIBCAER=ON version=3.3.15"

if [ "$fails" -ne 0 ]; then echo "$fails check(s) failed" >&2; exit 1; fi
echo "EVPIPE_WITH_LIBCAER: ON/OFF/AUTO, version floor and RPATH behave as documented"
