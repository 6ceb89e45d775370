#pragma once
/* The C interface of libevpipe_view_output.so (video and PNG writing: OpenCV videoio and imgcodecs, which pull in
 * FFmpeg, GDAL and ~200 other libraries). evpipe loads it with dlopen only for --video / --png-every, so that a
 * normal run neither loads those nor pays their start-up (0.4 s, 60 MB). view::FrameOutput is the C++ side. */
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A BGR 8-bit image. */
struct evpipe_frame {
  const unsigned char* bgr;
  int width;
  int height;
  size_t step; /**< bytes per row */
};

/** Opens a video writer (lazily, on the first frame). NULL only when out of memory. */
void* evpipe_video_open(const char* path, double fps);
/** 0 on success; else non-zero with the reason in err. */
int evpipe_video_write(void* video, const struct evpipe_frame* frame, char* err, size_t err_size);
/** The file written (after a fallback), the codec, frames and size. */
void evpipe_video_info(void* video, char* path, size_t path_size, char* codec, size_t codec_size, long long* frames,
                       int* width, int* height);
/** Flushes, closes and frees. */
void evpipe_video_close(void* video);
/** 0 on success. */
int evpipe_png_write(const char* path, const struct evpipe_frame* frame);

#ifdef __cplusplus
}
#endif
