#include "evpipe/io/byte_source.hpp"

#include <fmt/format.h>
#include <cerrno>
#include <cstring>

#include "evpipe/core/error.hpp"
#include "evpipe/core/file.hpp"

namespace evpipe::io {

bool ByteSource::read_exact(std::span<std::byte> dst) {
  std::size_t done = 0;
  while (done < dst.size()) {
    const std::size_t n = read(dst.subspan(done));
    if (n == 0) return false;
    done += n;
  }
  return true;
}

namespace {

class FileSource final : public ByteSource {
 public:
  FileSource(std::FILE* f, std::string path) : file_(f), path_(std::move(path)) {
    if (std::fseek(file_, 0, SEEK_END) == 0) {
      const long end = std::ftell(file_);
      if (end >= 0) size_ = static_cast<std::uint64_t>(end);
    }
    std::fseek(file_, 0, SEEK_SET);
  }
  ~FileSource() override { std::fclose(file_); }

  std::size_t read(std::span<std::byte> dst) override {
    const std::size_t n = std::fread(dst.data(), 1, dst.size(), file_);
    if (n < dst.size() && std::ferror(file_))
      throw SourceError(fmt::format("{}: byte {}: read error: {}", path_, pos_, std::strerror(errno)));
    pos_ += n;
    return n;
  }
  bool seek(std::uint64_t offset) override {
    if (size_ && offset > *size_) return false;
    if (fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0) return false;
    pos_ = offset;
    return true;
  }
  [[nodiscard]] std::uint64_t tell() const override { return pos_; }
  [[nodiscard]] std::optional<std::uint64_t> size() const override { return size_; }
  [[nodiscard]] const std::string& name() const override { return path_; }

 private:
  std::FILE* file_;
  std::string path_;
  std::uint64_t pos_ = 0;
  std::optional<std::uint64_t> size_;
};

class MemorySource final : public ByteSource {
 public:
  MemorySource(std::span<const std::byte> view, std::vector<std::byte> owned, std::string name)
      : owned_(std::move(owned)),
        data_(owned_.empty() ? view : std::span<const std::byte>(owned_)),
        name_(std::move(name)) {}

  std::size_t read(std::span<std::byte> dst) override {
    const std::size_t n = std::min<std::size_t>(dst.size(), data_.size() - pos_);
    if (n > 0) std::memcpy(dst.data(), data_.data() + pos_, n);
    pos_ += n;
    return n;
  }
  bool seek(std::uint64_t offset) override {
    if (offset > data_.size()) return false;
    pos_ = static_cast<std::size_t>(offset);
    return true;
  }
  [[nodiscard]] std::uint64_t tell() const override { return pos_; }
  [[nodiscard]] std::optional<std::uint64_t> size() const override { return data_.size(); }
  [[nodiscard]] const std::string& name() const override { return name_; }

 private:
  std::vector<std::byte> owned_;
  std::span<const std::byte> data_;
  std::string name_;
  std::size_t pos_ = 0;
};

}  // namespace

std::unique_ptr<ByteSource> open_file(const std::string& path) {
  return std::make_unique<FileSource>(open_input_file(path).release(), path);
}

std::unique_ptr<ByteSource> memory_source(std::span<const std::byte> data, std::string name) {
  return std::make_unique<MemorySource>(data, std::vector<std::byte>{}, std::move(name));
}

std::unique_ptr<ByteSource> memory_source(std::vector<std::byte> data, std::string name) {
  return std::make_unique<MemorySource>(std::span<const std::byte>{}, std::move(data), std::move(name));
}

}  // namespace evpipe::io
