#include "server/encoding.h"

#include <chrono>
#include <cstdio>
#include <vector>

namespace plantview::service {

void encode_frame(RenderResult& result) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<uint8_t> bytes;
  std::string error;
  if (!encode_image(result.image, result.format, result.quality, bytes, error)) {
    result.status = 500;
    result.content_type = "application/json";
    result.body = error_body(error);
  } else {
    result.body.assign(bytes.begin(), bytes.end());
  }
  result.image = Image{};
  result.needs_encoding = false;
  result.stats.ms.encode =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  char ms[32];
  std::snprintf(ms, sizeof ms, "%.1f", result.stats.ms.encode);
  result.headers.emplace_back("X-Encode-Ms", ms);
}

}  // namespace plantview::service
