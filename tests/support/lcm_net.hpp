#pragma once
// Multicast for LCM udpm:// tests. LCM needs a multicast route even for ttl=0 (docs/operations.md "LCM"); CI
// machines and containers often have none. As root the test moves itself into a private network namespace
// (unshare(CLONE_NEWNET): only `lo`, invisible to the host and to other tests running in parallel), brings lo up
// with multicast and adds 224.0.0.0/4 there. Child processes (lcm-logger, evpipe) inherit the namespace.
// If unshare is not allowed, a missing route is added on the host's lo (root only); otherwise the caller
// skips with the reason returned.

#include <sched.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>

namespace evpipe::testing {

struct MulticastSetup {
  bool ok{false};
  bool private_netns{false};
  std::string message;  ///< why it is not ok, or how it was set up
};

inline bool host_has_multicast_route() {
  return std::system("ip route show table all 2>/dev/null | grep -q '^224.0.0.0/4 '") == 0 ||
         std::system("ip route show 2>/dev/null | grep -q '^default '") == 0;
}

/// Enters a fresh private network namespace with lo up, optionally with the multicast route. Must be called
/// while the process is single-threaded (no live LCM instance with a receive thread).
inline MulticastSetup enter_private_netns(bool add_route) {
  MulticastSetup s;
  if (geteuid() != 0) {
    s.message = "not root: cannot create a network namespace";
    return s;
  }
  if (unshare(CLONE_NEWNET) != 0) {
    s.message = std::string("unshare(CLONE_NEWNET) failed: ") + std::strerror(errno);
    return s;
  }
  std::string cmd = "ip link set lo up && ip link set lo multicast on";
  if (add_route) {
    cmd += " && ip route add 224.0.0.0/4 dev lo";
  }
  if (std::system((cmd + " >/dev/null 2>&1").c_str()) != 0) {
    s.message = "in the private network namespace, '" + cmd + "' failed (is iproute2 installed?)";
    return s;
  }
  s.ok = true;
  s.private_netns = true;
  s.message = add_route ? "private network namespace, lo multicast + route 224.0.0.0/4"
                        : "private network namespace, lo up, no multicast route";
  return s;
}

/// A working multicast route for udpm:// on loopback: a private namespace when possible, else the host's route
/// (added on lo when missing and root).
inline MulticastSetup ensure_multicast_route() {
  MulticastSetup s = enter_private_netns(true);
  if (s.ok) {
    return s;
  }
  const std::string why_not_private = s.message;
  if (host_has_multicast_route()) {
    s.ok = true;
    s.message = "host network (" + why_not_private + "); a multicast/default route exists";
    return s;
  }
  if (geteuid() == 0 &&
      std::system("ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo >/dev/null 2>&1") == 0) {
    s.ok = true;
    s.message = "host network (" + why_not_private + "); added route 224.0.0.0/4 on lo";
    return s;
  }
  s.message = "no multicast route and cannot add one (" + why_not_private +
              "); as root: ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo";
  return s;
}

}  // namespace evpipe::testing
