#include "evpipe/transport/lcm_capture.hpp"

#include "evpipe/core/file.hpp"
#include "evpipe/transport/codec.hpp"

#include <fmt/format.h>
#include <lcm/lcm-cpp.hpp>

#include <cstdio>
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

std::vector<ReceivedMessage> read_lcm_log(const std::filesystem::path& path) {
  // A regular file (a FIFO would block LCM's fopen) that starts with an event's sync word: LCM's reader would
  // otherwise scan any file for one and report no events.
  std::string head;
  try {
    auto f = open_input_file(path.string());
    head.resize(4);
    head.resize(std::fread(head.data(), 1, head.size(), f.get()));
  } catch (const FileError& e) {
    throw std::runtime_error(fmt::format("{}: cannot open as an LCM log file: {}", path.string(), e.reason()));
  }
  constexpr std::string_view kSync("\xED\xA1\xDA\x01", 4);  // LCM's event sync word, big-endian
  if (!head.empty() && head != kSync) {
    throw std::runtime_error(
        fmt::format("{}: not an LCM log file (no LCM event sync word 0xEDA1DA01 at byte 0)", path.string()));
  }
  lcm::LogFile log(path.string(), "r");
  if (!log.good()) {
    throw std::runtime_error(fmt::format("{}: cannot open as an LCM log file", path.string()));
  }
  std::vector<ReceivedMessage> out;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    ReceivedMessage m;
    m.channel = e->channel;
    const auto* p = static_cast<const std::uint8_t*>(e->data);
    m.data.assign(p, p + e->datalen);
    m.recv_utime_us = e->timestamp;
    out.push_back(std::move(m));
  }
  return out;
}

}  // namespace evpipe::transport
