#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "detail.hpp"
#include "evpipe/core/file.hpp"

namespace evpipe::io::detail {

OutputFile::OutputFile(std::string path, std::span<const std::string> inputs) : path_(std::move(path)) {
  file_ = open_output_file(path_, inputs).release();
}

OutputFile::~OutputFile() {
  if (file_ != nullptr) std::fclose(file_);
}

void OutputFile::fail(const char* what, int err) {
  if (file_ != nullptr) std::fclose(file_);
  file_ = nullptr;
  throw SourceError(fmt::format("{}: byte {}: {}: {}", path_, pos_, what, std::strerror(err)));
}

void OutputFile::write(const void* data, std::size_t n) {
  if (file_ == nullptr) throw SourceError(fmt::format("{}: write after close", path_));
  if (n > 0 && std::fwrite(data, 1, n, file_) != n) fail("write failed", errno);
  pos_ += n;
}

void OutputFile::seek(std::uint64_t offset) {
  if (file_ == nullptr) throw SourceError(fmt::format("{}: seek after close", path_));
  if (fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0) fail("cannot seek", errno);
  pos_ = offset;
}

void OutputFile::close() {
  if (file_ == nullptr) return;
  std::FILE* f = file_;
  file_ = nullptr;
  const bool write_failed = std::ferror(f) != 0;
  const int close_status = std::fclose(f);
  const int err = errno;
  if (write_failed || close_status != 0)
    throw SourceError(fmt::format("{}: byte {}: write failed: {}", path_, pos_, std::strerror(err)));
}

void check_in_sensor(const std::string& path, const SensorGeometry& geometry, const Event& e) {
  if (!geometry.contains(e.x, e.y))
    throw std::invalid_argument(fmt::format("{}: event at t={} us, x={} y={} is outside the {}x{} sensor", path, e.t_us,
                                            e.x, e.y, geometry.width, geometry.height));
}

}  // namespace evpipe::io::detail
