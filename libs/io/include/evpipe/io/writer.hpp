#pragma once
// Event file writers: AEDAT 4.0 (LZ4; read back identically by dv-processing and the `aedat` package),
// AEDAT 3.1 (cAER packets; used to make 3.1 fixtures), and text (`t x y p [label]`).

#include <memory>
#include <string>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/io/reader.hpp"

namespace evpipe::io {

struct WriterOptions {
  SensorGeometry geometry = kDavis346;
  /// AEDAT 4.0: events per packet; AEDAT 3.1: events per packet.
  std::size_t packet_events = 4096;
  /// AEDAT 4.0: the `source` attribute of the event stream.
  std::string source_name = "evpipe";
  /// Text: write the fifth (label) column when labels are given.
  bool write_labels = true;
  /// AEDAT 4.0 compression: "lz4" (default), "zstd" or "none".
  std::string compression = "lz4";
  /// The program's input files: the output must not be one of them (same device and inode, links followed);
  /// open_writer() then throws SourceError before truncating anything (evpipe/core/file.hpp).
  std::vector<std::string> inputs;
};

class EventWriter {
 public:
  virtual ~EventWriter() = default;
  EventWriter() = default;
  EventWriter(const EventWriter&) = delete;
  EventWriter& operator=(const EventWriter&) = delete;

  /// Appends events (time-ordered within the file). `labels` is empty or one per event.
  virtual void write(EventSpan events, std::span<const Label> labels = {}) = 0;
  /// Flushes and finalises the file (AEDAT 4.0: the file data table). Call it explicitly: it throws
  /// evpipe::SourceError on I/O failure. A writer destroyed without close() (an interrupted program) still
  /// flushes the events written so far, but an AEDAT 4.0 file then has no data table
  /// (dataTablePosition = -1), which evpipe and the other readers handle.
  virtual void close() = 0;
};

/// Writer for `path` in the given format (text, aedat4 or aedat31). Throws SourceError if it cannot
/// create the file, std::invalid_argument for an unsupported format.
std::unique_ptr<EventWriter> open_writer(const std::string& path, Format format, WriterOptions options = {});
/// Format from the output file name: `.aedat4` → aedat4, `.aedat3` / `.aedat31` → aedat31, `.txt`/`.csv` →
/// text. Throws std::invalid_argument naming the path otherwise.
Format format_for_output(const std::string& path);

}  // namespace evpipe::io
