#pragma once
// LCM's wire encoding walked without allocating (big-endian numbers; a string = an int32 length counting its NUL,
// then the bytes): the decoders of codec.cpp and preview.cpp walk a message's layout with it before the generated
// decode() runs, because that code resizes an array to the count it has just read before checking that the bytes
// are there. Every length and count is bounded by the bytes left; a failure throws WireError naming
// "<type>.<field> at byte <N> of <size>".

#include <fmt/format.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace evpipe::transport::detail {

class WireError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class WireWalker {
 public:
  WireWalker(std::string_view type, const void* data, std::size_t size)
      : type_(type), p_(static_cast<const std::uint8_t*>(data)), size_(size) {}

  [[nodiscard]] std::size_t pos() const noexcept { return pos_; }
  [[nodiscard]] std::size_t left() const noexcept { return size_ - pos_; }

  /// The 8-byte fingerprint; false when it is not `hash` (another type: nothing to say about it).
  bool fingerprint(std::int64_t hash) {
    if (left() < 8) return false;
    const auto v = static_cast<std::int64_t>(be(pos_, 8));
    pos_ += 8;
    return v == hash;
  }

  /// A field of `bytes` fixed bytes (numbers, fixed-size arrays). A field of an array element is named by the
  /// array, the index and the member ("stages", 2, ".name"); the name is only formatted for an error.
  void fixed(std::string_view field, std::size_t bytes, std::int32_t index = -1, std::string_view member = {}) {
    if (bytes > left()) {
      fail(name(field, index, member), fmt::format("{} bytes needed, {} left (truncated)", bytes, left()));
    }
    pos_ += bytes;
  }

  void string(std::string_view field, std::int32_t index = -1, std::string_view member = {}) {
    const std::size_t at = pos_;
    const std::int32_t n = i32(field, index, member);
    if (n < 1) {
      fail(name(field, index, member), fmt::format("string length {} (at least 1: LCM counts the NUL)", n), at);
    }
    if (static_cast<std::size_t>(n) > left()) {
      fail(name(field, index, member), fmt::format("string length {} but {} bytes left", n, left()), at);
    }
    pos_ += static_cast<std::size_t>(n);
  }

  /// An array count whose elements take at least `min_element_bytes` each: refused when negative or when that
  /// many elements cannot fit in the bytes left.
  std::int32_t count(std::string_view field, std::size_t min_element_bytes) {
    const std::size_t at = pos_;
    const std::int32_t n = i32(field);
    if (n < 0) fail(field, fmt::format("negative count {}", n), at);
    if (static_cast<std::size_t>(n) > left() / min_element_bytes) {
      fail(field,
           fmt::format("count {} needs at least {} bytes ({} per entry), {} left", n,
                       static_cast<std::uint64_t>(n) * min_element_bytes, min_element_bytes, left()),
           at);
    }
    return n;
  }

 private:
  [[nodiscard]] std::uint64_t be(std::size_t at, std::size_t bytes) const {
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < bytes; ++i) v = (v << 8) | p_[at + i];
    return v;
  }

  static std::string name(std::string_view field, std::int32_t index, std::string_view member) {
    return index < 0 ? std::string(field) : fmt::format("{}[{}]{}", field, index, member);
  }

  std::int32_t i32(std::string_view field, std::int32_t index = -1, std::string_view member = {}) {
    const std::size_t at = pos_;
    fixed(field, 4, index, member);
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(be(at, 4)));
  }

  [[noreturn]] void fail(std::string_view field, const std::string& why) const { fail(field, why, pos_); }
  [[noreturn]] void fail(std::string_view field, const std::string& why, std::size_t at) const {
    throw WireError(fmt::format("{}.{} at byte {} of {}: {}", type_, field, at, size_, why));
  }

  std::string_view type_;
  const std::uint8_t* p_;
  std::size_t size_;
  std::size_t pos_{0};
};

/// Why bytes carrying fingerprint `hash` are not a whole `type` message, as `walk(WireWalker&)` lays it out; nullopt
/// when they are whole, or carry another fingerprint (or fewer than 8 bytes).
template <typename Walk>
std::optional<std::string> walk_error(std::string_view type, std::int64_t hash, const void* data, std::size_t size,
                                      Walk&& walk) {
  if (data == nullptr) return std::nullopt;
  WireWalker w(type, data, size);
  if (!w.fingerprint(hash)) return std::nullopt;
  try {
    walk(w);
  } catch (const WireError& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

}  // namespace evpipe::transport::detail
