#include "evpipe/transport/lcm_capture.hpp"

#include "evpipe/core/file.hpp"
#include "evpipe/transport/codec.hpp"

#include <fmt/format.h>
#include <lcm/lcm-cpp.hpp>

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <utility>

namespace evpipe::transport {

// Subscriptions go through LCM's C API: GCC 12's -fsanitize=vptr (our ASan+UBSan build) miscompiles lcm-cpp's
// templated subscription callbacks (LCMMHUntypedSubscription::cb_func reads a null handler and crashes); a plain C
// callback has no vtable to check. Measured with a 15-line memq:// program; clang is not affected.
struct LcmCapture::Handler {
  LcmCapture* owner;
  std::vector<lcm_subscription_t*> subscriptions;

  static void on_raw(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
    LcmCapture* self = static_cast<Handler*>(user)->owner;
    ReceivedMessage m;
    m.channel = channel;
    const auto* p = static_cast<const std::uint8_t*>(rbuf->data);
    m.data.assign(p, p + rbuf->data_size);
    m.recv_utime_us = rbuf->recv_utime;
    ++self->received_;
    if (self->callback_) {
      self->callback_(m);
    }
    if (self->keep_) {
      self->messages_.push_back(std::move(m));
    }
  }
};

LcmCapture::LcmCapture(const std::string& url) : LcmCapture(std::make_shared<lcm::LCM>(url)) {}

LcmCapture::LcmCapture(std::shared_ptr<lcm::LCM> lcm)
    : lcm_(std::move(lcm)), handler_(std::make_unique<Handler>(Handler{this, {}})) {}

LcmCapture::~LcmCapture() {
  // A shared instance outlives us: no callback may be left pointing at this object.
  if (lcm_ && lcm_->good()) {
    for (lcm_subscription_t* sub : handler_->subscriptions) {
      lcm_unsubscribe(lcm_->getUnderlyingLCM(), sub);
    }
  }
}

bool LcmCapture::good() const {
  return lcm_ && lcm_->good();
}

void LcmCapture::subscribe(const std::string& channel_regex) {
  if (!good()) {
    throw std::runtime_error(fmt::format("LCM capture: cannot subscribe to {}: LCM is not usable", channel_regex));
  }
  lcm_subscription_t* sub =
      lcm_subscribe(lcm_->getUnderlyingLCM(), channel_regex.c_str(), &Handler::on_raw, handler_.get());
  if (sub == nullptr) {
    throw std::runtime_error(fmt::format("LCM capture: cannot subscribe to {}", channel_regex));
  }
  handler_->subscriptions.push_back(sub);
}

void LcmCapture::on_message(std::function<void(const ReceivedMessage&)> callback) {
  callback_ = std::move(callback);
}

std::size_t LcmCapture::wait_for(std::size_t count, std::chrono::milliseconds timeout) {
  if (!good()) {
    return received_;
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (received_ < count) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      break;
    }
    if (lcm_->handleTimeout(static_cast<int>(left.count())) < 0) {
      break;  // LCM error (e.g. the file:// provider reached the end of its log)
    }
  }
  return received_;
}

std::size_t LcmCapture::drain(std::chrono::milliseconds duration) {
  if (!good()) {
    return received_;
  }
  const auto deadline = std::chrono::steady_clock::now() + duration;
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0 || lcm_->handleTimeout(static_cast<int>(left.count())) < 0) {
      break;
    }
  }
  return received_;
}

std::vector<PoseRecord> LcmCapture::poses(const std::string& channel) const {
  std::vector<PoseRecord> out;
  for (const ReceivedMessage& m : messages_) {
    if (m.channel == channel) {
      if (auto r = decode_pose(m.data.data(), m.data.size())) {
        out.push_back(std::move(*r));
      }
    }
  }
  return out;
}

std::vector<StatsRecord> LcmCapture::stats(const std::string& channel) const {
  std::vector<StatsRecord> out;
  for (const ReceivedMessage& m : messages_) {
    if (m.channel == channel) {
      if (auto r = decode_stats(m.data.data(), m.data.size())) {
        out.push_back(std::move(*r));
      }
    }
  }
  return out;
}

LcmLogError::LcmLogError(const std::string& what, std::uint64_t offset, std::vector<ReceivedMessage> before)
    : std::runtime_error(what), offset_(offset), messages_(std::move(before)) {}

