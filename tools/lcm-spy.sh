#!/usr/bin/env bash
# Starts lcm-spy with evpipe's LCM types so EVPIPE_POSE / EVPIPE_STATS show decoded.
#
# Debian 12's own `lcm-spy` script passes -Xincgc, which OpenJDK 17 rejects ("Could not create the Java Virtual
# Machine"); this launcher runs lcm.spy.Spy directly: the types jar goes in CLASSPATH (lcm-spy scans it for
# LCM types), lcm.jar + jchart2d.jar on -cp, IPv4 multicast. Needs liblcm-java, libjchart2d-java and a JRE.
#
# Usage: tools/lcm-spy.sh [--url URL] [--build-dir DIR] [--jar FILE] [--check]
#   --url URL        LCM URL to listen on (default: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0)
#   --build-dir DIR  build tree with the types jar (default: <repo>/build); built there when missing or stale
#   --jar FILE       use this types jar (default: $EVPIPE_LCMTYPES_JAR, the build tree, or the installed one)
#   --check          build/find the jar and verify that Java loads lcm.spy.Spy and finds the evpipe types the way
#                    lcm-spy does, without opening a window (CI)
# Installed by `cmake --install` as bin/evpipe-lcm-spy, it finds the jar under share/evpipe/lcmtypes.
set -euo pipefail

script_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo_root=$(cd "$script_dir/.." && pwd)
url="" build_dir="" jar="${EVPIPE_LCMTYPES_JAR:-}" check=0

die() { echo "lcm-spy.sh: $*" >&2; exit 1; }
while [ $# -gt 0 ]; do
  case "$1" in
    --url) [ $# -ge 2 ] || die "--url needs a value"; url=$2; shift 2 ;;
    --url=*) url=${1#--url=}; shift ;;
    --build-dir) [ $# -ge 2 ] || die "--build-dir needs a value"; build_dir=$2; shift 2 ;;
    --build-dir=*) build_dir=${1#--build-dir=}; shift ;;
    --jar) [ $# -ge 2 ] || die "--jar needs a value"; jar=$2; shift 2 ;;
    --jar=*) jar=${1#--jar=}; shift ;;
    --check) check=1; shift ;;
    -h|--help) sed -n '2,15p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done

# Java side: lcm.jar from lcm-java.pc, jchart2d.jar beside it (Debian's shared Java directory).
command -v java >/dev/null 2>&1 || die "no 'java' found: install default-jdk-headless (or default-jre)"
lcm_jar=$(pkg-config --variable=classpath lcm-java 2>/dev/null || true)
[ -n "$lcm_jar" ] || lcm_jar=/usr/share/java/lcm.jar
[ -f "$lcm_jar" ] || die "lcm.jar not found ($lcm_jar): install liblcm-java"
java_dir=$(dirname "$lcm_jar")
jchart_jar="$java_dir/jchart2d.jar"
[ -f "$jchart_jar" ] || die "jchart2d.jar not found in $java_dir: install libjchart2d-java"

# The types jar: explicit, else a build tree (built if needed), else the installed copy.
installed_jar="$script_dir/../share/evpipe/lcmtypes/evpipe_lcmtypes.jar"
if [ -z "$jar" ]; then
  if [ -z "$build_dir" ] && [ -f "$installed_jar" ]; then
    jar=$installed_jar
  else
    [ -n "$build_dir" ] || build_dir="$repo_root/build"
    if [ ! -f "$build_dir/CMakeCache.txt" ]; then
      [ -f "$repo_root/CMakeLists.txt" ] || die "no build tree at $build_dir and no source tree to configure"
      echo "lcm-spy.sh: configuring $build_dir" >&2
      cmake -S "$repo_root" -B "$build_dir" -G Ninja >/dev/null
    fi
    # Always ask the build: a no-op when the jar is current, a rebuild when a .lcm file changed.
    cmake --build "$build_dir" --target evpipe_lcmtypes_jar >/dev/null ||
      die "building evpipe_lcmtypes_jar in $build_dir failed (is a JDK installed? default-jdk-headless)"
    jar="$build_dir/evpipe_lcmtypes.jar"
  fi
fi
[ -f "$jar" ] || die "types jar not found: $jar"
jar=$(cd "$(dirname "$jar")" && pwd)/$(basename "$jar")

if [ "$check" = 1 ]; then
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  # Single-file source launch (JDK 11+). Loads Spy without initialising Swing, then lets lcm-spy's own type
  # database scan CLASSPATH and looks every evpipe type up by its fingerprint, as Spy does for each message.
  cat >"$tmp/EvpipeSpyCheck.java" <<'JAVA'
public class EvpipeSpyCheck {
  public static void main(String[] args) throws Exception {
    ClassLoader loader = EvpipeSpyCheck.class.getClassLoader();
    Class.forName("lcm.spy.Spy", false, loader);
    lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
    int bad = 0;
    for (String name : new String[] {"evpipe.pose_t", "evpipe.stats_t", "evpipe.stage_stats_t", "evpipe.queue_stats_t"}) {
      Class<?> c = Class.forName(name, true, loader);
      long fp = c.getField("LCM_FINGERPRINT").getLong(null);
      Class<?> found = db.getClassByFingerprint(fp);
      boolean ok = found != null && found.getName().equals(name);
      System.out.printf("%s fingerprint 0x%016x %s%n", name, fp, ok ? "found by lcm-spy's type database" : "NOT FOUND");
      if (!ok) bad++;
    }
    System.exit(bad == 0 ? 0 : 1);
  }
}
JAVA
  CLASSPATH="$jar" java -Djava.awt.headless=true -Djava.net.preferIPv4Stack=true \
    -cp "$lcm_jar:$jchart_jar:$jar" "$tmp/EvpipeSpyCheck.java" ||
    die "check failed: Java cannot load lcm.spy.Spy or the evpipe types from $jar"
  echo "lcm-spy.sh: ok: lcm.spy.Spy and the evpipe types load (jar $jar)"
  exit 0
fi

if [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ]; then
  die "no display (DISPLAY is not set): lcm-spy is a GUI. Run it on a desktop, with 'ssh -X', or under
  xvfb-run; without a GUI use evpipe-lcm-echo to print the messages as JSON lines."
fi
args=()
[ -n "$url" ] && args+=(--lcm-url="$url")
echo "lcm-spy.sh: types $jar; URL ${url:-${LCM_DEFAULT_URL:-LCM default}}" >&2
CLASSPATH="$jar" exec java -Djava.net.preferIPv4Stack=true -cp "$lcm_jar:$jchart_jar" lcm.spy.Spy "${args[@]}"
