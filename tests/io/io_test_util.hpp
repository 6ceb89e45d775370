#pragma once
// Small helpers for the reader tests: byte builders, draining a reader, collecting warnings.

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "evpipe/io/reader.hpp"

namespace evpipe::testing {

using Bytes = std::vector<std::byte>;

inline void append(Bytes& out, std::string_view s) {
  for (char c : s) out.push_back(static_cast<std::byte>(c));
}
inline Bytes bytes_of(std::string_view s) {
  Bytes out;
  append(out, s);
  return out;
}
inline void put_be32(Bytes& out, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFFu));
}
inline void put_le32(Bytes& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFFu));
}
inline void put_le16(Bytes& out, std::uint16_t v) {
  out.push_back(static_cast<std::byte>(v & 0xFFu));
  out.push_back(static_cast<std::byte>(v >> 8));
}

inline Bytes read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::vector<char> raw((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  Bytes out(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) out[i] = static_cast<std::byte>(raw[i]);
  return out;
}

inline std::string text_of(const Bytes& b) {
  return std::string(reinterpret_cast<const char*>(b.data()), b.size());
}

struct Drained {
  std::vector<Event> events;
  std::vector<Label> labels;
  std::vector<EventBatchPtr> batches;
};

inline Drained drain(EventSource& reader) {
  Drained d;
  while (auto b = reader.next()) {
    d.batches.push_back(b);
    d.events.insert(d.events.end(), b->events.begin(), b->events.end());
    d.labels.insert(d.labels.end(), b->labels.begin(), b->labels.end());
  }
  return d;
}

/// Collects the warnings of a reader (keep the object alive while the reader runs).
struct WarningLog {
  std::shared_ptr<std::vector<Warning>> items = std::make_shared<std::vector<Warning>>();
  [[nodiscard]] io::ReaderOptions attach(io::ReaderOptions o = {}) const {
    auto sink = items;
    o.on_warning = [sink](const Warning& w) { sink->push_back(w); };
    return o;
  }
  [[nodiscard]] bool any_contains(std::string_view needle) const {
    for (const auto& w : *items)
      if (w.message().find(needle) != std::string::npos) return true;
    return false;
  }
};

/// Returns the FormatError thrown while opening and draining `make(source)`, or nullopt.
template <typename Make>
std::optional<FormatError> read_error(Make make, const Bytes& data, io::ReaderOptions options = {},
                                      std::string name = "<memory>") {
  try {
    auto reader = make(io::memory_source(data, std::move(name)), std::move(options));
    drain(*reader);
  } catch (const FormatError& e) {
    return e;
  }
  return std::nullopt;
}

}  // namespace evpipe::testing
