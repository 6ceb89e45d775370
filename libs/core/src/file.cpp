#include "evpipe/core/file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <utility>

namespace evpipe {

FileError::FileError(std::string path, const std::string& reason)
    : SourceError(fmt::format("{}: {}", path, reason)), path_(std::move(path)), reason_(reason) {}

namespace {

const char* kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  return "not a regular file";
}

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(Fd&& o) noexcept : fd_(o.release()) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd& operator=(Fd&&) = delete;
  [[nodiscard]] int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

// Opens read-only without blocking (a FIFO without a writer) and checks that it is a regular file.
Fd open_regular(const std::string& path, struct stat& st) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY));
  if (fd.get() < 0) throw FileError(path, fmt::format("cannot open: {}", std::strerror(errno)));
  if (::fstat(fd.get(), &st) != 0) throw FileError(path, fmt::format("cannot examine: {}", std::strerror(errno)));
  if (!S_ISREG(st.st_mode)) throw FileError(path, fmt::format("is {}, not a regular file", kind_of(st.st_mode)));
  const int flags = ::fcntl(fd.get(), F_GETFL);
  if (flags >= 0) ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

UniqueFile to_stream(Fd& fd, const std::string& path, const char* mode) {
  std::FILE* f = ::fdopen(fd.get(), mode);
  if (f == nullptr) throw FileError(path, fmt::format("cannot open: {}", std::strerror(errno)));
  fd.release();
  return UniqueFile(f);
}

FileId id_of(const struct stat& st) {
  return {static_cast<std::uint64_t>(st.st_dev), static_cast<std::uint64_t>(st.st_ino)};
}

void check_not_input(const std::string& path, const FileId& out, std::span<const std::string> inputs) {
  for (const std::string& in : inputs) {
    if (in.empty()) continue;
    if (const auto id = file_id(in); id && *id == out) {
      throw FileError(path, in == path ? "is also an input of this program: refusing to overwrite it"
                                       : fmt::format("is the same file as the input {}: refusing to overwrite it", in));
    }
  }
}

void check_output_kind(const std::string& path, mode_t mode) {
  if (S_ISDIR(mode)) throw FileError(path, "is a directory, not a file to write");
  if (S_ISSOCK(mode) || S_ISBLK(mode)) throw FileError(path, fmt::format("is {}: not an output", kind_of(mode)));
}

}  // namespace

std::optional<FileId> file_id(const std::string& path) {
  struct stat st {};
  if (path.empty() || ::stat(path.c_str(), &st) != 0) return std::nullopt;
  return id_of(st);
}

UniqueFile open_input_file(const std::string& path) {
  struct stat st {};
  Fd fd = open_regular(path, st);
  return to_stream(fd, path, "rb");
}

void check_input_file(const std::string& path) {
  struct stat st {};
  (void)open_regular(path, st);
}

std::string read_small_file(const std::string& path, std::uint64_t max_bytes, const std::string& what) {
  struct stat st {};
  Fd fd = open_regular(path, st);
  const auto size = static_cast<std::uint64_t>(st.st_size);
  const auto too_big = [&](std::uint64_t n) {
    return FileError(path, fmt::format("file is {}{} bytes, more than the {} accepted for {}", n > size ? "over " : "",
                                       n, max_bytes, what));
  };
  if (size > max_bytes) throw too_big(size);
  std::string text(static_cast<std::size_t>(size), '\0');
  std::size_t done = 0;
  for (;;) {
    if (done == text.size()) {
      if (done > max_bytes) throw too_big(done);
      text.resize(std::min<std::size_t>(done + 4096, static_cast<std::size_t>(max_bytes) + 1));
      if (done == text.size()) throw too_big(done);
    }
    const ssize_t n = ::read(fd.get(), text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw FileError(path, fmt::format("byte {}: read error: {}", done, std::strerror(errno)));
    }
    if (n == 0) break;
    done += static_cast<std::size_t>(n);
  }
  if (done > max_bytes) throw too_big(done);
  text.resize(done);
  return text;
}

UniqueFile open_output_file(const std::string& path, std::span<const std::string> inputs) {
  // No O_TRUNC: the file is truncated only once it is known not to be an input.
  Fd fd(::open(path.c_str(), O_WRONLY | O_CREAT | O_NONBLOCK | O_CLOEXEC | O_NOCTTY, 0666));
  if (fd.get() < 0) {
    const int err = errno;
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) check_output_kind(path, st.st_mode);
    if (err == ENXIO) throw FileError(path, "is a FIFO that no process reads: cannot write to it");
    throw FileError(path, fmt::format("cannot create: {}", std::strerror(err)));
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) throw FileError(path, fmt::format("cannot examine: {}", std::strerror(errno)));
  check_output_kind(path, st.st_mode);
  check_not_input(path, id_of(st), inputs);
  if (S_ISREG(st.st_mode) && ::ftruncate(fd.get(), 0) != 0)
    throw FileError(path, fmt::format("cannot truncate: {}", std::strerror(errno)));
  const int flags = ::fcntl(fd.get(), F_GETFL);
  if (flags >= 0) ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK);
  return to_stream(fd, path, "wb");
}

void check_output_file(const std::string& path, std::span<const std::string> inputs) {
  struct stat st {};
  if (path.empty() || ::stat(path.c_str(), &st) != 0) return;  // created by the writer
  check_output_kind(path, st.st_mode);
  check_not_input(path, id_of(st), inputs);
}

}  // namespace evpipe
