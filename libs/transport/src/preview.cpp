#include "evpipe/transport/preview.hpp"

#include "evpipe/preview_t.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/records.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <lcm/lcm-cpp.hpp>

#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

#include "wire_walker.hpp"

namespace evpipe::transport {

std::string_view preview_status_name(std::int8_t status) noexcept {
  switch (status) {
    case kPreviewStatusInitialising:
      return "initialising";
    case kPreviewStatusTracking:
      return "tracking";
    case kPreviewStatusLost:
      return "lost";
    case kPreviewStatusHolding:
      return "holding";
    default:
      return "?";
  }
}

namespace {

constexpr std::uint8_t kRunShort = 63;  // a run byte's count field: < 63 = n + 1 pixels, 63 = 64 + LEB128

void put_run(std::vector<std::uint8_t>& out, std::uint8_t code, std::size_t n) {
  if (n <= kRunShort) {
    out.push_back(static_cast<std::uint8_t>(code << 6 | (n - 1)));
    return;
  }
  out.push_back(static_cast<std::uint8_t>(code << 6 | kRunShort));
  std::size_t extra = n - 64;
  do {
    auto b = static_cast<std::uint8_t>(extra & 0x7F);
    extra >>= 7;
    if (extra != 0) b |= 0x80;
    out.push_back(b);
  } while (extra != 0);
}

// preview_t.lcm's wire layout (LCM's encoding: big-endian numbers, a string = an int32 length counting its NUL,
// then the bytes), walked before the generated decode() runs: that code resizes `image` to image_bytes and the
// segment arrays to num_segments before checking that the bytes are there (a 200-byte message claiming 2^31 - 1
// image bytes had the viewer allocate 2 GB; a negative count, converted to a size, more). The walk allocates
// nothing and bounds every count and length by the bytes left (wire_walker.hpp, as codec.cpp's pose_t / stats_t);
// the preview round trips (tests/transport) keep it in step with preview_t.lcm: a field added there and not here
// makes every preview fail to decode.
// preview_t.lcm, field by field.
void walk(detail::WireWalker& w) {
  w.fixed("utime", 8);
  w.fixed("seq", 8);
  w.fixed("t_us", 8);
  w.fixed("window_t0_us", 8);
  w.fixed("window_t1_us", 8);
  w.fixed("status", 1);
  w.fixed("pose_valid", 1);
  w.fixed("raw_events", 4);
  w.fixed("kept_events", 4);
  w.fixed("pose_events", 4);
  w.fixed("inliers", 4);
  w.fixed("sigma_px", 4);
  w.fixed("latency_ms", 4);
  w.fixed("latency_p99_ms", 4);
  w.fixed("queue_drops", 8);
  w.fixed("previews_dropped", 8);
  w.fixed("width", 2);
  w.fixed("height", 2);
  w.fixed("bin", 1);
  w.fixed("encoding", 1);
  const std::int32_t image_bytes = w.count("image_bytes", 1);
  w.fixed("image", static_cast<std::size_t>(image_bytes));
  const std::int32_t segments = w.count("num_segments", 4 * 4);  // x0, y0, x1 and y1: a float each
  for (const std::string_view field : {"x0", "y0", "x1", "y1"}) w.fixed(field, static_cast<std::size_t>(segments) * 4);
  w.string("note");
}

}  // namespace

std::optional<std::string> preview_wire_error(const void* data, std::size_t size) {
  return detail::walk_error("preview_t", evpipe::preview_t::getHash(), data, size,
                            [](detail::WireWalker& w) { walk(w); });
}

EncodedImage encode_preview_image(const std::vector<std::uint8_t>& pixels) {
  EncodedImage rle{evpipe::preview_t::ENCODING_RLE, {}};
  for (std::size_t i = 0; i < pixels.size();) {
    const std::uint8_t code = pixels[i] & 3;
    std::size_t j = i + 1;
    while (j < pixels.size() && (pixels[j] & 3) == code) ++j;
    put_run(rle.bytes, code, j - i);
    i = j;
  }
  const std::size_t packed_size = (pixels.size() + 3) / 4;
  if (rle.bytes.size() <= packed_size) return rle;
  EncodedImage packed{evpipe::preview_t::ENCODING_PACKED, std::vector<std::uint8_t>(packed_size, 0)};
  for (std::size_t i = 0; i < pixels.size(); ++i)
    packed.bytes[i / 4] = static_cast<std::uint8_t>(packed.bytes[i / 4] | (pixels[i] & 3) << (2 * (i % 4)));
  return packed;
}

std::vector<std::uint8_t> decode_preview_image(std::int8_t encoding, const std::uint8_t* data, std::size_t size,
                                               std::size_t count) {
  std::vector<std::uint8_t> pixels;
  if (encoding == evpipe::preview_t::ENCODING_PACKED) {
    if (size != (count + 3) / 4)
      throw DecodeError(
          fmt::format("preview_t.image: {} bytes, a packed {}-pixel image has {}", size, count, (count + 3) / 4));
    pixels.resize(count);
    for (std::size_t i = 0; i < count; ++i) pixels[i] = static_cast<std::uint8_t>(data[i / 4] >> (2 * (i % 4)) & 3);
    return pixels;
  }
  if (encoding != evpipe::preview_t::ENCODING_RLE)
    throw DecodeError(fmt::format("preview_t.encoding: {} is neither PACKED (0) nor RLE (1)", encoding));
  pixels.reserve(count);
  for (std::size_t i = 0; i < size;) {
    const std::size_t at = i;
    const std::uint8_t b = data[i++];
    std::size_t n = (b & kRunShort) + 1u;
    if ((b & kRunShort) == kRunShort) {
      std::size_t extra = 0;
      int shift = 0;
      for (;;) {
        if (i >= size || shift > 28)
          throw DecodeError(fmt::format("preview_t.image: run at byte {}: truncated or overlong count", at));
        const std::uint8_t c = data[i++];
        extra |= static_cast<std::size_t>(c & 0x7F) << shift;
        shift += 7;
        if ((c & 0x80) == 0) break;
      }
      n = 64 + extra;
    }
    if (n > count - pixels.size())
      throw DecodeError(fmt::format("preview_t.image: run at byte {} goes past the {} pixels of the image", at, count));
    pixels.insert(pixels.end(), n, static_cast<std::uint8_t>(b >> 6));
  }
  if (pixels.size() != count)
    throw DecodeError(fmt::format("preview_t.image: {} pixels decoded, the image has {}", pixels.size(), count));
  return pixels;
}

std::vector<std::uint8_t> encode(const PreviewRecord& r) {
  evpipe::preview_t m;
  m.utime = r.utime_us;
  m.seq = r.seq;
  m.t_us = r.t_us;
  m.window_t0_us = r.window_t0_us;
  m.window_t1_us = r.window_t1_us;
  m.status = r.status;
  m.pose_valid = r.pose_valid ? 1 : 0;
  m.raw_events = r.raw_events;
  m.kept_events = r.kept_events;
  m.pose_events = r.pose_events;
  m.inliers = r.inliers;
  m.sigma_px = r.sigma_px;
  m.latency_ms = r.latency_ms;
  m.latency_p99_ms = r.latency_p99_ms;
  m.queue_drops = r.queue_drops;
  m.previews_dropped = r.previews_dropped;
  m.width = static_cast<std::int16_t>(r.width);
  m.height = static_cast<std::int16_t>(r.height);
  m.bin = static_cast<std::int8_t>(r.bin);
  auto image = encode_preview_image(r.pixels);
  m.encoding = image.encoding;
  m.image_bytes = static_cast<std::int32_t>(image.bytes.size());
  m.image = std::move(image.bytes);
  m.num_segments = static_cast<std::int32_t>(r.segments.size());
  for (const auto& s : r.segments) {
    m.x0.push_back(s.x0_px);
    m.y0.push_back(s.y0_px);
    m.x1.push_back(s.x1_px);
    m.y1.push_back(s.y1_px);
  }
  m.note = r.note;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

std::optional<PreviewRecord> decode_preview(const void* data, std::size_t size) {
  if (data == nullptr || size > static_cast<std::size_t>(std::numeric_limits<int>::max())) return std::nullopt;
  // Truncated, or a count / length beyond the bytes: walked before decode() allocates.
  if (preview_wire_error(data, size)) return std::nullopt;
  evpipe::preview_t m;
  // The walk has refused negative or absurd counts already; the catch is a second line.
  try {
    if (m.decode(data, 0, static_cast<int>(size)) < 0) return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (m.width <= 0 || m.height <= 0 || m.bin <= 0)
    throw DecodeError(fmt::format("preview_t: image size {}x{} bin {} (all must be > 0)", m.width, m.height, m.bin));
  // evpipe bins its previews to at most 100 000 pixels (view::kMaxPreviewPixels); a stray message claiming up to
  // 32767 x 32767 would have the viewer allocate gigabytes before its image is found not to decode.
  constexpr std::int64_t kMaxPixels = 1'000'000;
  if (static_cast<std::int64_t>(m.width) * m.height > kMaxPixels)
    throw DecodeError(fmt::format("preview_t: image size {}x{} is more than the {} pixels a preview has at most",
                                  m.width, m.height, kMaxPixels));
  PreviewRecord r;
  r.utime_us = m.utime;
  r.seq = m.seq;
  r.t_us = m.t_us;
  r.window_t0_us = m.window_t0_us;
  r.window_t1_us = m.window_t1_us;
  r.status = m.status;
  r.pose_valid = m.pose_valid;
  r.raw_events = m.raw_events;
  r.kept_events = m.kept_events;
  r.pose_events = m.pose_events;
  r.inliers = m.inliers;
  r.sigma_px = m.sigma_px;
  r.latency_ms = m.latency_ms;
  r.latency_p99_ms = m.latency_p99_ms;
  r.queue_drops = m.queue_drops;
  r.previews_dropped = m.previews_dropped;
  r.width = m.width;
  r.height = m.height;
  r.bin = m.bin;
  r.pixels = decode_preview_image(m.encoding, m.image.data(), m.image.size(),
                                  static_cast<std::size_t>(m.width) * static_cast<std::size_t>(m.height));
  r.segments.reserve(m.x0.size());
  for (std::size_t i = 0; i < m.x0.size(); ++i) {
    const PreviewSegment s{m.x0[i], m.y0[i], m.x1[i], m.y1[i]};
    if (!std::isfinite(s.x0_px) || !std::isfinite(s.y0_px) || !std::isfinite(s.x1_px) || !std::isfinite(s.y1_px))
      throw DecodeError(fmt::format("preview_t: segment {} has a non-finite coordinate", i));
    r.segments.push_back(s);
  }
  r.note = m.note;
  return r;
}

PreviewPublisher::PreviewPublisher(std::string url, std::string channel)
    : url_(std::move(url)), channel_(std::move(channel)) {}

PreviewPublisher::~PreviewPublisher() = default;

bool PreviewPublisher::publish(const PreviewRecord& r) {
  const std::lock_guard lock(mutex_);
  PreviewRecord m = r;
  if (m.seq < 0) m.seq = next_seq_++;
  if (m.utime_us == 0) m.utime_us = wall_clock_utime_us();
  if (!lcm_) {
    const auto now = std::chrono::steady_clock::now();
    if (!attempted_ || now - last_attempt_ >= std::chrono::seconds(1)) {
      attempted_ = true;
      last_attempt_ = now;
      auto lcm = std::make_shared<lcm::LCM>(url_);
      if (lcm->good()) {
        lcm_ = std::move(lcm);
      } else if (counters_.failures == 0) {
        spdlog::warn("LCM preview: cannot create LCM on {}; previews are dropped until it works",
                     effective_lcm_url(url_));
      }
    }
  }
  if (!lcm_) {
    ++counters_.failures;
    return false;
  }
  const auto bytes = encode(m);
  if (lcm_->publish(channel_, bytes.data(), static_cast<unsigned int>(bytes.size())) != 0) {
    ++counters_.failures;
    return false;
  }
  ++counters_.published;
  counters_.bytes += static_cast<std::int64_t>(bytes.size());
  return true;
}

PreviewPublisherCounters PreviewPublisher::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace evpipe::transport
