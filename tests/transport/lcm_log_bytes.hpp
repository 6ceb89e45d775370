#pragma once
// Hand-made LCM log files and messages for the tests of bad input (test_wire.cpp, test_echo.cpp): an event is a
// 28-byte big-endian header (sync word 0xEDA1DA01, event number, timestamp, channel length, data length), then the
// channel name and the data. The lengths can be overridden to write corrupt events.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace evpipe::testing {

inline void put_be(std::vector<std::uint8_t>& out, std::uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

/// Overwrites the big-endian int32 at `at` (an LCM count or length inside a message).
inline void set_be32(std::vector<std::uint8_t>& bytes, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) bytes.at(at + static_cast<std::size_t>(i)) = static_cast<std::uint8_t>(v >> (24 - 8 * i));
}

/// One log event; `channel_len` / `data_len` replace the true lengths in the header (the bytes written stay).
inline std::vector<std::uint8_t> lcm_event(const std::string& channel, const std::vector<std::uint8_t>& data,
                                           std::int64_t number = 0, std::optional<std::uint32_t> channel_len = {},
                                           std::optional<std::uint32_t> data_len = {}) {
  std::vector<std::uint8_t> out;
  put_be(out, 0xEDA1DA01U, 4);
  put_be(out, static_cast<std::uint64_t>(number), 8);
  put_be(out, static_cast<std::uint64_t>(1'700'000'000'000'000 + number), 8);
  put_be(out, channel_len.value_or(static_cast<std::uint32_t>(channel.size())), 4);
  put_be(out, data_len.value_or(static_cast<std::uint32_t>(data.size())), 4);
  out.insert(out.end(), channel.begin(), channel.end());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

inline void write_bytes(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

inline std::vector<std::uint8_t> concat(std::initializer_list<std::vector<std::uint8_t>> parts) {
  std::vector<std::uint8_t> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

}  // namespace evpipe::testing
