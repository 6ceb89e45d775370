// AEDAT 4.0 writer (formats.md §5.6): magic, size-prefixed IOHeader, packets of size-prefixed EVTS
// flatbuffers each compressed as one LZ4 frame (or zstd / none), then the compressed FTAB data table,
// and finally data_table_position patched in the IOHeader. A writer destroyed without close() flushes
// its buffered events but writes no table: data_table_position stays -1, as in an interrupted DV
// recording, and readers still read every packet.

#include <lz4frame.h>
#include <zstd.h>

#include <fmt/format.h>
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "aedat4_events_generated.h"
#include "aedat4_generated.h"
#include "aedat4_table_generated.h"
#include "detail.hpp"

namespace evpipe::io::detail {
namespace {

constexpr std::string_view kMagic = "#!AER-DAT4.0\r\n";
constexpr std::int32_t kEventStreamId = 0;

std::string xml_escape(std::string_view s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

/// The infoNode of DV recordings, reduced to one event stream.
std::string info_node(const WriterOptions& options, std::string_view compression_name) {
  constexpr std::string_view kPath = "/mainloop/Recorder/outInfo/";
  return fmt::format(
      "<dv version=\"2.0\">\n"
      "    <node name=\"outInfo\" path=\"{0}\">\n"
      "        <node name=\"0\" path=\"{0}0/\">\n"
      "            <attr key=\"compression\" type=\"string\">{1}</attr>\n"
      "            <attr key=\"originalModuleName\" type=\"string\">evpipe</attr>\n"
      "            <attr key=\"originalOutputName\" type=\"string\">events</attr>\n"
      "            <attr key=\"typeDescription\" type=\"string\">Array of events (polarity ON/OFF).</attr>\n"
      "            <attr key=\"typeIdentifier\" type=\"string\">EVTS</attr>\n"
      "            <node name=\"info\" path=\"{0}0/info/\">\n"
      "                <attr key=\"sizeX\" type=\"int\">{2}</attr>\n"
      "                <attr key=\"sizeY\" type=\"int\">{3}</attr>\n"
      "                <attr key=\"source\" type=\"string\">{4}</attr>\n"
      "                <attr key=\"tsOffset\" type=\"long\">0</attr>\n"
      "            </node>\n"
      "        </node>\n"
      "    </node>\n"
      "</dv>\n",
      kPath, compression_name, options.geometry.width, options.geometry.height, xml_escape(options.source_name));
}

struct TableEntry {
  std::int64_t payload_at;
  std::int32_t stored_bytes;
  std::int64_t events;
  std::int64_t t_first_us;
  std::int64_t t_last_us;
};

class Aedat4Writer final : public EventWriter {
 public:
  Aedat4Writer(const std::string& path, const WriterOptions& options)
      : path_(path), options_(options), packet_events_(std::max<std::size_t>(1, options.packet_events)) {
    std::string name;
    for (const char c : options.compression) name += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    std::string_view xml_name;
    if (name == "lz4") {
      compression_ = fb::CompressionType::LZ4;
      xml_name = "LZ4";
    } else if (name == "zstd") {
      compression_ = fb::CompressionType::ZSTD;
      xml_name = "ZSTD";
    } else if (name == "none") {
      compression_ = fb::CompressionType::NONE;
      xml_name = "NONE";
    } else {
      throw std::invalid_argument(
          fmt::format("{}: unknown AEDAT 4.0 compression '{}' (use lz4, zstd or none)", path, options.compression));
    }
    // Coordinates are int16 in the file.
    if (options.geometry.width <= 0 || options.geometry.height <= 0 || options.geometry.width > kMaxSensorSide ||
        options.geometry.height > kMaxSensorSide)
      throw std::invalid_argument(fmt::format("{}: sensor size {}x{} cannot be written to AEDAT 4.0", path,
                                              options.geometry.width, options.geometry.height));

    out_ = std::make_unique<OutputFile>(path, options.inputs);

    // force_defaults: data_table_position = -1 gets a slot that close() can patch in place.
    flatbuffers::FlatBufferBuilder fbb(4096);
    fbb.ForceDefaults(true);
    const auto xml = fbb.CreateString(info_node(options, xml_name));
    fb::FinishSizePrefixedIOHeaderBuffer(fbb, fb::CreateIOHeader(fbb, compression_, -1, xml));
    header_.assign(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
    put(kMagic.data(), kMagic.size());
    put(header_.data(), header_.size());
    pending_.reserve(packet_events_);
  }

  ~Aedat4Writer() override {
    if (!out_ || !out_->is_open()) return;
    try {
      flush_packet();  // keep the events; no table (as an interrupted recording)
    } catch (...) {    // NOLINT(bugprone-empty-catch): destructors must not throw; close() reports errors
    }
  }

  void write(EventSpan events, std::span<const Label> /*labels: AEDAT 4.0 has no label field*/) override {
    if (!out_->is_open()) throw SourceError(fmt::format("{}: write after close()", path_));
    for (const Event& e : events) {
      check_in_sensor(path_, options_.geometry, e);
      pending_.emplace_back(e.t_us, static_cast<std::int16_t>(e.x), static_cast<std::int16_t>(e.y), e.polarity);
      if (pending_.size() >= packet_events_) flush_packet();
    }
  }

  void close() override {
    if (!out_->is_open()) return;
    flush_packet();
    const auto table_at = static_cast<std::int64_t>(out_->tell());
    write_table();
    // Patch the IOHeader copy and rewrite it in place (same size: the slot exists).
    if (!fb::GetMutableSizePrefixedIOHeader(header_.data())->mutate_data_table_position(table_at))
      throw SourceError(fmt::format("{}: internal error: IOHeader has no data_table_position slot", path_));
    out_->seek(kMagic.size());
    put(header_.data(), header_.size());
    out_->close();
  }

 private:
  void put(const void* data, std::size_t n) { out_->write(data, n); }

  /// Compresses `raw` (one size-prefixed flatbuffer) into compressed_, or returns it unchanged.
  std::span<const std::uint8_t> compress(std::span<const std::uint8_t> raw) {
    switch (compression_) {
      case fb::CompressionType::LZ4:
      case fb::CompressionType::LZ4_HIGH: {
        LZ4F_preferences_t prefs{};
        prefs.frameInfo.contentSize = raw.size();
        // a content checksum lets readers detect a damaged packet instead of decoding wrong events
        prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
        compressed_.resize(LZ4F_compressFrameBound(raw.size(), &prefs));
        const std::size_t n =
            LZ4F_compressFrame(compressed_.data(), compressed_.size(), raw.data(), raw.size(), &prefs);
        if (LZ4F_isError(n))
          throw SourceError(fmt::format("{}: LZ4 compression failed: {}", path_, LZ4F_getErrorName(n)));
        return {compressed_.data(), n};
      }
      case fb::CompressionType::ZSTD:
      case fb::CompressionType::ZSTD_HIGH: {
        compressed_.resize(ZSTD_compressBound(raw.size()));
        const std::size_t n =
            ZSTD_compress(compressed_.data(), compressed_.size(), raw.data(), raw.size(), ZSTD_CLEVEL_DEFAULT);
        if (ZSTD_isError(n))
          throw SourceError(fmt::format("{}: zstd compression failed: {}", path_, ZSTD_getErrorName(n)));
        return {compressed_.data(), n};
      }
      case fb::CompressionType::NONE:
        break;
    }
    return raw;
  }

  void flush_packet() {
    if (pending_.empty()) return;
    fbb_.Clear();
    const auto elements = fbb_.CreateVectorOfStructs(pending_.data(), pending_.size());
    fb::FinishSizePrefixedEventPacketBuffer(fbb_, fb::CreateEventPacket(fbb_, elements));
    const auto stored = compress({fbb_.GetBufferPointer(), fbb_.GetSize()});
    if (stored.size() > static_cast<std::size_t>(INT32_MAX))
      throw SourceError(fmt::format("{}: packet of {} bytes is too large", path_, stored.size()));

    std::array<std::uint8_t, 8> header{};
    const std::int32_t stream = kEventStreamId;
    const auto size = static_cast<std::int32_t>(stored.size());
    std::memcpy(header.data(), &stream, 4);  // little-endian targets only (see detail::load_le)
    std::memcpy(header.data() + 4, &size, 4);
    put(header.data(), header.size());
    table_.push_back(TableEntry{static_cast<std::int64_t>(out_->tell()), size,
                                static_cast<std::int64_t>(pending_.size()), pending_.front().timestamp(),
                                pending_.back().timestamp()});
    put(stored.data(), stored.size());
    pending_.clear();
  }

  void write_table() {
    fbb_.Clear();
    std::vector<flatbuffers::Offset<fb::FileDataDefinition>> entries;
    entries.reserve(table_.size());
    for (const TableEntry& t : table_) {
      const fb::PacketHeader info(kEventStreamId, t.stored_bytes);
      entries.push_back(fb::CreateFileDataDefinition(fbb_, t.payload_at, &info, t.events, t.t_first_us, t.t_last_us));
    }
    const auto vec = fbb_.CreateVector(entries);
    fb::FinishSizePrefixedFileDataTableBuffer(fbb_, fb::CreateFileDataTable(fbb_, vec));
    const auto stored = compress({fbb_.GetBufferPointer(), fbb_.GetSize()});
    put(stored.data(), stored.size());
  }

  std::string path_;
  WriterOptions options_;
  std::size_t packet_events_;
  fb::CompressionType compression_ = fb::CompressionType::LZ4;
  std::unique_ptr<OutputFile> out_;   // created after the options are checked
  std::vector<std::uint8_t> header_;  // the size-prefixed IOHeader as written
  std::vector<fb::Event> pending_;
  std::vector<TableEntry> table_;
  flatbuffers::FlatBufferBuilder fbb_{1 << 16};
  std::vector<std::uint8_t> compressed_;
};

}  // namespace

std::unique_ptr<EventWriter> make_aedat4_writer(const std::string& path, const WriterOptions& options) {
  return std::make_unique<Aedat4Writer>(path, options);
}

}  // namespace evpipe::io::detail
