// Frame encoding, handed off the render thread: the render thread goes on with the next frame
// while a pool thread (libuv's) turns this one's pixels into JPEG or PNG bytes.
// Threads: any; a result is encoded by one thread at a time, and nothing is shared.
// Errors: a frame that cannot be encoded becomes a 500 answer with the image module's message.
#pragma once

#include "server/render_job.h"

namespace plantview::service {

// Encodes result.image (result.needs_encoding) into result.body in result.format, frees the
// pixels and adds the X-Encode-Ms header (stats.ms.encode, milliseconds).
void encode_frame(RenderResult& result);

}  // namespace plantview::service
