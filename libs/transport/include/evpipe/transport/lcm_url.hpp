#pragma once
// LCM URL checks done before LCM sees a URL (LCM 1.3.1 takes `?ttl=300` as TTL 44 and `?ttl=-1` as 255, ignores
// unknown options, and a URL it cannot parse would only fail each time LCM is created): docs/operations.md, "LCM".

#include <optional>
#include <string>

namespace evpipe::transport {

/// A parsed LCM URL: `provider://target?key=value&...`.
struct LcmUrl {
  std::string provider;  ///< udpm, mpudpm, file, memq, tcpq
  std::string target;    ///< udpm: group:port (may be empty: LCM's default); file: the log path; tcpq: host:port
  std::string mode;      ///< file: r (default), w or a
};

/// Checks `url` (already resolved: effective_lcm_url()) for a publisher (`for_publishing`: a file:// log must be
/// opened with mode=w) or a subscriber. Returns the reason it is not usable, or nullopt with `parsed` filled.
/// Checked: the provider is one LCM 1.3.1 has; udpm/mpudpm: an IPv4 multicast group (224.0.0.0/4) and a port
/// 1-65535, options ttl (an integer 0-255) and recv_buf_size (a positive integer) only; file: a path, options mode
/// (r, w), speed (>= 0) and start_timestamp (an integer); tcpq: host:port; memq: nothing after "memq://".
[[nodiscard]] std::optional<std::string> check_lcm_url(const std::string& url, bool for_publishing,
                                                       LcmUrl* parsed = nullptr);

}  // namespace evpipe::transport