namespace {

// LCM's log format (lcm/eventlog.c): events back to back, each a 28-byte header (big-endian) then the channel
// name and the data. Read here rather than with liblcm's lcm_eventlog_read_next_event, which trusts the lengths
// (a data length of 0x7fffffff crashed in its fread), scans past garbage, and reports a bad event on stderr as the
// end of the log.
constexpr std::uint32_t kLogSync = 0xEDA1DA01;
constexpr std::size_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;  // sync, event number, timestamp, lengths
constexpr std::int32_t kMaxChannelBytes = 1000;               // liblcm's reader refuses longer names too

std::uint64_t big_endian(const unsigned char* p, std::size_t bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

void read_lcm_log(const std::filesystem::path& path, const std::function<void(ReceivedMessage&&)>& on_event) {
  UniqueFile f;
  std::uint64_t size = 0;
  try {
    f = open_input_file(path.string());  // a regular file (a FIFO would block)
    struct stat st {};
    if (::fstat(::fileno(f.get()), &st) != 0) {
      throw FileError(path.string(), fmt::format("cannot examine: {}", std::strerror(errno)));
    }
    size = static_cast<std::uint64_t>(st.st_size);
  } catch (const FileError& e) {
    throw std::runtime_error(fmt::format("{}: cannot open as an LCM log file: {}", path.string(), e.reason()));
  }
  std::uint64_t offset = 0;  // of the event being read
  const auto fail = [&](const std::string& why) {
    throw LcmLogError(fmt::format("{}: LCM log event at byte {}: {}", path.string(), offset, why), offset);
  };
  const auto read_bytes = [&](void* buf, std::size_t n, std::string_view what) {
    if (n != 0 && std::fread(buf, 1, n, f.get()) != n) {
      fail(std::ferror(f.get()) != 0 ? fmt::format("cannot read its {}: {}", what, std::strerror(errno))
                                     : fmt::format("the file ended in its {} (it shrank while being read)", what));
    }
  };
  while (offset < size) {
    const std::uint64_t left = size - offset;
    std::array<unsigned char, kEventHeaderBytes> h{};
    const std::size_t have = static_cast<std::size_t>(std::min<std::uint64_t>(left, h.size()));
    read_bytes(h.data(), have, "header");
    const std::size_t sync_bytes = std::min<std::size_t>(have, 4);
    if (big_endian(h.data(), sync_bytes) != (kLogSync >> (8 * (4 - sync_bytes)))) {
      if (offset == 0) {
        throw LcmLogError(
            fmt::format("{}: not an LCM log file (no LCM event sync word 0xEDA1DA01 at byte 0)", path.string()), 0);
      }
      fail(fmt::format("no event sync word 0xEDA1DA01 (found 0x{:0{}X}): the log is corrupt here",
                       big_endian(h.data(), sync_bytes), 2 * sync_bytes));
    }
    if (have < h.size()) {
      fail(fmt::format("truncated: the file ends {} bytes into the {}-byte event header", have, h.size()));
    }
    const auto channel_len = static_cast<std::int32_t>(static_cast<std::uint32_t>(big_endian(h.data() + 20, 4)));
    const auto data_len = static_cast<std::int32_t>(static_cast<std::uint32_t>(big_endian(h.data() + 24, 4)));
    if (channel_len <= 0 || channel_len >= kMaxChannelBytes) {
      fail(fmt::format("channel name length {} (1 to {} bytes): the log is corrupt here", channel_len,
                       kMaxChannelBytes - 1));
    }
    if (data_len < 0) {
      fail(fmt::format("negative data length {}: the log is corrupt here", data_len));
    }
    const std::uint64_t body = static_cast<std::uint64_t>(channel_len) + static_cast<std::uint64_t>(data_len);
    if (body > left - h.size()) {
      fail(
          fmt::format("truncated or corrupt: channel name and data are {} + {} bytes, the file has {} after the header",
                      channel_len, data_len, left - h.size()));
    }
    ReceivedMessage m;
    m.recv_utime_us = static_cast<std::int64_t>(big_endian(h.data() + 12, 8));
    m.channel.resize(static_cast<std::size_t>(channel_len));
    read_bytes(m.channel.data(), m.channel.size(), "channel name");
    m.data.resize(static_cast<std::size_t>(data_len));
    read_bytes(m.data.data(), m.data.size(), "data");
    offset += h.size() + body;
    on_event(std::move(m));
  }
}

std::vector<ReceivedMessage> read_lcm_log(const std::filesystem::path& path) {
  std::vector<ReceivedMessage> out;
  try {
    read_lcm_log(path, [&](ReceivedMessage&& m) { out.push_back(std::move(m)); });
  } catch (const LcmLogError& e) {
    throw LcmLogError(e.what(), e.offset(), std::move(out));
  }
  return out;
}

}  // namespace evpipe::transport
