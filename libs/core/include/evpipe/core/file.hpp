#pragma once
// Opening the files a program reads and writes, one way for every program (docs/operations.md, "Files"):
//
// * Inputs are regular files only: a directory, FIFO, socket or device is refused with a message naming the path.
//   The open never blocks (O_NONBLOCK, cleared once the file is known to be regular), so a FIFO without a writer
//   cannot hang a program. There is no exception: the readers seek, so pipes and /dev/stdin could not work anyway.
// * Small text inputs (configurations, calibrations, models) are read whole with a size cap checked before
//   allocating, and again while reading (a file that grows).
// * An output is never one of the program's inputs: the same device and inode, after following links (a symbolic
//   or hard link of an input is refused), is refused BEFORE anything is truncated. Outputs may be regular files,
//   character devices (/dev/null) or FIFOs with a reader (opened without blocking: no reader = an error);
//   directories, sockets and block devices are refused.

#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "evpipe/core/error.hpp"

namespace evpipe {

/// A file that cannot be opened, read or written as required: "<path>: <reason>".
class FileError : public SourceError {
 public:
  FileError(std::string path, const std::string& reason);
  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  [[nodiscard]] const std::string& reason() const noexcept { return reason_; }

 private:
  std::string path_;
  std::string reason_;
};

/// Device and inode of a file (links followed).
struct FileId {
  std::uint64_t device = 0;
  std::uint64_t inode = 0;
  bool operator==(const FileId&) const = default;
};

/// The id of `path` (stat, links followed); nullopt when it does not exist or cannot be examined.
[[nodiscard]] std::optional<FileId> file_id(const std::string& path);

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f != nullptr) std::fclose(f);
  }
};
using UniqueFile = std::unique_ptr<std::FILE, FileCloser>;

/// Opens a regular file for reading ("rb"). @throws FileError "<path>: cannot open: <errno text>" or
/// "<path>: is a FIFO, not a regular file" (directory, socket, character/block device likewise).
[[nodiscard]] UniqueFile open_input_file(const std::string& path);

/// The checks of open_input_file() without keeping the file open, for code that opens by name itself (OpenCV,
/// std::ifstream, LCM's log reader).
void check_input_file(const std::string& path);

/// Reads a whole regular file of at most max_bytes (the size is checked before allocating).
/// @throws FileError as open_input_file(), or "<path>: file is N bytes, more than the M accepted for <what>".
[[nodiscard]] std::string read_small_file(const std::string& path, std::uint64_t max_bytes,
                                          const std::string& what = "this kind of file");

/// Creates (or truncates) an output file for writing ("wb"), after checking that it is none of `inputs` (same
/// device and inode, links followed; empty entries are skipped): nothing is truncated when the check fails.
/// @throws FileError "<path>: is the same file as the input <input>: refusing to overwrite it",
///         "<path>: cannot create: <errno text>", "<path>: is a directory, not a file to write".
[[nodiscard]] UniqueFile open_output_file(const std::string& path, std::span<const std::string> inputs = {});

/// The output checks of open_output_file() without opening, for outputs written by other code (OpenCV images, the
/// LCM log): `path` (when it exists) must not be one of `inputs`, nor a directory, socket or block device.
void check_output_file(const std::string& path, std::span<const std::string> inputs);

}  // namespace evpipe
