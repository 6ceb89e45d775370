#include <fmt/format.h>

#include "evpipe/core/error.hpp"

namespace evpipe {

namespace {
std::string locate(const std::string& file, std::optional<std::uint64_t> offset, const std::string& what) {
  if (offset) return fmt::format("{}: byte {}: {}", file, *offset, what);
  return fmt::format("{}: {}", file, what);
}
}  // namespace

FormatError::FormatError(std::string file, std::optional<std::uint64_t> offset, const std::string& what)
    : SourceError(locate(file, offset, what)), file_(std::move(file)), offset_(offset), reason_(what) {}

std::string Warning::message() const {
  return locate(file, offset, what);
}

}  // namespace evpipe
