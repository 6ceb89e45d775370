#!/usr/bin/env bash
# `systemd-analyze verify` on the configured evpipe.service. verify needs ExecStart='s program to exist, and the
# installed path (e.g. /usr/local/bin/evpipe) need not exist on a build machine: a copy of the unit with
# ExecStart= pointing at the freshly built evpipe is verified instead (every other line unchanged).
# Any diagnostic fails the test: verify exits 0 on "Unknown key ..., ignoring", which would hide a typo.
# Usage: check_unit.sh <configured evpipe.service> <built evpipe> <work dir>
set -euo pipefail
unit=$1 evpipe=$2 work=$3

if ! command -v systemd-analyze >/dev/null 2>&1; then
  echo "SKIP: systemd-analyze not found (Debian package systemd, listed in tools/setup.sh)"
  exit 0
fi
[ -x "$evpipe" ] || { echo "FAIL: built evpipe not found at $evpipe" >&2; exit 1; }
grep -q '^ExecStart=/' "$unit" || { echo "FAIL: $unit has no absolute ExecStart=" >&2; exit 1; }

rm -rf "$work" && mkdir -p "$work"
installed_bin=$(sed -n 's/^ExecStart=\([^ ]*\).*/\1/p' "$unit")
sed "s|^ExecStart=$installed_bin|ExecStart=$evpipe|" "$unit" >"$work/evpipe.service"
grep -q "^ExecStart=$evpipe --config /" "$work/evpipe.service" || { echo "FAIL: ExecStart not rewritten" >&2; exit 1; }

# The settings the service depends on (docs/operations.md): a regression here would pass verify.
for line in 'Type=notify' 'NotifyAccess=main' 'WatchdogSec=5s' 'Restart=on-failure' 'DynamicUser=yes' \
            'SupplementaryGroups=plugdev' 'DevicePolicy=closed' 'DeviceAllow=char-usb_device rw' \
            'After=network-online.target' 'Wants=network-online.target'; do
  grep -qxF "$line" "$unit" || { echo "FAIL: $unit lacks '$line'" >&2; exit 1; }
done
if grep -q '^PrivateDevices=yes' "$unit"; then
  echo "FAIL: PrivateDevices=yes hides the USB device nodes" >&2; exit 1
fi

out=$(cd "$work" && systemd-analyze verify ./evpipe.service 2>&1) || { echo "$out" >&2; echo "FAIL: verify exit code" >&2; exit 1; }
if [ -n "$out" ]; then
  echo "$out" >&2
  echo "FAIL: systemd-analyze verify printed diagnostics" >&2
  exit 1
fi
echo "systemd-analyze verify: OK ($unit, ExecStart=$installed_bin -> $evpipe)"
if security=$(cd "$work" && systemd-analyze security --offline=yes ./evpipe.service 2>/dev/null | tail -1); then
  echo "$security"
fi
