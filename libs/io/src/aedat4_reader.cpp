// AEDAT 4.0 reader (DV / dv-processing files). Layout: formats.md §5.
//
//   "#!AER-DAT4.0\r\n" | uint32 N | IOHeader flatbuffer (N bytes, "IOHE")
//   { PacketHeader {int32 streamId; int32 size} | size bytes: compress(size-prefixed flatbuffer) }*
//   [ file data table at IOHeader.data_table_position ]
//
// Packets are read sequentially; the data table is never needed (files from other writers carry
// incomplete tables, interrupted recordings none at all). Memory stays bounded: one stored and one
// decompressed packet at a time, both capped before allocation.

#include <lz4frame.h>
#include <zstd.h>

#include <fmt/format.h>
#include <algorithm>
#include <charconv>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "aedat4_events_generated.h"
#include "aedat4_generated.h"
#include "detail.hpp"

namespace evpipe::io {
namespace {

constexpr std::string_view kMagic = "#!AER-DAT4.0\r\n";
constexpr std::uint64_t kHeaderStart = kMagic.size();          // the IOHeader size prefix
constexpr std::uint64_t kMaxHeaderBytes = 64ull << 20;         // IOHeader (mostly XML): far below this
constexpr std::uint64_t kMaxStoredPacketBytes = 256ull << 20;  // one packet as stored in the file
constexpr std::uint64_t kMaxDecodedPacketBytes = 1ull << 30;   // one packet after decompression
constexpr std::size_t kPacketHeaderBytes = 8;
constexpr std::size_t kReadAheadBytes = std::size_t{1} << 20;
constexpr std::uint64_t kMaxCorruptWarnings = 20;

// ----------------------------------------------------------------------------------------------------
// infoNode XML: DV writes <dv><node name="outInfo"><node name="<id>"> <attr key=.. type=..>value</attr>
// ... <node name="info"> sizeX, sizeY, source, tsOffset </node></node>...</node></dv>. A full XML parser
// is not needed: we track the stack of node names and read the attr elements.

struct StreamDecl {
  int id = -1;
  std::string type_identifier;
  int size_x = 0;
  int size_y = 0;
  std::string source;
};

std::string xml_unescape(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '&') {
      out += s[i];
      continue;
    }
    static constexpr std::pair<std::string_view, char> kEntities[] = {
        {"&amp;", '&'}, {"&lt;", '<'}, {"&gt;", '>'}, {"&quot;", '"'}, {"&apos;", '\''}};
    bool done = false;
    for (const auto& [name, c] : kEntities) {
      if (s.substr(i, name.size()) == name) {
        out += c;
        i += name.size() - 1;
        done = true;
        break;
      }
    }
    if (!done) out += '&';
  }
  return out;
}

/// Value of `key="..."` inside a start tag, or nullopt.
std::optional<std::string_view> tag_attribute(std::string_view tag, std::string_view key) {
  std::size_t from = 0;
  while (true) {
    const auto at = tag.find(key, from);
    if (at == std::string_view::npos) return std::nullopt;
    from = at + key.size();
    // must be a whole attribute name: preceded by whitespace, followed by ="
    if (at == 0 || (tag[at - 1] != ' ' && tag[at - 1] != '\t' && tag[at - 1] != '\n' && tag[at - 1] != '\r')) continue;
    std::size_t p = from;
    while (p < tag.size() && (tag[p] == ' ' || tag[p] == '\t')) ++p;
    if (p >= tag.size() || tag[p] != '=') continue;
    ++p;
    while (p < tag.size() && (tag[p] == ' ' || tag[p] == '\t')) ++p;
    if (p >= tag.size() || (tag[p] != '"' && tag[p] != '\'')) continue;
    const char quote = tag[p];
    const auto end = tag.find(quote, p + 1);
    if (end == std::string_view::npos) return std::nullopt;
    return tag.substr(p + 1, end - p - 1);
  }
}

std::optional<int> parse_int(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\n' || s.front() == '\r' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\n' || s.back() == '\r' || s.back() == '\t'))
    s.remove_suffix(1);
  int v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

