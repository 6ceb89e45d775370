#include "evpipe/view/output.hpp"

#include <dlfcn.h>
#include <fmt/format.h>
#include <unistd.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "evpipe/view/output_module.h"

namespace evpipe::view {

struct OutputModule {
  void* handle = nullptr;
  decltype(&evpipe_video_open) video_open = nullptr;
  decltype(&evpipe_video_write) video_write = nullptr;
  decltype(&evpipe_video_info) video_info = nullptr;
  decltype(&evpipe_video_close) video_close = nullptr;
  decltype(&evpipe_png_write) png_write = nullptr;
  ~OutputModule() {
    if (handle) dlclose(handle);
  }
};

namespace {

constexpr const char* kModule = "libevpipe_view_output.so";

std::vector<std::string> candidates() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("EVPIPE_VIEW_OUTPUT"); env && *env) out.emplace_back(env);
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back((exe.parent_path().parent_path() / "lib" / "evpipe" / kModule).string());
#ifdef EVPIPE_VIEW_OUTPUT_BUILD_PATH
  out.emplace_back(EVPIPE_VIEW_OUTPUT_BUILD_PATH);
#endif
  out.emplace_back(kModule);  // the loader's own search (LD_LIBRARY_PATH, ld.so.cache)
  return out;
}

template <typename F>
void bind(OutputModule& m, F& fn, const char* name) {
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-reinterpret-cast): dlsym gives a data pointer
  fn = reinterpret_cast<F>(dlsym(m.handle, name));
  if (!fn) throw std::runtime_error(fmt::format("{}: no symbol {}", kModule, name));
}

cv::Mat continuous_bgr(const cv::Mat& img) {
  if (img.type() != CV_8UC3) throw std::invalid_argument("FrameOutput: frames must be CV_8UC3 (BGR)");
  return img;
}

evpipe_frame frame_of(const cv::Mat& m) {
  return {m.data, m.cols, m.rows, m.step[0]};
}

}  // namespace

FrameOutput::FrameOutput() : module_(std::make_unique<OutputModule>()) {
  std::string tried;
  for (const auto& path : candidates()) {
    if (path.find('/') != std::string::npos && !std::filesystem::exists(path)) {
      tried += fmt::format("\n  {}: not there", path);
      continue;
    }
    module_->handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (module_->handle) break;
    tried += fmt::format("\n  {}: {}", path, dlerror());
  }
  if (!module_->handle)
    throw std::runtime_error(
        fmt::format("cannot load {} (video and PNG output; set EVPIPE_VIEW_OUTPUT to its path):{}", kModule, tried));
  bind(*module_, module_->video_open, "evpipe_video_open");
  bind(*module_, module_->video_write, "evpipe_video_write");
  bind(*module_, module_->video_info, "evpipe_video_info");
  bind(*module_, module_->video_close, "evpipe_video_close");
  bind(*module_, module_->png_write, "evpipe_png_write");
}

FrameOutput::~FrameOutput() {
  close_video();
}

void FrameOutput::open_video(const std::string& path, double fps) {
  close_video();
  video_ = module_->video_open(path.c_str(), fps);
  if (!video_) throw std::runtime_error(fmt::format("{}: cannot create a video writer", path));
}

void FrameOutput::write_video(const cv::Mat& bgr) {
  if (!video_) throw std::logic_error("FrameOutput::write_video without open_video");
  const cv::Mat m = continuous_bgr(bgr);
  const evpipe_frame f = frame_of(m);
  std::array<char, 512> err{};
  if (module_->video_write(video_, &f, err.data(), err.size()) != 0) throw std::runtime_error(err.data());
}

FrameOutput::VideoInfo FrameOutput::video_info() const {
  if (!video_) return last_info_;
  VideoInfo info;
  std::array<char, 4096> path{};
  std::array<char, 128> codec{};
  long long frames = 0;
  module_->video_info(video_, path.data(), path.size(), codec.data(), codec.size(), &frames, &info.width, &info.height);
  info.path = path.data();
  info.codec = codec.data();
  info.frames = frames;
  return info;
}

void FrameOutput::close_video() {
  if (!video_) return;
  last_info_ = video_info();
  module_->video_close(video_);
  video_ = nullptr;
}

void FrameOutput::write_png(const std::string& path, const cv::Mat& bgr) {
  const cv::Mat m = continuous_bgr(bgr);
  const evpipe_frame f = frame_of(m);
  if (module_->png_write(path.c_str(), &f) != 0) throw std::runtime_error(fmt::format("{}: cannot write PNG", path));
}

}  // namespace evpipe::view
