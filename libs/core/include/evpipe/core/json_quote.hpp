#pragma once
// JSON string quoting shared by every machine-readable output (evpipe --json, evdenoise --metrics, evpose-eval
// --json, evpipe-lcm-echo).

#include <fmt/format.h>

#include <string>
#include <string_view>

namespace evpipe {

/// `s` as a JSON string literal, quotes included; control characters escaped.
inline std::string json_quote(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("\\u{:04x}", static_cast<unsigned>(static_cast<unsigned char>(c)));
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

}  // namespace evpipe
