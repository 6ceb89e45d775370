// Text writer: `# width=W height=H`, then one `t x y p [label]` line per event (t integer µs, p 0/1,
// label 1 = signal / 0 = noise), formatted with fmt into a buffer flushed in large writes.

#include <fmt/format.h>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "detail.hpp"

namespace evpipe::io::detail {

namespace {

constexpr std::size_t kFlushBytes = std::size_t{1} << 20;

class TextWriter final : public EventWriter {
 public:
  TextWriter(const std::string& path, const WriterOptions& options)
      : path_(path), options_(options), out_(path, options.inputs) {
    fmt::format_to(std::back_inserter(buf_), "# width={} height={}\n", options_.geometry.width,
                   options_.geometry.height);
  }

  ~TextWriter() override {
    try {
      close();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; call close() to see errors
    }
  }

  void write(EventSpan events, std::span<const Label> labels) override {
    if (!out_.is_open()) throw SourceError(path_ + ": write after close");
    if (!labels.empty() && labels.size() != events.size())
      throw std::invalid_argument(fmt::format("{}: {} labels for {} events", path_, labels.size(), events.size()));
    if (events.empty()) return;
    // The reader needs the same column count on every line: the first events written decide.
    const bool with_labels = options_.write_labels && !labels.empty();
    if (!labelled_) labelled_ = with_labels;
    if (*labelled_ != with_labels)
      throw std::invalid_argument(
          fmt::format("{}: events {} labels after events {} them (every line of a text "
                      "file needs the same columns)",
                      path_, with_labels ? "with" : "without", *labelled_ ? "with" : "without"));
    auto out = std::back_inserter(buf_);
    for (std::size_t i = 0; i < events.size(); ++i) {
      const Event& e = events[i];
      check_in_sensor(path_, options_.geometry, e);
      if (with_labels) {
        fmt::format_to(out, "{} {} {} {} {}\n", e.t_us, e.x, e.y, e.polarity ? 1 : 0,
                       labels[i] == Label::signal ? 1 : 0);
      } else {
        fmt::format_to(out, "{} {} {} {}\n", e.t_us, e.x, e.y, e.polarity ? 1 : 0);
      }
      if (buf_.size() >= kFlushBytes) flush();
    }
  }

  void close() override {
    if (!out_.is_open()) return;
    flush();
    out_.close();
  }

 private:
  void flush() {
    out_.write(buf_.data(), buf_.size());
    buf_.clear();
  }

  std::string path_;
  WriterOptions options_;
  OutputFile out_;
  fmt::memory_buffer buf_;
  std::optional<bool> labelled_;
};

}  // namespace

std::unique_ptr<EventWriter> make_text_writer(const std::string& path, const WriterOptions& options) {
  return std::make_unique<TextWriter>(path, options);
}

}  // namespace evpipe::io::detail