/// The streams declared in the infoNode (a stream is a <node> with a numeric name; its <node name="info">
/// child carries the size). Unknown elements are ignored.
std::vector<StreamDecl> parse_info_node(std::string_view xml) {
  std::vector<StreamDecl> streams;
  std::vector<std::string_view> stack;  // node names
  auto stream_for = [&](int id) -> StreamDecl& {
    for (auto& s : streams)
      if (s.id == id) return s;
    streams.push_back(StreamDecl{id, {}, 0, 0, {}});
    return streams.back();
  };
  std::size_t i = 0;
  while ((i = xml.find('<', i)) != std::string_view::npos) {
    if (xml.substr(i, 4) == "<!--") {
      const auto end = xml.find("-->", i);
      if (end == std::string_view::npos) break;
      i = end + 3;
      continue;
    }
    const auto close = xml.find('>', i);
    if (close == std::string_view::npos) break;
    const std::string_view tag = xml.substr(i, close + 1 - i);
    i = close + 1;
    const bool self_closing = tag.size() >= 2 && tag[tag.size() - 2] == '/';
    if (tag.starts_with("</node")) {
      if (!stack.empty()) stack.pop_back();
    } else if (tag.starts_with("<node") && tag.size() > 5 && (tag[5] == ' ' || tag[5] == '\t' || tag[5] == '\n')) {
      if (!self_closing) stack.push_back(tag_attribute(tag, "name").value_or(""));
    } else if (tag.starts_with("<attr") && !self_closing) {
      const auto key = tag_attribute(tag, "key");
      const auto value_end = xml.find('<', i);
      if (!key || value_end == std::string_view::npos || stack.empty()) continue;
      const std::string_view value = xml.substr(i, value_end - i);
      // attribute of a stream node, or of its "info" child
      const bool in_info = stack.size() >= 2 && stack.back() == "info";
      const auto id = parse_int(in_info ? stack[stack.size() - 2] : stack.back());
      if (!id) continue;
      StreamDecl& s = stream_for(*id);
      if (!in_info && *key == "typeIdentifier") s.type_identifier = xml_unescape(value);
      if (in_info && *key == "sizeX") s.size_x = parse_int(value).value_or(0);
      if (in_info && *key == "sizeY") s.size_y = parse_int(value).value_or(0);
      if (in_info && *key == "source") s.source = xml_unescape(value);
    }
  }
  return streams;
}

// ----------------------------------------------------------------------------------------------------

struct Lz4Ctx {
  LZ4F_dctx* ctx = nullptr;
  Lz4Ctx() {
    if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) ctx = nullptr;
  }
  ~Lz4Ctx() {
    if (ctx) LZ4F_freeDecompressionContext(ctx);
  }
  Lz4Ctx(const Lz4Ctx&) = delete;
  Lz4Ctx& operator=(const Lz4Ctx&) = delete;
};

struct ZstdCtx {
  ZSTD_DCtx* ctx = ZSTD_createDCtx();
  ZstdCtx() = default;
  ~ZstdCtx() { ZSTD_freeDCtx(ctx); }
  ZstdCtx(const ZstdCtx&) = delete;
  ZstdCtx& operator=(const ZstdCtx&) = delete;
};

class Aedat4Reader final : public FileReader {
 public:
  Aedat4Reader(std::unique_ptr<ByteSource> source, ReaderOptions options)
      : source_(std::move(source)),
        options_(std::move(options)),
        file_(source_->name()),
        clock_(options_, stats_, file_),
        batch_events_(std::max<std::size_t>(1, options_.batch_events)) {
    info_.name = file_;
    info_.format = "aedat4";
    info_.geometry = options_.default_geometry;
    file_size_ = source_->size();
    stop_ = file_size_.value_or(std::numeric_limits<std::uint64_t>::max());
    if (!source_->seek(0)) throw FormatError(file_, 0, "cannot rewind the input");
    read_header();
    pending_.events.reserve(batch_events_);
  }

  EventBatchPtr next() override {
    if (finished_) return nullptr;
    while (true) {
      if (elements_ != nullptr) {
        if (auto batch = decode_current_packet()) return batch;
        elements_ = nullptr;  // packet exhausted
      }
      if (!load_next_packet()) {
        finished_ = true;
        if (!pending_.events.empty()) return take_pending();
        return nullptr;
      }
    }
  }

  [[nodiscard]] std::optional<double> progress() const override {
    if (finished_) return 1.0;
    return detail::byte_progress(pos_, file_size_);
  }

