#pragma once
// Byte input for readers. Readers take an injected ByteSource (a file, or memory for fuzzers and tests)
// and never load a whole file: they pull bounded chunks.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace evpipe::io {

class ByteSource {
 public:
  virtual ~ByteSource() = default;
  ByteSource() = default;
  ByteSource(const ByteSource&) = delete;
  ByteSource& operator=(const ByteSource&) = delete;

  /// Reads up to dst.size() bytes at the current position; returns the count (0 = end of input).
  virtual std::size_t read(std::span<std::byte> dst) = 0;
  /// Moves to an absolute offset; returns false when the source cannot seek there.
  virtual bool seek(std::uint64_t offset) = 0;
  [[nodiscard]] virtual std::uint64_t tell() const = 0;
  /// Total size in bytes, when known.
  [[nodiscard]] virtual std::optional<std::uint64_t> size() const = 0;
  /// Name used in messages (the path, or "<memory>").
  [[nodiscard]] virtual const std::string& name() const = 0;

  /// Reads exactly dst.size() bytes or returns false (position then at end of input).
  bool read_exact(std::span<std::byte> dst);
};

/// A regular file opened read-only (never blocks: a FIFO, directory or device is refused); throws
/// evpipe::SourceError (FileError) naming the path when it cannot be opened.
std::unique_ptr<ByteSource> open_file(const std::string& path);
/// A view of memory (not copied: the caller keeps it alive). For fuzzers and tests.
std::unique_ptr<ByteSource> memory_source(std::span<const std::byte> data, std::string name = "<memory>");
/// Owning variant.
std::unique_ptr<ByteSource> memory_source(std::vector<std::byte> data, std::string name = "<memory>");

}  // namespace evpipe::io
