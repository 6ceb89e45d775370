#pragma once
// Errors raised at boundaries (files, devices, configuration). Messages are complete sentences a user can
// act on: they name the file, the byte offset or field, and what was wrong.

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace evpipe {

class SourceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Malformed input: "<file>: byte <offset>: <what>".
class FormatError : public SourceError {
 public:
  FormatError(std::string file, std::optional<std::uint64_t> offset, const std::string& what);
  [[nodiscard]] const std::string& file() const noexcept { return file_; }
  [[nodiscard]] std::optional<std::uint64_t> offset() const noexcept { return offset_; }
  [[nodiscard]] const std::string& reason() const noexcept { return reason_; }

 private:
  std::string file_;
  std::optional<std::uint64_t> offset_;
  std::string reason_;
};

/// A recoverable problem reported by a source (the source goes on reading).
struct Warning {
  std::string file;
  std::optional<std::uint64_t> offset;
  std::string what;
  [[nodiscard]] std::string message() const;
};

}  // namespace evpipe