 private:
  // ---- header ------------------------------------------------------------------------------------

  void read_header() {
    std::array<std::byte, kMagic.size()> magic{};
    const std::size_t got = read_up_to(magic);
    if (got == 0) throw FormatError(file_, 0, "the file is empty (expected an AEDAT 4.0 header)");
    if (got < magic.size() || std::memcmp(magic.data(), kMagic.data(), kMagic.size()) != 0)
      throw FormatError(file_, 0, "not an AEDAT 4.0 file: it does not start with '#!AER-DAT4.0\\r\\n'");

    std::array<std::byte, 4> prefix{};
    if (read_up_to(prefix) < prefix.size())
      throw FormatError(file_, kHeaderStart, "the file ends inside the IOHeader size prefix");
    const auto header_bytes = detail::load_le<std::uint32_t>(prefix.data());
    const std::uint64_t header_end = kHeaderStart + 4 + header_bytes;
    if (header_bytes > kMaxHeaderBytes || header_end > stop_)
      throw FormatError(file_, kHeaderStart,
                        fmt::format("IOHeader size {} runs past the end of the file ({} bytes remain)", header_bytes,
                                    stop_ - std::min(stop_, kHeaderStart + 4)));

    std::vector<std::uint8_t> buf(4 + header_bytes);
    std::memcpy(buf.data(), prefix.data(), 4);
    if (read_up_to(std::as_writable_bytes(std::span(buf).subspan(4))) < header_bytes)
      throw FormatError(file_, kHeaderStart + 4, "the file ends inside the IOHeader");
    const std::uint8_t* root = verified<fb::IOHeader>(buf, fb::IOHeaderIdentifier(), header_copy_);
    if (root == nullptr)
      throw FormatError(file_, kHeaderStart + 4, "the IOHeader is not a valid 'IOHE' flatbuffer (failed verification)");
    const fb::IOHeader* header = fb::GetIOHeader(root);

    const auto compression = header->compression();
    switch (compression) {
      case fb::CompressionType::NONE:
      case fb::CompressionType::LZ4:
      case fb::CompressionType::LZ4_HIGH:
      case fb::CompressionType::ZSTD:
      case fb::CompressionType::ZSTD_HIGH:
        break;
      default:
        throw FormatError(
            file_, kHeaderStart + 4,
            fmt::format("unknown compression type {} in the IOHeader", static_cast<std::int32_t>(compression)));
    }
    compression_ = compression;
    pos_ = header_end;
    stats_.bytes_read = pos_;

    const std::int64_t table_at = header->data_table_position();
    if (table_at >= 0 && static_cast<std::uint64_t>(table_at) >= header_end &&
        static_cast<std::uint64_t>(table_at) <= stop_) {
      stop_ = static_cast<std::uint64_t>(table_at);
    } else if (table_at != -1) {
      clock_.warn(kHeaderStart + 4, fmt::format("dataTablePosition {} is not inside the file: ignored, "
                                                "reading packets to the end of the file",
                                                table_at));
    }

    choose_event_stream(header->info_node() ? header->info_node()->string_view() : std::string_view{});
  }

