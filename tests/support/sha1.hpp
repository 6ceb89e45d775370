#pragma once
// SHA-1 (FIPS 180-4) for test fingerprints, header-only. Not for security: it only compares decoded
// event streams with the golden fingerprints of formats.md §10.1.
//
//   evpipe::testing::sha1_hex(bytes)    -> 40 hex digits
//   evpipe::testing::fingerprint(events) -> first 12 hex digits of SHA-1 over all t as int64 LE, then all
//                                           x as int32 LE, all y as int32 LE, all (p > 0) as one byte
//                                           (the method of ../shared/data/real/verify.py)

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::testing {

class Sha1 {
 public:
  void update(std::span<const std::byte> data) {
    for (const std::byte b : data) {
      block_[fill_++] = static_cast<std::uint8_t>(b);
      if (fill_ == 64) {
        compress();
        fill_ = 0;
      }
    }
    length_bytes_ += data.size();
  }
  void update(std::string_view s) { update(std::as_bytes(std::span(s.data(), s.size()))); }

  /// Finishes the hash (the object is then spent) and returns 40 lowercase hex digits.
  std::string hex() {
    const std::uint64_t length_bits = length_bytes_ * 8;
    const std::uint8_t one = 0x80;
    update(std::as_bytes(std::span(&one, 1)));
    const std::uint8_t zero = 0;
    while (fill_ != 56) update(std::as_bytes(std::span(&zero, 1)));
    std::array<std::uint8_t, 8> len{};
    for (int i = 0; i < 8; ++i)
      len[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(length_bits >> (56 - 8 * i));
    update(std::as_bytes(std::span(len)));
    static constexpr char kHex[] = "0123456789abcdef";
    std::string out;
    for (const std::uint32_t word : h_)
      for (int shift = 28; shift >= 0; shift -= 4) out += kHex[(word >> shift) & 0xF];
    return out;
  }

 private:
  static std::uint32_t rotl(std::uint32_t v, int n) { return (v << n) | (v >> (32 - n)); }

  void compress() {
    std::array<std::uint32_t, 80> w{};
    for (std::size_t i = 0; i < 16; ++i)
      w[i] = (std::uint32_t{block_[4 * i]} << 24) | (std::uint32_t{block_[4 * i + 1]} << 16) |
             (std::uint32_t{block_[4 * i + 2]} << 8) | std::uint32_t{block_[4 * i + 3]};
    for (std::size_t i = 16; i < 80; ++i) w[i] = rotl(w[i - 3] ^ w[i - 8] ^ w[i - 14] ^ w[i - 16], 1);
    std::uint32_t a = h_[0], b = h_[1], c = h_[2], d = h_[3], e = h_[4];
    for (std::size_t i = 0; i < 80; ++i) {
      std::uint32_t f = 0;
      std::uint32_t k = 0;
      if (i < 20) {
        f = (b & c) | (~b & d);
        k = 0x5A827999;
      } else if (i < 40) {
        f = b ^ c ^ d;
        k = 0x6ED9EBA1;
      } else if (i < 60) {
        f = (b & c) | (b & d) | (c & d);
        k = 0x8F1BBCDC;
      } else {
        f = b ^ c ^ d;
        k = 0xCA62C1D6;
      }
      const std::uint32_t t = rotl(a, 5) + f + e + k + w[i];
      e = d;
      d = c;
      c = rotl(b, 30);
      b = a;
      a = t;
    }
    h_[0] += a;
    h_[1] += b;
    h_[2] += c;
    h_[3] += d;
    h_[4] += e;
  }

  std::array<std::uint32_t, 5> h_{0x67452301, 0xEFCDAB89, 0x98BADCFE, 0x10325476, 0xC3D2E1F0};
  std::array<std::uint8_t, 64> block_{};
  std::size_t fill_ = 0;
  std::uint64_t length_bytes_ = 0;
};

inline std::string sha1_hex(std::span<const std::byte> bytes) {
  Sha1 h;
  h.update(bytes);
  return h.hex();
}
inline std::string sha1_hex(std::string_view s) {
  return sha1_hex(std::as_bytes(std::span(s.data(), s.size())));
}

/// Golden-fingerprint method of formats.md §10.1 (raw coordinates, file order), first 12 hex digits.
inline std::string fingerprint(std::span<const Event> events) {
  Sha1 h;
  auto put = [&h](const auto value) {
    std::array<std::byte, sizeof(value)> le{};
    for (std::size_t i = 0; i < sizeof(value); ++i)
      le[i] = static_cast<std::byte>((static_cast<std::uint64_t>(value) >> (8 * i)) & 0xFF);
    h.update(le);
  };
  for (const Event& e : events) put(static_cast<std::int64_t>(e.t_us));
  for (const Event& e : events) put(static_cast<std::int32_t>(e.x));
  for (const Event& e : events) put(static_cast<std::int32_t>(e.y));
  for (const Event& e : events) put(static_cast<std::uint8_t>(e.polarity ? 1 : 0));
  return h.hex().substr(0, 12);
}
inline std::string fingerprint(const std::vector<Event>& events) {
  return fingerprint(std::span<const Event>(events));
}

}  // namespace evpipe::testing
