// What the routes hand to the render thread (a RenderJob) and what comes back (a RenderResult).
// Plain values: they cross threads by move, and nothing in them points anywhere.
#pragma once

#include <cstdint>
#include <string>

#include "plantview/render.h"
#include "server/http.h"

namespace plantview::service {

struct RenderJob {
  enum class Kind { frame, stats, pick } kind = Kind::frame;
  Camera camera;                    // valid (validate_camera) when the routes made it
  uint32_t width = 0, height = 0;   // pixels, 1..4096
  ImageFormat format = ImageFormat::jpeg;
  int quality = 85;                 // 1..100, JPEG only
  LodPolicy policy = LodPolicy::screen_space;
  double pixel_error = 1.0;         // pixels, (0, 1000]
  uint32_t x = 0, y = 0;            // pick: a pixel inside width x height
  std::string client;               // latest-wins key: a waiting job with the same key is replaced
  uint64_t ticket = 0;              // the response it answers (the loop's bookkeeping)
};

struct RenderResult {
  uint64_t ticket = 0;
  int status = 200;
  std::string content_type;
  std::string body;
  Fields headers;
  bool rendered = false;  // stats below are meaningful
  FrameStats stats;
  // Frames: the pixels, encoded off the render thread (encoding.h) so that the next frame
  // renders while this one encodes. body is empty until then.
  bool needs_encoding = false;
  Image image;
  ImageFormat format = ImageFormat::jpeg;
  int quality = 85;
};

}  // namespace plantview::service
