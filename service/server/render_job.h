// What the routes hand to the render workers (a RenderJob) and what comes back (a RenderResult).
// Plain values: they cross threads by move, and nothing in them points anywhere.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "plantview/render.h"
#include "server/http.h"

namespace plantview::service {

// What a frame asks of its quality (`mode` on /api/frame). Interactive frames may be rendered
// cheaper while requests wait for the renderers (render_worker.h: choose_degradation); a still
// is never degraded, only queued, and is antialiased where the renderer offers it.
enum class FrameMode { still, interactive };

struct RenderJob {
  enum class Kind { frame, stats, pick } kind = Kind::frame;
  Camera camera;                    // valid (validate_camera) when the routes made it
  uint32_t width = 0, height = 0;   // pixels, 1..4096: what the client asked for
  ImageFormat format = ImageFormat::jpeg;
  int quality = 85;                 // 1..100, JPEG only
  LodPolicy policy = LodPolicy::screen_space;
  double pixel_error = 1.0;         // pixels, (0, 1000]
  FrameMode mode = FrameMode::still;  // frames only; stats and picks are never degraded
  uint32_t x = 0, y = 0;            // pick: a pixel inside width x height
  // What the view shows besides its camera (view_filters.h), valid when the routes made it:
  // clip= and box= (caps= is section.capped), colour_by=, hide=, only=.
  Section section;
  ObjectStyle style;
  // highlight=: object ids or tags, resolved by the render worker through its renderer's read
  // view (object_words.h); empty: nothing highlighted.
  std::vector<std::string> highlight;
  // changes=R1[..R2]: a change image (render.h: RenderOptions::changes); whether the store
  // can draw it is the render worker's to say (422).
  std::optional<ChangeRange> changes;
  // The latest-wins slot (routes.h: a connection's, or the one an issued client id names): the
  // unit of round-robin, and with `kind` the key a newer job replaces a waiting one by. Never
  // empty in a job the routes made.
  std::string client;
  std::string client_id;            // the id that names `client`, sent back as X-Plantview-Client
  uint64_t ticket = 0;              // the response it answers (the loop's bookkeeping)
};

// How a job was rendered, chosen by the worker when it takes the job (render_worker.h).
struct Degradation {
  double pixel_error_factor = 1;  // the job's pixel error times this
  uint32_t size_divisor = 1;      // both sides divided by this (at least 1 pixel each)
  bool any() const { return pixel_error_factor != 1 || size_divisor != 1; }
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
