// libevpipe_view_output.so: the C interface of output_module.h over view::VideoOut and cv::imwrite.
#include "evpipe/view/output_module.h"

#include <cstdio>
#include <exception>
#include <new>
#include <opencv2/imgcodecs.hpp>

#include "evpipe/view/video.hpp"

namespace {

cv::Mat wrap(const evpipe_frame* f) {
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-const-cast): read only (cv::Mat has no const view)
  return {f->height, f->width, CV_8UC3, const_cast<unsigned char*>(f->bgr), f->step};
}

}  // namespace

extern "C" {

void* evpipe_video_open(const char* path, double fps) {
  return new (std::nothrow) evpipe::view::VideoOut(path, fps);
}

int evpipe_video_write(void* video, const evpipe_frame* frame, char* err, size_t err_size) {
  try {
    static_cast<evpipe::view::VideoOut*>(video)->write(wrap(frame));
    return 0;
  } catch (const std::exception& e) {
    if (err_size > 0) std::snprintf(err, err_size, "%s", e.what());
    return 1;
  }
}

void evpipe_video_info(void* video, char* path, size_t path_size, char* codec, size_t codec_size, long long* frames,
                       int* width, int* height) {
  const auto* v = static_cast<evpipe::view::VideoOut*>(video);
  if (path_size > 0) std::snprintf(path, path_size, "%s", v->path().c_str());
  if (codec_size > 0) std::snprintf(codec, codec_size, "%s", v->codec().c_str());
  *frames = v->frames();
  *width = v->size().width;
  *height = v->size().height;
}

void evpipe_video_close(void* video) {
  delete static_cast<evpipe::view::VideoOut*>(video);
}

int evpipe_png_write(const char* path, const evpipe_frame* frame) {
  try {
    return cv::imwrite(path, wrap(frame)) ? 0 : 1;
  } catch (const std::exception&) {
    return 1;
  }
}

}  // extern "C"
