// The frame stream's messages and per-stream policies (docs/stream.md, protocol v1): what the
// client sends (hello, view, ack, key), the binary frame the server sends, the bit rate a
// stream's video aims at, and the video encoder. The server (server.cpp) joins them to a
// WebSocket connection and the render worker.
//
// Rules
//   - Messages: JSON text. A message that is not JSON, not an object, of an unknown type, or a
//     view whose params are not an object of string or number values (arrays of them for the
//     repeatable `clip`) is refused with a message naming what was wrong; the stream stays open.
//   - A view's params become /api/frame query fields (numbers written as JSON writes them), and
//     go through the same routes as /api/frame (routes.h): the same parameters and errors.
//   - Frames: "PVF1", the header's length (u32 little-endian), the JSON header, the payload.
//   - Bit rate (BitrateControl): starts at kStartKbps (or the client's max_kbps if lower), never
//     below kMinKbps or above max_kbps. From each ack's round trip (frame sent to ack received):
//     the least round trip seen is the link's; an ack later than that by more than
//     kQueueDelayMs says frames queue on the link, and the target drops by 15% (at most once per
//     500 ms); acks on time raise it by 5% (at most once per second). The window (2 frames in
//     flight) keeps a slow link from queueing more than two frames whatever the target.
// Threads: parsing, packing and BitrateControl are pure, for the loop thread; a VideoEncoder is
// used by one thread at a time (the server encodes on libuv's pool, one frame of a stream at a
// time).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "plantview/image.h"
#include "server/http.h"

namespace plantview::service {

enum class StreamCodec { jpeg, h264, vp8 };
const char* codec_name(StreamCodec codec);
bool codec_from_name(std::string_view name, StreamCodec& codec);

struct ClientMessage {
  enum class Type { hello, view, ack, key } type = Type::view;
  // hello
  std::string token;
  bool has_token = false;
  std::string codec;  // as sent; "" if not given
  uint32_t max_kbps = 0;  // 0: not given
  // view
  uint64_t seq = 0;
  bool has_seq = false;
  Fields params;
  // ack
  uint64_t frame = 0;
};

// False with `error` (naming what was wrong) and, if the message was a view with a seq, `seq`.
bool parse_client_message(std::string_view text, ClientMessage& message, std::string& error);

// {"type":"error","message":...[,"seq":n]}
std::string error_message(std::string_view message, const uint64_t* seq = nullptr);

// A binary frame message: "PVF1", the header length, `header_json`, `payload`.
std::string pack_frame(std::string_view header_json, std::string_view payload);

class BitrateControl {
 public:
  static constexpr uint32_t kStartKbps = 8000, kMinKbps = 250, kDefaultMaxKbps = 20000;
  static constexpr double kQueueDelayMs = 120;

  explicit BitrateControl(uint32_t max_kbps = 0);
  // An ack `round_trip_ms` after its frame was sent, at `now_ms`.
  void on_ack(double round_trip_ms, uint64_t now_ms);
  uint32_t target_kbps() const { return kbps_; }

 private:
  uint32_t kbps_, max_kbps_;
  double least_round_trip_ms_ = -1;
  uint64_t last_change_ms_ = 0;
};

// One stream's video encoder (libavcodec: libx264 or libvpx's VP8) in low-latency settings: no
// B-frames, no look-ahead, a key frame every ~2 s of frames (kKeyInterval) and whenever asked.
// A frame of another size than the last makes a new encoder (and so a key frame).
class VideoEncoder {
 public:
  static constexpr int kKeyInterval = 20;  // frames (about 2 s at 10 frames a second)
  // Null with `error` when the codec's encoder is not in this libavcodec.
  static std::unique_ptr<VideoEncoder> create(StreamCodec codec, std::string& error);
  virtual ~VideoEncoder() = default;
  // Encodes `image` (RGBA, its size even or not: odd sides lose their last row or column) into
  // one access unit (H.264 Annex B or a VP8 frame). `key`: make it a key frame; set to whether
  // it is one. `kbps`: the target bit rate. False with `error`.
  virtual bool encode(const Image& image, uint32_t kbps, bool& key, std::string& out, std::string& error) = 0;
  // The size of the last frame encoded.
  virtual uint32_t width() const = 0;
  virtual uint32_t height() const = 0;
};

// Whether this libavcodec has an encoder for the codec (libx264, libvpx).
bool codec_available(StreamCodec codec);

}  // namespace plantview::service
