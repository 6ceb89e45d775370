#include "evpipe/transport/lcm_url.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <vector>

namespace evpipe::transport {

namespace {

std::optional<std::int64_t> to_int(std::string_view s) {
  std::int64_t v = 0;
  if (s.empty()) return std::nullopt;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || p != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<double> to_double(std::string_view s) {
  double v = 0;
  if (s.empty()) return std::nullopt;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || p != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<std::string> check_port(std::string_view port, std::string_view what) {
  const auto p = to_int(port);
  if (!p || *p < 1 || *p > 65535) return fmt::format("{}: port '{}' is not an integer 1-65535", what, port);
  return std::nullopt;
}

// group:port, both optional (LCM's defaults); the group an IPv4 multicast address.
std::optional<std::string> check_udpm_target(std::string_view target) {
  if (target.empty()) return std::nullopt;
  const auto colon = target.rfind(':');
  const std::string_view host = target.substr(0, colon);
  if (colon != std::string_view::npos) {
    if (auto e = check_port(target.substr(colon + 1), "udpm")) return e;
  }
  std::vector<std::int64_t> octets;
  std::size_t start = 0;
  for (;;) {
    const auto dot = host.find('.', start);
    const auto o = to_int(host.substr(start, dot == std::string_view::npos ? std::string_view::npos : dot - start));
    if (!o || *o < 0 || *o > 255) {
      octets.clear();
      break;
    }
    octets.push_back(*o);
    if (dot == std::string_view::npos) break;
    start = dot + 1;
  }
  if (octets.size() != 4) return fmt::format("udpm: '{}' is not an IPv4 address a.b.c.d", host);
  if (octets[0] < 224 || octets[0] > 239)
    return fmt::format("udpm: {} is not a multicast group (224.0.0.0 to 239.255.255.255)", host);
  return std::nullopt;
}

}  // namespace

std::optional<std::string> check_lcm_url(const std::string& url, bool for_publishing, LcmUrl* parsed) {
  const auto sep = url.find("://");
  if (sep == std::string::npos || sep == 0)
    return fmt::format("'{}' is not an LCM URL (provider://target?options, e.g. udpm://239.255.76.67:7667?ttl=0)", url);
  LcmUrl u;
  u.provider = url.substr(0, sep);
  const std::string rest = url.substr(sep + 3);
  const auto q = rest.find('?');
  u.target = rest.substr(0, q);
  std::vector<std::pair<std::string, std::string>> options;
  if (q != std::string::npos) {
    std::string_view opts = std::string_view(rest).substr(q + 1);
    while (!opts.empty()) {
      const auto amp = opts.find('&');
      const std::string_view kv = opts.substr(0, amp);
      const auto eq = kv.find('=');
      if (eq == std::string_view::npos || eq == 0) return fmt::format("{}: option '{}' is not key=value", url, kv);
      options.emplace_back(std::string(kv.substr(0, eq)), std::string(kv.substr(eq + 1)));
      if (amp == std::string_view::npos) break;
      opts.remove_prefix(amp + 1);
    }
  }
  const auto bad = [&](const std::string& why) { return fmt::format("{}: {}", url, why); };
  if (u.provider == "udpm" || u.provider == "mpudpm") {
    if (auto e = check_udpm_target(u.target)) return bad(*e);
    for (const auto& [k, v] : options) {
      if (k == "ttl") {
        const auto t = to_int(v);
        if (!t || *t < 0 || *t > 255) return bad(fmt::format("ttl '{}' is not an integer 0-255", v));
      } else if (k == "recv_buf_size") {
        const auto n = to_int(v);
        if (!n || *n <= 0 || *n > INT32_MAX) return bad(fmt::format("recv_buf_size '{}' is not a positive integer", v));
      } else if (u.provider == "udpm") {
        return bad(fmt::format("unknown udpm option '{}' (known: ttl, recv_buf_size)", k));
      }
    }
  } else if (u.provider == "file") {
    if (u.target.empty()) return bad("file:// needs a path (file:///var/log/evpipe/run.lcmlog?mode=w)");
    u.mode = "r";
    for (const auto& [k, v] : options) {
      if (k == "mode") {
        if (v != "r" && v != "w") return bad(fmt::format("mode '{}' is not r or w", v));
        u.mode = v;
      } else if (k == "speed") {
        const auto s = to_double(v);
        if (!s || *s < 0) return bad(fmt::format("speed '{}' is not a number >= 0", v));
      } else if (k == "start_timestamp") {
        if (!to_int(v)) return bad(fmt::format("start_timestamp '{}' is not an integer", v));
      } else {
        return bad(fmt::format("unknown file option '{}' (known: mode, speed, start_timestamp)", k));
      }
    }
    if (for_publishing && u.mode != "w") return bad("publishing to a log file needs mode=w (read mode is the default)");
    if (!for_publishing && u.mode == "w")
      return bad("mode=w would truncate the log: reading it needs mode=r (the default)");
  } else if (u.provider == "memq") {
    if (!u.target.empty() || !options.empty()) return bad("memq:// takes no target or options");
  } else if (u.provider == "tcpq") {
    const auto colon = u.target.rfind(':');
    if (u.target.empty() || colon == std::string::npos || colon == 0)
      return bad("tcpq:// needs host:port (e.g. tcpq://127.0.0.1:7700)");
    if (auto e = check_port(u.target.substr(colon + 1), "tcpq")) return bad(*e);
    if (!options.empty()) return bad("tcpq:// takes no options");
  } else {
    return bad(fmt::format("unknown LCM provider '{}' (known: udpm, mpudpm, file, memq, tcpq)", u.provider));
  }
  if (parsed != nullptr) *parsed = std::move(u);
  return std::nullopt;
}

}  // namespace evpipe::transport
