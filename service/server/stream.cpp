// Rules: stream.h.
#include "server/stream.h"

#include <algorithm>
#include <cstring>
#include <nlohmann/json.hpp>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

namespace plantview::service {

const char* codec_name(StreamCodec codec) {
  switch (codec) {
    case StreamCodec::h264: return "h264";
    case StreamCodec::vp8: return "vp8";
    case StreamCodec::jpeg: break;
  }
  return "jpeg";
}

bool codec_from_name(std::string_view name, StreamCodec& codec) {
  if (name == "jpeg") codec = StreamCodec::jpeg;
  else if (name == "h264") codec = StreamCodec::h264;
  else if (name == "vp8") codec = StreamCodec::vp8;
  else return false;
  return true;
}

// --- messages -----------------------------------------------------------------------------------

namespace {

using nlohmann::json;

// A param's value as /api/frame's query would carry it; false if it is not a string or number.
bool param_text(const json& value, std::string& out) {
  if (value.is_string()) out = value.get<std::string>();
  else if (value.is_number_integer() || value.is_number_unsigned()) out = value.dump();
  else if (value.is_number_float()) out = value.dump();
  else return false;
  return true;
}

bool read_params(const json& params, Fields& out, std::string& error) {
  if (!params.is_object()) {
    error = "'params' must be an object of /api/frame parameters";
    return false;
  }
  for (const auto& [key, value] : params.items()) {
    std::string text;
    if (value.is_array()) {
      // clip: one plane per element; any other key: its numbers joined by commas (eye: [x,y,z]).
      std::string joined;
      for (const json& element : value) {
        std::string part;
        if (element.is_array() && key == "clip") {
          for (const json& number : element) {
            std::string n;
            if (!param_text(number, n)) {
              error = "param '" + key + "' has a value that is neither a string nor a number";
              return false;
            }
            part += (part.empty() ? "" : ",") + n;
          }
        } else if (!param_text(element, part)) {
          error = "param '" + key + "' has a value that is neither a string nor a number";
          return false;
        }
        if (key == "clip") out.emplace_back(key, part);
        else joined += (joined.empty() ? "" : ",") + part;
      }
      if (key != "clip") out.emplace_back(key, joined);
      continue;
    }
    if (!param_text(value, text)) {
      error = "param '" + key + "' must be a string or a number";
      return false;
    }
    out.emplace_back(key, std::move(text));
  }
  return true;
}

bool read_count(const json& message, const char* key, uint64_t& out, std::string& error) {
  const auto it = message.find(key);
  if (it == message.end() || !it->is_number_unsigned()) {
    if (it != message.end() && it->is_number_integer() && it->get<int64_t>() >= 0) {
      out = uint64_t(it->get<int64_t>());
      return true;
    }
    error = std::string("'") + key + "' must be a whole number >= 0";
    return false;
  }
  out = it->get<uint64_t>();
  return true;
}

}  // namespace

bool parse_client_message(std::string_view text, ClientMessage& m, std::string& error) {
  m = ClientMessage{};
  const json message = json::parse(text, nullptr, false);
  if (message.is_discarded()) {
    error = "the message is not JSON";
    return false;
  }
  if (!message.is_object() || !message.contains("type") || !message["type"].is_string()) {
    error = "the message must be a JSON object with a string 'type'";
    return false;
  }
  const std::string type = message["type"].get<std::string>();
  if (type == "hello") {
    m.type = ClientMessage::Type::hello;
    if (const auto it = message.find("token"); it != message.end()) {
      if (!it->is_string()) {
        error = "'token' must be a string";
        return false;
      }
      m.token = it->get<std::string>();
      m.has_token = true;
    }
    if (const auto it = message.find("codec"); it != message.end()) {
      if (!it->is_string()) {
        error = "'codec' must be a string: jpeg, h264 or vp8";
        return false;
      }
      m.codec = it->get<std::string>();
    }
    if (message.contains("max_kbps")) {
      uint64_t kbps = 0;
      if (!read_count(message, "max_kbps", kbps, error)) return false;
      m.max_kbps = uint32_t(std::min<uint64_t>(kbps, 1000000));
    }
    return true;
  }
  if (type == "view") {
    m.type = ClientMessage::Type::view;
    if (message.contains("seq")) {
      if (!read_count(message, "seq", m.seq, error)) return false;
      m.has_seq = true;
    }
    if (!m.has_seq) {
      error = "a view needs a 'seq' (a whole number)";
      return false;
    }
    const auto it = message.find("params");
    if (it == message.end()) {
      error = "a view needs 'params' (the /api/frame parameters)";
      return false;
    }
    return read_params(*it, m.params, error);
  }
  if (type == "ack") {
    m.type = ClientMessage::Type::ack;
    return read_count(message, "frame", m.frame, error);
  }
  if (type == "key") {
    m.type = ClientMessage::Type::key;
    return true;
  }
  error = "unknown message type '" + type.substr(0, 64) + "' (hello, view, ack or key)";
  return false;
}

std::string error_message(std::string_view message, const uint64_t* seq) {
  json m = {{"type", "error"}, {"message", std::string(message)}};
  if (seq) m["seq"] = *seq;
  return m.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string pack_frame(std::string_view header_json, std::string_view payload) {
  std::string out;
  out.reserve(8 + header_json.size() + payload.size());
  out += "PVF1";
  const uint32_t n = uint32_t(header_json.size());
  for (int k = 0; k < 4; ++k) out += char((n >> (8 * k)) & 0xFF);
  out += header_json;
  out += payload;
  return out;
}

// --- bit rate -----------------------------------------------------------------------------------

BitrateControl::BitrateControl(uint32_t max_kbps)
    : max_kbps_(max_kbps ? std::max(max_kbps, kMinKbps) : kDefaultMaxKbps) {
  kbps_ = std::min(kStartKbps, max_kbps_);
}

void BitrateControl::on_ack(double round_trip_ms, uint64_t now_ms) {
  if (least_round_trip_ms_ < 0 || round_trip_ms < least_round_trip_ms_) least_round_trip_ms_ = round_trip_ms;
  const uint64_t since = now_ms - last_change_ms_;
  if (round_trip_ms > least_round_trip_ms_ + kQueueDelayMs) {
    if (since < 500) return;
    kbps_ = std::max(kMinKbps, uint32_t(kbps_ * 0.85));
    last_change_ms_ = now_ms;
  } else if (since >= 1000) {
    kbps_ = std::min(max_kbps_, std::max(kbps_ + 1, uint32_t(kbps_ * 1.05)));
    last_change_ms_ = now_ms;
  }
}

// --- video --------------------------------------------------------------------------------------

namespace {

// Quality levels: x264's CRF (0..51) and libvpx's constrained quality (cq-level, 0..63), set so
// that a moving frame has at least the PSNR of a JPEG at quality 60 (measured on preset c at
// 1280x720 along a walk, docs/stream.md: x264 veryfast CRF 27 34% of the JPEG's bytes, VP8 at
// cq-level 45..48 about two thirds).
constexpr const char* kCrfH264 = "27";
constexpr const char* kCrfVp8 = "48";
// x264's preset: veryfast, not ultrafast: on these renders (thin, aliased pipes) ultrafast needed
// 68% of the JPEG's bytes for its PSNR, veryfast 34%, for about twice the encode time (15 ms to
// 25-45 ms a 720p frame on 2 busy cores).
constexpr const char* kPresetH264 = "veryfast";
constexpr double kVbvSeconds = 0.2;  // two frames at the nominal 10 frames/s

const char* encoder_name(StreamCodec codec) { return codec == StreamCodec::h264 ? "libx264" : "libvpx"; }

std::string av_error(int rc) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(rc, text, sizeof text);
  return text;
}

class AvEncoder final : public VideoEncoder {
 public:
  explicit AvEncoder(StreamCodec codec) : codec_(codec) {}
  ~AvEncoder() override { reset(); }

  bool encode(const Image& image, uint32_t kbps, bool& key, std::string& out, std::string& error) override {
    out.clear();
    const uint32_t w = std::max(2u, image.width & ~1u), h = std::max(2u, image.height & ~1u);
    if (image.width < 2 || image.height < 2) {
      error = "video: a frame needs at least 2 x 2 pixels";
      return false;
    }
    // VP8 here takes its bit rate when it opens: a change of over a quarter opens it anew.
    const bool rate_moved = codec_ == StreamCodec::vp8 && kbps_ != 0 &&
                            (kbps > kbps_ * 5 / 4 || kbps < kbps_ * 3 / 4);
    if (!context_ || w != width_ || h != height_ || rate_moved) {
      reset();
      if (!open(w, h, kbps, error)) return false;
      key = true;
    } else if (kbps != kbps_) {
      // libx264 reconfigures its VBV when these change between frames.
      context_->rc_max_rate = int64_t(kbps) * 1000;
      context_->rc_buffer_size = int(context_->rc_max_rate * kVbvSeconds);
      kbps_ = kbps;
    }
    sws_ = sws_getCachedContext(sws_, int(image.width), int(image.height), AV_PIX_FMT_RGBA, int(w), int(h),
                                AV_PIX_FMT_YUV420P, SWS_BILINEAR, nullptr, nullptr, nullptr);
    if (!sws_) {
      error = "video: no RGB to YUV conversion for this size";
      return false;
    }
    int rc = av_frame_make_writable(frame_);
    if (rc < 0) {
      error = "video: " + av_error(rc);
      return false;
    }
    const uint8_t* source[1] = {image.rgba.data()};
    const int stride[1] = {int(image.width * 4)};
    sws_scale(sws_, source, stride, 0, int(image.height), frame_->data, frame_->linesize);
    frame_->pts = next_pts_++;
    frame_->pict_type = key ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
    rc = avcodec_send_frame(context_, frame_);
    if (rc < 0) {
      error = "video: " + av_error(rc);
      return false;
    }
    key = false;
    for (;;) {
      rc = avcodec_receive_packet(context_, packet_);
      if (rc == AVERROR(EAGAIN) || rc == AVERROR_EOF) break;
      if (rc < 0) {
        error = "video: " + av_error(rc);
        return false;
      }
      out.append(reinterpret_cast<const char*>(packet_->data), size_t(packet_->size));
      key = key || (packet_->flags & AV_PKT_FLAG_KEY);
      av_packet_unref(packet_);
    }
    if (out.empty()) {
      error = std::string("video: ") + encoder_name(codec_) + " held the frame back";
      return false;
    }
    return true;
  }
  uint32_t width() const override { return width_; }
  uint32_t height() const override { return height_; }

 private:
  bool open(uint32_t w, uint32_t h, uint32_t kbps, std::string& error) {
    const AVCodec* codec = avcodec_find_encoder_by_name(encoder_name(codec_));
    if (!codec) {
      error = std::string("video: this libavcodec has no ") + encoder_name(codec_);
      return false;
    }
    context_ = avcodec_alloc_context3(codec);
    context_->width = int(w);
    context_->height = int(h);
    context_->pix_fmt = AV_PIX_FMT_YUV420P;
    // A nominal 10 frames a second: the rate control's bits per frame are kbps / 10.
    context_->time_base = {1, 10};
    context_->framerate = {10, 1};
    context_->gop_size = kKeyInterval;
    context_->max_b_frames = 0;
    // Constant quality, capped: a frame costs what its picture needs (kCrf), and the target is
    // a ceiling (VBV of kVbvSeconds), so a slow link lowers quality rather than queueing.
    context_->rc_max_rate = int64_t(kbps) * 1000;
    context_->rc_buffer_size = int(context_->rc_max_rate * kVbvSeconds);
    // One thread: the encoders of all streams already run side by side on libuv's pool, and on
    // busy cores libvpx with 2 threads took 5 times as long (250 ms against 45 ms a 720p frame).
    context_->thread_count = 1;
    AVDictionary* options = nullptr;
    if (codec_ == StreamCodec::h264) {
      av_dict_set(&options, "preset", kPresetH264, 0);
      av_dict_set(&options, "tune", "zerolatency", 0);
      av_dict_set(&options, "forced-idr", "1", 0);
      av_dict_set(&options, "crf", kCrfH264, 0);
    } else {
      // libvpx's constrained quality: the bit rate is the ceiling, crf the quality level.
      context_->bit_rate = context_->rc_max_rate;
      av_dict_set(&options, "crf", kCrfVp8, 0);
      av_dict_set(&options, "deadline", "realtime", 0);
      av_dict_set(&options, "cpu-used", "12", 0);
      av_dict_set(&options, "lag-in-frames", "0", 0);
      av_dict_set(&options, "auto-alt-ref", "0", 0);
    }
    const int rc = avcodec_open2(context_, codec, &options);
    av_dict_free(&options);
    if (rc < 0) {
      error = std::string("video: cannot open ") + encoder_name(codec_) + ": " + av_error(rc);
      reset();
      return false;
    }
    frame_ = av_frame_alloc();
    packet_ = av_packet_alloc();
    frame_->format = AV_PIX_FMT_YUV420P;
    frame_->width = int(w);
    frame_->height = int(h);
    if (av_frame_get_buffer(frame_, 0) < 0) {
      error = "video: out of memory for a frame";
      reset();
      return false;
    }
    width_ = w;
    height_ = h;
    kbps_ = kbps;
    return true;
  }

  void reset() {
    if (context_) avcodec_free_context(&context_);
    if (frame_) av_frame_free(&frame_);
    if (packet_) av_packet_free(&packet_);
    if (sws_) sws_freeContext(sws_);
    sws_ = nullptr;
    width_ = height_ = kbps_ = 0;
  }

  StreamCodec codec_;
  AVCodecContext* context_ = nullptr;
  AVFrame* frame_ = nullptr;
  AVPacket* packet_ = nullptr;
  SwsContext* sws_ = nullptr;
  uint32_t width_ = 0, height_ = 0, kbps_ = 0;
  int64_t next_pts_ = 0;
};

}  // namespace

bool codec_available(StreamCodec codec) {
  return codec == StreamCodec::jpeg || avcodec_find_encoder_by_name(encoder_name(codec)) != nullptr;
}

std::unique_ptr<VideoEncoder> VideoEncoder::create(StreamCodec codec, std::string& error) {
  if (codec == StreamCodec::jpeg || !codec_available(codec)) {
    error = std::string("video: no encoder for ") + codec_name(codec);
    return nullptr;
  }
  // libavcodec's encoders log every open and close on stderr: errors only.
  static const bool quiet = [] {
    av_log_set_level(AV_LOG_ERROR);
    return true;
  }();
  (void)quiet;
  return std::make_unique<AvEncoder>(codec);
}

}  // namespace plantview::service
