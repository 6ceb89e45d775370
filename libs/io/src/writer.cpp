#include "evpipe/io/writer.hpp"

#include <algorithm>
#include <stdexcept>

#include "detail.hpp"

namespace evpipe::io {

std::unique_ptr<EventWriter> open_writer(const std::string& path, Format format, WriterOptions options) {
  switch (format) {
    case Format::text:
      return detail::make_text_writer(path, options);
    case Format::aedat4:
      return detail::make_aedat4_writer(path, options);
    case Format::aedat31:
      return detail::make_aedat31_writer(path, options);
    case Format::aedat2:
    case Format::unknown:
      break;
  }
  throw std::invalid_argument(path + ": evpipe writes AEDAT 4.0, AEDAT 3.1 and text, not " +
                              std::string(format_name(format)));
}

Format format_for_output(const std::string& path) {
  auto ends_with = [&](std::string_view suffix) {
    if (path.size() < suffix.size()) return false;
    return std::equal(suffix.rbegin(), suffix.rend(), path.rbegin(),
                      [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); });
  };
  if (ends_with(".aedat4")) return Format::aedat4;
  if (ends_with(".aedat3") || ends_with(".aedat31")) return Format::aedat31;
  if (ends_with(".txt") || ends_with(".csv")) return Format::text;
  throw std::invalid_argument(path + ": cannot tell the output format from the name (use .aedat4, .aedat3 or .txt)");
}

}  // namespace evpipe::io
