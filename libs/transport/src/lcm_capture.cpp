#include "evpipe/transport/lcm_capture.hpp"

#include "evpipe/transport/codec.hpp"

#include <fmt/format.h>
#include <lcm/lcm-cpp.hpp>

#include <stdexcept>
#include <utility>

namespace evpipe::transport {

struct LcmCapture::Handler {
  LcmCapture* owner;
  void on_raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    ReceivedMessage m;
    m.channel = channel;
    const auto* p = static_cast<const std::uint8_t*>(rbuf->data);
    m.data.assign(p, p + rbuf->data_size);
    m.recv_utime_us = rbuf->recv_utime;
    ++owner->received_;
    if (owner->callback_) {
      owner->callback_(m);
    }
    if (owner->keep_) {
      owner->messages_.push_back(std::move(m));
    }
  }
};

LcmCapture::LcmCapture(const std::string& url) : LcmCapture(std::make_shared<lcm::LCM>(url)) {}

LcmCapture::LcmCapture(std::shared_ptr<lcm::LCM> lcm)
    : lcm_(std::move(lcm)), handler_(std::make_unique<Handler>(Handler{this})) {}

LcmCapture::~LcmCapture() = default;

bool LcmCapture::good() const {
  return lcm_ && lcm_->good();
}

void LcmCapture::subscribe(const std::string& channel_regex) {
  if (!good()) {
    throw std::runtime_error(fmt::format("LCM capture: cannot subscribe to {}: LCM is not usable", channel_regex));
  }
  lcm_->subscribe(channel_regex, &Handler::on_raw, handler_.get());
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
