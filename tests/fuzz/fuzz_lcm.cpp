// libFuzzer target: what evpipe-lcm-echo and evpipe-view read. The input is taken (a) as one LCM message for the
// pose_t, stats_t and preview_t decoders and (b) as an LCM log file for the log reader, every event of which is
// decoded too. nullopt, DecodeError and LcmLogError / std::runtime_error are the expected answers to bad bytes; a
// crash, a leak, UB, a hang or an allocation beyond -rss_limit_mb (a count decoded before it was checked: a
// 153-byte stats_t once allocated 15 GB) is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/preview.hpp"

namespace {

void decode_all(const void* data, std::size_t size) {
  using namespace evpipe::transport;
  try {
    (void)decode_pose(data, size);
  } catch (const DecodeError&) {
  }
  try {
    (void)decode_stats(data, size);
  } catch (const DecodeError&) {
  }
  try {
    (void)decode_preview(data, size);
  } catch (const DecodeError&) {
  }
  (void)wire_error(data, size);
  (void)preview_wire_error(data, size);
}

// The log reader reads files: the input is written to one per process, removed at exit.
struct LogFile {
  std::string path =
      (std::filesystem::temp_directory_path() / ("evpipe-fuzz-lcm-" + std::to_string(::getpid()) + ".lcmlog")).string();
  ~LogFile() { std::remove(path.c_str()); }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  decode_all(data, size);
  static const LogFile log;
  std::FILE* f = std::fopen(log.path.c_str(), "wb");
  if (f == nullptr) return 0;
  const bool written = size == 0 || std::fwrite(data, 1, size, f) == size;
  if (std::fclose(f) != 0 || !written) return 0;
  try {
    evpipe::transport::read_lcm_log(
        log.path, [](evpipe::transport::ReceivedMessage&& m) { decode_all(m.data.data(), m.data.size()); });
  } catch (const std::runtime_error&) {  // LcmLogError (a bad event) or the file refused
  }
  return 0;
}
