// evconvert IN OUT: converts an event recording between formats. The input format is found from the
// content; the output format from OUT's extension (.aedat4, .aedat3, .txt). Events are copied unchanged and
// in input order (out-of-order timestamps are kept and counted), labels are kept for text output.
// Exit status: 0 success, 1 input/output error, 2 usage error.

#include <fmt/format.h>
#include <cstdio>

#include "evpipe/cli/cli.hpp"
#include "evpipe/core/error.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"

int main(int argc, char** argv) {
  std::string in_path;
  std::string out_path;
  std::string compression = "lz4";
  bool quiet = false;
  evpipe::cli::App app{"evconvert: convert event recordings (AEDAT 2.0/3.1/4.0, text) to AEDAT 4.0, AEDAT 3.1 or text"};
  app.add_option("IN", in_path, "Input recording (format detected from content)")->required();
  app.add_option("OUT", out_path, "Output file: .aedat4, .aedat3 or .txt")->required();
  app.add_option("--compression", compression, "AEDAT 4.0 packet compression")
      ->check(evpipe::cli::is_member({"lz4", "zstd", "none"}));
  app.add_flag("-q,--quiet", quiet, "No summary line");
  if (const auto status = app.parse(argc, argv)) return *status;

  evpipe::io::Format out_format{};
  try {
    out_format = evpipe::io::format_for_output(out_path);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "evconvert: %s\n", e.what());
    return 2;
  }
  std::uint64_t warnings = 0;
  evpipe::io::ReaderOptions ropt;
  ropt.out_of_order = evpipe::io::OutOfOrderPolicy::keep;
  ropt.on_warning = [&warnings](const evpipe::Warning& w) {
    if (++warnings <= 20) std::fprintf(stderr, "evconvert: warning: %s\n", w.message().c_str());
  };
  try {
    auto reader = evpipe::io::open_reader(in_path, ropt);
    evpipe::io::WriterOptions wopt;
    wopt.geometry = reader->info().geometry;
    wopt.compression = compression;
    wopt.inputs = {in_path};  // `evconvert IN IN` (or a link of IN) is refused before IN is truncated
    auto writer = evpipe::io::open_writer(out_path, out_format, wopt);
    while (auto batch = reader->next()) writer->write(batch->span(), batch->labels);
    writer->close();
    const auto& st = reader->stats();
    if (!quiet)
      std::printf("%s (%s, %dx%d): %llu events -> %s (%s)%s\n", in_path.c_str(), reader->info().format.c_str(),
                  reader->info().geometry.width, reader->info().geometry.height,
                  static_cast<unsigned long long>(st.events), out_path.c_str(),
                  std::string(evpipe::io::format_name(out_format)).c_str(),
                  warnings ? fmt::format(", {} warning(s)", warnings).c_str() : "");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evconvert: %s\n", e.what());
    return 1;
  }
  return 0;
}
