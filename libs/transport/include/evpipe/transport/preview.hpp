#pragma once
// The preview message (preview_t on EVPIPE_PREVIEW, docs/operations.md "Watching the pipeline"): the plain record,
// its codec (class image packed 2 bits a pixel or run-length coded, whichever is smaller) and a publisher with its
// own LCM instance, so that a preview's send never holds the lock the pose publisher takes.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lcm {
class LCM;
}

namespace evpipe::transport {

inline constexpr std::string_view kDefaultPreviewChannel = "EVPIPE_PREVIEW";

/// Pixel classes of the preview image (preview_t).
enum class PreviewPixel : std::uint8_t { none = 0, raw = 1, kept_on = 2, kept_off = 3 };

/// Status values on the wire (pose_t.STATUS_*). 3 = holding (pose_t gains STATUS_HOLDING = 3): named here by value
/// so that the preview works whether or not this build's pose_t knows it yet.
inline constexpr std::int8_t kPreviewStatusInitialising = 0;
inline constexpr std::int8_t kPreviewStatusTracking = 1;
inline constexpr std::int8_t kPreviewStatusLost = 2;
inline constexpr std::int8_t kPreviewStatusHolding = 3;
[[nodiscard]] std::string_view preview_status_name(std::int8_t status) noexcept;

struct PreviewSegment {
  float x0_px{0}, y0_px{0}, x1_px{0}, y1_px{0};
};

struct PreviewRecord {
  std::int64_t seq{-1};      ///< -1 = assigned by the publisher
  std::int64_t utime_us{0};  ///< 0 = set when published
  std::int64_t t_us{0};
  std::int64_t window_t0_us{0};
  std::int64_t window_t1_us{0};
  std::int8_t status{kPreviewStatusInitialising};
  bool pose_valid{false};
  std::int32_t raw_events{0};
  std::int32_t kept_events{0};
  std::int32_t pose_events{0};
  std::int32_t inliers{0};
  float sigma_px{0};
  float latency_ms{0};
  float latency_p99_ms{0};
  std::int64_t queue_drops{0};
  std::int64_t previews_dropped{0};
  int width{0};                      ///< image columns (binned)
  int height{0};                     ///< image rows (binned)
  int bin{1};                        ///< sensor pixels per image pixel along each axis
  std::vector<std::uint8_t> pixels;  ///< width * height PreviewPixel codes, row-major
  std::vector<PreviewSegment> segments;
  std::string note;

  [[nodiscard]] double inlier_share() const {
    return pose_events > 0 ? static_cast<double>(inliers) / pose_events : 0.0;
  }
  [[nodiscard]] double window_s() const { return static_cast<double>(window_t1_us - window_t0_us) * 1e-6; }
};

/// The encoding the codec chose and the bytes of the image.
struct EncodedImage {
  std::int8_t encoding{0};  ///< preview_t.ENCODING_*
  std::vector<std::uint8_t> bytes;
};
/// Packs `pixels` (codes 0..3; higher bits ignored) both ways and returns the smaller.
[[nodiscard]] EncodedImage encode_preview_image(const std::vector<std::uint8_t>& pixels);
/// Throws DecodeError (codec.hpp) naming what is wrong when the bytes do not give exactly `count` pixels.
[[nodiscard]] std::vector<std::uint8_t> decode_preview_image(std::int8_t encoding, const std::uint8_t* data,
                                                             std::size_t size, std::size_t count);

[[nodiscard]] std::vector<std::uint8_t> encode(const PreviewRecord& r);
/// nullopt when the bytes are not a preview_t (fingerprint) or truncated, or a count (image_bytes, num_segments) or
/// the note's length goes beyond the bytes (checked before anything is allocated: a count that cannot fit is never
/// allocated); DecodeError for invalid content (sizes, image that does not decode to width * height pixels,
/// segment coordinates).
[[nodiscard]] std::optional<PreviewRecord> decode_preview(const void* data, std::size_t size);
/// Why bytes carrying the preview_t fingerprint are not a whole preview_t (the cases where decode_preview returns
/// nullopt for them), naming the field and its byte offset, e.g. "preview_t.image_bytes at byte 100 of 200: count
/// 268435456 needs at least ... bytes". nullopt when the bytes are a whole preview_t, or carry another fingerprint.
[[nodiscard]] std::optional<std::string> preview_wire_error(const void* data, std::size_t size);

struct PreviewPublisherCounters {
  std::int64_t published{0};
  std::int64_t failures{0};
  std::int64_t bytes{0};  ///< encoded bytes sent
};

/// Publishes previews on their own LCM instance. Not connected (no multicast route) = each publish fails and is
/// counted; the instance is re-created at most once a second. Any thread (one mutex, not shared with poses).
class PreviewPublisher {
 public:
  PreviewPublisher(std::string url, std::string channel);
  ~PreviewPublisher();
  PreviewPublisher(const PreviewPublisher&) = delete;
  PreviewPublisher& operator=(const PreviewPublisher&) = delete;

  bool publish(const PreviewRecord& r);
  [[nodiscard]] PreviewPublisherCounters counters() const;
  [[nodiscard]] const std::string& channel() const noexcept { return channel_; }

 private:
  std::string url_;
  std::string channel_;
  mutable std::mutex mutex_;
  std::shared_ptr<lcm::LCM> lcm_;
  std::chrono::steady_clock::time_point last_attempt_{};
  bool attempted_{false};
  std::int64_t next_seq_{0};
  PreviewPublisherCounters counters_;
};

}  // namespace evpipe::transport