  void choose_event_stream(std::string_view xml) {
    auto streams = parse_info_node(xml);
    std::sort(streams.begin(), streams.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
    std::vector<const StreamDecl*> event_streams;
    for (const auto& s : streams)
      if (s.type_identifier == "EVTS") event_streams.push_back(&s);
    if (streams.empty()) {
      // No usable stream table: take the first stream whose packets carry the EVTS identifier.
      identify_by_content_ = true;
      clock_.warn(kHeaderStart + 4, fmt::format("the IOHeader declares no streams: reading packets "
                                                "identified as 'EVTS'; sensor size unknown, assuming {}x{}",
                                                info_.geometry.width, info_.geometry.height));
      return;
    }
    if (event_streams.empty()) {
      clock_.warn(kHeaderStart + 4, "the file declares no event (EVTS) stream: no events to read");
      return;
    }
    const StreamDecl& chosen = *event_streams.front();
    event_stream_ = chosen.id;
    if (event_streams.size() > 1)
      clock_.warn(kHeaderStart + 4, fmt::format("the file has {} event streams: reading stream {} only",
                                                event_streams.size(), chosen.id));
    // Event coordinates are int16 in the file.
    if (chosen.size_x > kMaxSensorSide || chosen.size_y > kMaxSensorSide)
      throw FormatError(file_, kHeaderStart + 4,
                        fmt::format("event stream {} declares a {}x{} sensor: larger than the largest evpipe accepts "
                                    "({}x{}, docs/operations.md \"Limits\")",
                                    chosen.id, chosen.size_x, chosen.size_y, kMaxSensorSide, kMaxSensorSide));
    if (chosen.size_x > 0 && chosen.size_y > 0) {
      info_.geometry = SensorGeometry{chosen.size_x, chosen.size_y};
      info_.geometry_known = true;
    } else {
      clock_.warn(kHeaderStart + 4,
                  fmt::format("event stream {} states no valid sensor size (sizeX={} sizeY={}): assuming {}x{}",
                              chosen.id, chosen.size_x, chosen.size_y, info_.geometry.width, info_.geometry.height));
    }
  }

  /// Verifies a size-prefixed flatbuffer (`sized` = uint32 size + buffer, in memory aligned to 8) and
  /// returns its unprefixed start, or nullptr. Writers differ in what they align to: dv-processing
  /// aligns fields relative to the size prefix (FlatBuffers' FinishSizePrefixed), another writer
  /// (davis346-faery-trimmed) relative to the buffer after it. The second layout is verified on an
  /// aligned copy in `copy`, so that every access stays aligned.
  template <typename T>
  static const std::uint8_t* verified(std::span<const std::uint8_t> sized, const char* identifier,
                                      std::vector<std::uint64_t>& copy) {
    if (sized.size() < 8 ||
        detail::load_le<std::uint32_t>(reinterpret_cast<const std::byte*>(sized.data())) != sized.size() - 4)
      return nullptr;
    {
      flatbuffers::Verifier verifier(sized.data(), sized.size());
      if (verifier.VerifySizePrefixedBuffer<T>(identifier)) return sized.data() + 4;
    }
    const std::size_t n = sized.size() - 4;
    copy.resize((n + 7) / 8);
    auto* plain = reinterpret_cast<std::uint8_t*>(copy.data());
    std::memcpy(plain, sized.data() + 4, n);
    flatbuffers::Verifier verifier(plain, n);
    return verifier.VerifyBuffer<T>(identifier) ? plain : nullptr;
  }

  // ---- packets -----------------------------------------------------------------------------------

  /// Reads until dst is full or the input ends; returns the byte count.
  std::size_t read_up_to(std::span<std::byte> dst) {
    std::size_t done = 0;
    while (done < dst.size()) {
      const std::size_t n = source_->read(dst.subspan(done));
      if (n == 0) break;
      done += n;
    }
    return done;
  }

  /// Makes n bytes at pos_ available in the read-ahead window (reading ahead kReadAheadBytes at a time, so
  /// that small packets cost no system call each); returns how many are available (< n only at the end of
  /// the input). Callers bound n (packet header, or a packet size checked against the file size and cap).
  std::size_t fill(std::size_t n) {
    std::size_t have = window_end_ - window_begin_;
    if (have >= n) return n;
    if (window_begin_ > 0) {
      std::memmove(window_.data(), window_.data() + window_begin_, have);
      window_begin_ = 0;
      window_end_ = have;
    }
    // read ahead, but not beyond the end of a small input (fuzzers, tests)
    std::size_t ahead = kReadAheadBytes;
    if (file_size_ && *file_size_ > pos_)
      ahead = static_cast<std::size_t>(std::min<std::uint64_t>(ahead, *file_size_ - pos_));
    if (window_.size() < std::max(n, ahead)) window_.resize(std::max(n, ahead));
    window_end_ += read_up_to(std::span(window_.data() + window_end_, window_.size() - window_end_));
    have = window_end_ - window_begin_;
    return std::min(n, have);
  }

  void consume(std::size_t n) {
    window_begin_ += n;
    pos_ += n;
    stats_.bytes_read = pos_;
  }

  /// Skips n bytes (a packet that is not read): within the window, else by seeking.
  bool skip(std::uint64_t n) {
    if (n <= window_end_ - window_begin_) {
      consume(static_cast<std::size_t>(n));
      return true;
    }
    pos_ += n;
    stats_.bytes_read = pos_;
    window_begin_ = window_end_ = 0;
    return source_->seek(pos_);
  }

  void truncated(std::uint64_t at, std::uint64_t bytes, const std::string& what) {
    stats_.truncated_bytes += bytes;
    clock_.warn(at, what + fmt::format(": the recording is truncated; {} trailing bytes ignored", bytes));
    pos_ = stop_;
    stats_.bytes_read = pos_;
  }

  void corrupt(std::uint64_t at, const std::string& what) {
    ++stats_.corrupt_packets;
    if (stats_.corrupt_packets <= kMaxCorruptWarnings) clock_.warn(at, what + " (packet skipped)");
    if (stats_.corrupt_packets == kMaxCorruptWarnings)
      clock_.warn(std::nullopt, "further corrupt packets are counted but not reported");
  }

  bool is_event_stream(std::int32_t stream_id) const {
    if (identify_by_content_) return event_stream_ < 0 || stream_id == event_stream_;
    return stream_id == event_stream_;
  }

  /// Loads the next events packet into elements_; false at the end of the data.
  bool load_next_packet() {
    while (pos_ < stop_) {
      const std::uint64_t header_at = pos_;
      const std::size_t got = fill(kPacketHeaderBytes);
      if (got == 0 && !file_size_) return false;  // unknown size: clean end of input
      if (got < kPacketHeaderBytes) {
        truncated(header_at, got, fmt::format("packet header cut off after {} bytes", got));
        return false;
      }
      const auto stream_id = detail::load_le<std::int32_t>(window_.data() + window_begin_);
      const auto size = detail::load_le<std::int32_t>(window_.data() + window_begin_ + 4);
      const std::uint64_t payload_at = header_at + kPacketHeaderBytes;
      if (size < 0)
        throw FormatError(file_, header_at,
                          fmt::format("packet header of stream {} has a negative size {}", stream_id, size));
      if (payload_at > stop_ || static_cast<std::uint64_t>(size) > stop_ - payload_at) {
        truncated(header_at, stop_ - header_at,
                  fmt::format("packet of stream {} declares {} bytes but only {} remain", stream_id, size,
                              stop_ - std::min(stop_, payload_at)));
        return false;
      }
      consume(kPacketHeaderBytes);

      if (!is_event_stream(stream_id) || static_cast<std::uint64_t>(size) > kMaxStoredPacketBytes) {
        if (is_event_stream(stream_id))
          corrupt(header_at,
                  fmt::format("events packet of {} bytes exceeds the {} MiB limit", size, kMaxStoredPacketBytes >> 20));
        else
          ++stats_.skipped_non_dvs;
        if (!skip(static_cast<std::uint64_t>(size))) {
          truncated(header_at, 0, "cannot skip past the packet");
          return false;
        }
        continue;
      }

      // size is bounded here by the remaining file size and kMaxStoredPacketBytes
      const auto stored_bytes = static_cast<std::size_t>(size);
      const std::size_t available = fill(stored_bytes);
      if (available < stored_bytes) {
        truncated(header_at, kPacketHeaderBytes + available,
                  fmt::format("packet of stream {} declares {} bytes but the input ends after {}", stream_id, size,
                              available));
        return false;
      }
      std::span<const std::byte> stored(window_.data() + window_begin_, stored_bytes);
      consume(stored_bytes);  // the bytes stay in the window until the next fill()
      if (compression_ == fb::CompressionType::NONE) {
        // the flatbuffer is read in place: copy it to an aligned buffer
        if (stored_.size() < stored_bytes) stored_.resize(stored_bytes);
        if (stored_bytes > 0) std::memcpy(stored_.data(), stored.data(), stored_bytes);  // empty: data() may be null
        stored = std::span<const std::byte>(stored_.data(), stored_bytes);
      }

      std::span<const std::byte> buffer;
      if (const std::string error = decompress(stored, buffer); !error.empty()) {
        corrupt(payload_at, fmt::format("packet of stream {}: {}", stream_id, error));
        continue;
      }
      const auto* bytes = reinterpret_cast<const std::uint8_t*>(buffer.data());
      if (identify_by_content_ &&
          (buffer.size() < 12 || !flatbuffers::BufferHasIdentifier(bytes, fb::EventPacketIdentifier(), true))) {
        ++stats_.skipped_non_dvs;
        continue;
      }
      const std::uint8_t* root =
          verified<fb::EventPacket>(std::span(bytes, buffer.size()), fb::EventPacketIdentifier(), realigned_);
      if (root == nullptr) {
        corrupt(payload_at,
                fmt::format("packet of stream {} is not a valid 'EVTS' flatbuffer (failed verification)", stream_id));
        continue;
      }
      if (identify_by_content_) event_stream_ = stream_id;
      const auto* elements = fb::GetEventPacket(root)->elements();
      if (elements == nullptr || elements->size() == 0) continue;
      // FlatBuffers' verifier (2.0.8) checks the alignment of a vector's length field only, not of its
      // struct elements; every conforming writer aligns them to the struct (8 bytes), so a misaligned array
      // is damage, and reading it would be undefined behaviour.
      if (reinterpret_cast<std::uintptr_t>(elements->Data()) % alignof(fb::Event) != 0) {
        corrupt(payload_at, fmt::format("packet of stream {}: its event array is misaligned", stream_id));
        continue;
      }
      elements_ = elements;
      cursor_ = 0;
      packet_at_ = payload_at;
      return true;
    }
    return false;
  }

  /// Decompresses one stored packet into `out` (a view of decoded_ or of `stored`). Returns "" or the
  /// reason the packet is unreadable. The decompressed size is bounded by the buffer's size prefix and
  /// by kMaxDecodedPacketBytes; the buffer grows only as output is actually produced.
  std::string decompress(std::span<const std::byte> stored, std::span<const std::byte>& out) {
    switch (compression_) {
      case fb::CompressionType::NONE:
        out = stored;
        return {};
      case fb::CompressionType::LZ4:
      case fb::CompressionType::LZ4_HIGH:
        return decompress_lz4(stored, out);
      case fb::CompressionType::ZSTD:
      case fb::CompressionType::ZSTD_HIGH:
        return decompress_zstd(stored, out);
    }
    return "unknown compression";
  }

  /// Bytes the packet may decompress to: its size prefix + 4 once decoded, else the global cap.
  std::uint64_t output_limit(std::size_t produced) const {
    if (produced < 4) return kMaxDecodedPacketBytes;
    return std::uint64_t{detail::load_le<std::uint32_t>(decoded_.data())} + 4;
  }

  /// Output space for the next decompression step. One guard byte past the limit lets the decoder
  /// finish a frame whose output exactly fills the limit, and reveals output that exceeds it. decoded_
  /// grows only as output is actually produced (geometric), never beyond the limit + 1.
  std::size_t make_room(std::size_t produced, std::uint64_t limit, std::size_t stored_bytes) {
    const std::size_t end = static_cast<std::size_t>(limit) + 1;
    if (decoded_.size() < end && produced >= decoded_.size()) {
      const std::size_t want = std::max({decoded_.size() * 2, stored_bytes * 4, std::size_t{64} << 10});
      decoded_.resize(std::min(want, end));
    }
    return std::min(decoded_.size(), end) - produced;
  }

  /// "" while the output is within bounds, else the reason.
  static std::string check_limit(std::size_t produced, std::uint64_t limit) {
    if (limit > kMaxDecodedPacketBytes)
      return fmt::format("size prefix of {} bytes exceeds the {} MiB limit", limit - 4, kMaxDecodedPacketBytes >> 20);
    if (produced > limit)
      return produced < 4 || limit == kMaxDecodedPacketBytes
                 ? fmt::format("decompressed packet exceeds {} MiB", kMaxDecodedPacketBytes >> 20)
                 : "decompressed data is longer than the packet's size prefix";
    return {};
  }

  std::string check_decoded_size(std::size_t produced) const {
    if (produced < 8) return fmt::format("decompressed packet has only {} bytes", produced);
    const std::uint64_t total = output_limit(produced);
    if (total != produced)
      return fmt::format("decompressed packet has {} bytes but its size prefix says {}", produced, total);
    return {};
  }

  std::string decompress_lz4(std::span<const std::byte> stored, std::span<const std::byte>& out) {
    if (lz4_.ctx == nullptr) return "cannot create an LZ4 decompression context";
    LZ4F_resetDecompressionContext(lz4_.ctx);
    const auto* src = reinterpret_cast<const char*>(stored.data());
    std::size_t src_left = stored.size();
    std::size_t produced = 0;
    while (true) {
      const std::uint64_t limit = output_limit(produced);
      if (auto error = check_limit(produced, limit); !error.empty()) return error;
      std::size_t dst_n = make_room(produced, limit, stored.size());
      std::size_t src_n = src_left;
      const std::size_t hint = LZ4F_decompress(lz4_.ctx, decoded_.data() + produced, &dst_n, src, &src_n, nullptr);
      if (LZ4F_isError(hint)) return fmt::format("LZ4 error: {}", LZ4F_getErrorName(hint));
      produced += dst_n;
      src += src_n;
      src_left -= src_n;
      if (hint == 0 && src_left == 0) break;  // frame complete, input used up
      if (src_left == 0 && dst_n == 0) return "LZ4 frame is incomplete";
      if (src_n == 0 && dst_n == 0) return "LZ4 decoder made no progress";
    }
    if (auto error = check_limit(produced, output_limit(produced)); !error.empty()) return error;
    if (auto error = check_decoded_size(produced); !error.empty()) return error;
    out = std::span<const std::byte>(decoded_.data(), produced);
    return {};
  }

  std::string decompress_zstd(std::span<const std::byte> stored, std::span<const std::byte>& out) {
    if (zstd_.ctx == nullptr) return "cannot create a zstd decompression context";
    ZSTD_DCtx_reset(zstd_.ctx, ZSTD_reset_session_only);
    ZSTD_inBuffer in{stored.data(), stored.size(), 0};
    std::size_t produced = 0;
    while (true) {
      const std::uint64_t limit = output_limit(produced);
      if (auto error = check_limit(produced, limit); !error.empty()) return error;
      const std::size_t room = make_room(produced, limit, stored.size());
      ZSTD_outBuffer dst{decoded_.data(), produced + room, produced};
      const std::size_t in_before = in.pos;
      const std::size_t ret = ZSTD_decompressStream(zstd_.ctx, &dst, &in);
      if (ZSTD_isError(ret)) return fmt::format("zstd error: {}", ZSTD_getErrorName(ret));
      const bool progressed = dst.pos != produced || in.pos != in_before;
      produced = dst.pos;
      if (ret == 0 && in.pos == in.size) break;  // frame complete and flushed, input used up
      if (in.pos == in.size && dst.pos < dst.size) return "zstd frame is incomplete";
      if (!progressed) return "zstd decoder made no progress";
    }
    if (auto error = check_limit(produced, output_limit(produced)); !error.empty()) return error;
    if (auto error = check_decoded_size(produced); !error.empty()) return error;
    out = std::span<const std::byte>(decoded_.data(), produced);
    return {};
  }

  // ---- events ------------------------------------------------------------------------------------

  /// Decodes events of the current packet from cursor_; returns a batch when one is complete (the
  /// packet may then have events left), nullptr when the packet is exhausted.
  EventBatchPtr decode_current_packet() {
    const std::uint32_t n = elements_->size();
    // Structs are stored inline: the vector's data is an array of fb::Event (verified; alignment checked
    // in load_next_packet()).
    const auto* events = reinterpret_cast<const fb::Event*>(elements_->Data());
    const auto width = static_cast<unsigned>(info_.geometry.width);
    const auto height = static_cast<unsigned>(info_.geometry.height);
    while (cursor_ < n) {
      // Fast path: copy the run of in-order events inside the sensor and the time limits, then tell the TimeOrder
      // only the run's last timestamp (all of them would have been kept; its state ends the same).
      auto& out = pending_.events;
      const std::size_t base = out.size();
      const std::uint32_t run_end =
          cursor_ + static_cast<std::uint32_t>(std::min<std::size_t>(batch_events_ - base, n - cursor_));
      out.resize(base + (run_end - cursor_));
      Event* dst = out.data() + base;
      std::int64_t last = last_t_us_;
      std::uint32_t i = cursor_;
      for (; i < run_end; ++i) {
        const fb::Event& e = events[i];
        const std::int64_t t = e.timestamp();
        const int x = e.x();
        const int y = e.y();
        if (t < last || !within_timestamp_limits(t) || static_cast<unsigned>(x) >= width ||
            static_cast<unsigned>(y) >= height) {
          break;
        }
        last = t;
        *dst++ = Event{t, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), e.polarity()};
      }
      out.resize(base + (i - cursor_));
      if (i > cursor_) {
        clock_.check(last, packet_at_);
        last_t_us_ = last;
        cursor_ = i;
      }
      if (out.size() >= batch_events_) return take_pending();
      if (i < run_end) {
        if (auto batch = decode_one(events[i])) return batch;  // out of order, or outside the sensor
      }
    }
    return nullptr;
  }

  /// The general path for the event at cursor_: geometry error, time-order policy, discontinuity split.
  EventBatchPtr decode_one(const fb::Event& e) {
    const int x = e.x();
    const int y = e.y();
    if (!info_.geometry.contains(x, y))
      throw FormatError(file_, packet_at_,
                        fmt::format("event {} of the packet: x={} y={} is outside the {}x{} sensor{}", cursor_, x, y,
                                    info_.geometry.width, info_.geometry.height,
                                    info_.geometry_known ? "" : " (size assumed: the file states none)"));
    const Event ev{e.timestamp(), static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), e.polarity()};
    ++cursor_;
    const auto verdict = clock_.check(ev.t_us, packet_at_);
    // mirror TimeOrder's notion of the previous timestamp (it advances on in-order events and resets)
    if (verdict == detail::TimeOrder::Verdict::keep_after_discontinuity || ev.t_us >= last_t_us_) last_t_us_ = ev.t_us;
    switch (verdict) {
      case detail::TimeOrder::Verdict::drop:
        return nullptr;
      case detail::TimeOrder::Verdict::keep:
        break;
      case detail::TimeOrder::Verdict::keep_after_discontinuity:
        if (!pending_.events.empty()) {
          auto batch = take_pending();
          pending_.discontinuity_before = true;
          pending_.events.push_back(ev);
          return batch;
        }
        pending_.discontinuity_before = true;
        break;
    }
    pending_.events.push_back(ev);
    if (pending_.events.size() >= batch_events_) return take_pending();
    return nullptr;
  }

  EventBatchPtr take_pending() {
    stats_.events += pending_.events.size();
    ++stats_.batches;
    pending_.read_at = std::chrono::steady_clock::now();
    auto batch = std::make_shared<const EventBatch>(std::move(pending_));
    pending_ = EventBatch{};
    pending_.events.reserve(batch_events_);
    return batch;
  }

  std::unique_ptr<ByteSource> source_;
  ReaderOptions options_;
  std::string file_;
  detail::TimeOrder clock_;
  std::size_t batch_events_;

  std::optional<std::uint64_t> file_size_;
  std::uint64_t pos_ = 0;   // next unread byte
  std::uint64_t stop_ = 0;  // end of the packet area (data table or end of file)
  fb::CompressionType compression_ = fb::CompressionType::NONE;
  std::int32_t event_stream_ = -1;    // the stream read; -1 = none (yet)
  bool identify_by_content_ = false;  // no stream table: accept the first stream whose packets are EVTS

  Lz4Ctx lz4_;
  ZstdCtx zstd_;
  std::vector<std::byte> window_;  // read-ahead: file bytes from pos_ at window_[window_begin_]
  std::size_t window_begin_ = 0;
  std::size_t window_end_ = 0;
  std::vector<std::byte> stored_;           // an uncompressed packet, copied to be aligned
  std::vector<std::byte> decoded_;          // one packet decompressed (grows to the largest)
  std::vector<std::uint64_t> realigned_;    // a packet re-aligned for verification (rare layout)
  std::vector<std::uint64_t> header_copy_;  // the IOHeader, idem

  // the current packet's events: in stored_, decoded_ or realigned_ (never in window_)
  const flatbuffers::Vector<const fb::Event*>* elements_ = nullptr;
  std::uint32_t cursor_ = 0;
  std::int64_t last_t_us_ = std::numeric_limits<std::int64_t>::min();  // TimeOrder's previous timestamp
  std::uint64_t packet_at_ = 0;                                        // file offset of the current packet's payload
  EventBatch pending_;
};

}  // namespace

std::unique_ptr<FileReader> make_aedat4_reader(std::unique_ptr<ByteSource> source, ReaderOptions options) {
  return std::make_unique<Aedat4Reader>(std::move(source), std::move(options));
}

}  // namespace evpipe::io
