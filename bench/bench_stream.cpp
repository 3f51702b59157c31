// Frames for remote viewers over a slow link (issue 43): HTTP polling (the viewer's old way:
// request, wait, next) against the WebSocket stream (/api/stream) with JPEG and with video
// (h264, vp8), along a scripted walk, through a link shaped to 20 Mbit/s with 25 ms each way
// (stream_link.h: a network namespace, a veth pair, tc tbf both ways, a delay proxy), and on
// loopback without shaping; one viewer and four.
//
// Each viewer walks the walkthrough (make_camera_path) at 30 camera poses a second from its own
// starting pose. HTTP: it asks for the pose current when it sends (1280x720, JPEG quality 60,
// px 3, mode=interactive) and waits for the answer. Stream: it sends a view message each time
// the pose changes (30 a second), decodes each frame (libavcodec) and acknowledges it.
// Per run: frames/s delivered per viewer (mean, slowest / mean), bytes per frame, motion-to-
// photon latency (view sent to frame decoded) median and p95, the server's render and encode
// time (median), and PSNR of what arrived against a lossless render (PNG via /api/frame, the
// same parameters, on loopback after the run) of the same views: every 10th frame, at most 12,
// in one-viewer runs (four viewers are measured for fairness).
//
// Usage: bench_stream [--quick] [--store DIR] [--seconds S] [--size WxH] [--rate MBIT]
//                     [--delay MS] [--modes http,jpeg,h264,vp8] [--viewers 1,4]
//                     [--links shaped,loopback] [--max-kbps N] [--bin PLANTVIEW]
//   --max-kbps  the video streams' max_kbps (hello): the server's rate control aims at
//               kbps / 10 per frame, so this sets the video's bytes (and PSNR) per frame
//   --quick   preset a, 320x180, 3 s a run, loopback only, one viewer, http and jpeg (the
//             CTest smoke run; video too where the server offers it)
// The shaped link needs root (ip netns, tc): without it those runs are skipped with a message.
// Runs whose stream the server does not offer (no /api/stream, a codec it lacks) say so and
// are skipped. Prints a table, then "json: " lines, then the goals.
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/imgutils.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "plantview/render.h"
#include "plantview/store.h"
#include "stream_link.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace plantview;
using plantview::bench::connect_tcp;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

constexpr double kPosesPerSecond = 30;
constexpr int kPsnrEvery = 10, kPsnrMax = 12;  // one-viewer runs only

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(std::ceil(p * double(v.size()))) - 1)];
}

// --- the server -----------------------------------------------------------------------------------

pid_t start_server(const std::string& bin, const std::string& store, int& port) {
  int out[2];
  if (pipe(out) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    execl(bin.c_str(), bin.c_str(), "serve", "--store", store.c_str(), "--listen", "127.0.0.1:0",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  close(out[1]);
  std::string line;
  char c;
  pollfd pfd{out[0], POLLIN, 0};
  while (line.find('\n') == std::string::npos && poll(&pfd, 1, 60000) > 0 && read(out[0], &c, 1) == 1) line += c;
  close(out[0]);
  const size_t colon = line.rfind(':');
  port = colon == std::string::npos ? 0 : std::atoi(line.c_str() + colon + 1);
  return port > 0 ? pid : -1;
}

// --- bytes on a connection ----------------------------------------------------------------------

// A blocking connection with a read buffer. Reads wait at most timeout_ms (then fail).
struct Connection {
  int fd = -1;
  std::string buffer;
  explicit Connection(int f) : fd(f) {}
  ~Connection() {
    if (fd >= 0) close(fd);
  }
  bool send_all(const std::string& bytes) {
    for (size_t at = 0; at < bytes.size();) {
      const ssize_t n = send(fd, bytes.data() + at, bytes.size() - at, MSG_NOSIGNAL);
      if (n <= 0) return false;
      at += size_t(n);
    }
    return true;
  }
  // Reads more into the buffer; false on close, error or timeout.
  bool fill(int timeout_ms) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return false;
    char chunk[65536];
    const ssize_t n = recv(fd, chunk, sizeof chunk, 0);
    if (n <= 0) return false;
    buffer.append(chunk, size_t(n));
    return true;
  }
  bool need(size_t bytes, int timeout_ms) {
    while (buffer.size() < bytes)
      if (!fill(timeout_ms)) return false;
    return true;
  }
};

struct HttpReply {
  int status = 0;
  std::map<std::string, std::string> headers;  // lower-case names
  std::string body;
};

bool read_http_head(Connection& c, HttpReply& r, int timeout_ms) {
  size_t end;
  while ((end = c.buffer.find("\r\n\r\n")) == std::string::npos)
    if (!c.fill(timeout_ms)) return false;
  std::istringstream head(c.buffer.substr(0, end));
  c.buffer.erase(0, end + 4);
  std::string line;
  std::getline(head, line);
  if (line.size() < 12) return false;
  r.status = std::atoi(line.c_str() + 9);
  while (std::getline(head, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string name = line.substr(0, colon);
    for (char& ch : name) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    size_t v = colon + 1;
    while (v < line.size() && line[v] == ' ') ++v;
    r.headers[name] = line.substr(v);
  }
  return true;
}

bool http_get(Connection& c, const std::string& target, HttpReply& r, int timeout_ms = 60000) {
  r = HttpReply{};
  if (!c.send_all("GET " + target + " HTTP/1.1\r\nHost: bench\r\n\r\n")) return false;
  if (!read_http_head(c, r, timeout_ms)) return false;
  const auto it = r.headers.find("content-length");
  const size_t length = it == r.headers.end() ? 0 : size_t(std::stoull(it->second));
  if (!c.need(length, timeout_ms)) return false;
  r.body = c.buffer.substr(0, length);
  c.buffer.erase(0, length);
  return true;
}

// --- a WebSocket client (RFC 6455: masked client frames, unfragmented sends) ----------------------

std::string base64(const unsigned char* data, size_t n) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < n; i += 3) {
    const uint32_t v = uint32_t(data[i]) << 16 | (i + 1 < n ? uint32_t(data[i + 1]) << 8 : 0) |
                       (i + 2 < n ? uint32_t(data[i + 2]) : 0);
    out += k[v >> 18 & 63];
    out += k[v >> 12 & 63];
    out += i + 1 < n ? k[v >> 6 & 63] : '=';
    out += i + 2 < n ? k[v & 63] : '=';
  }
  return out;
}

class WebSocket {
 public:
  explicit WebSocket(int fd) : c_(fd) {}
  int fd() const { return c_.fd; }
  // The upgrade: 101 with subprotocol plantview.v1 offered. False with the answer's status.
  bool open(std::string& error) {
    unsigned char key[16];
    std::random_device rd;
    for (auto& b : key) b = static_cast<unsigned char>(rd());
    if (!c_.send_all("GET /api/stream HTTP/1.1\r\nHost: bench\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Key: " + base64(key, 16) + "\r\nSec-WebSocket-Version: 13\r\n"
                     "Sec-WebSocket-Protocol: plantview.v1\r\n\r\n")) {
      error = "upgrade: send failed";
      return false;
    }
    HttpReply r;
    if (!read_http_head(c_, r, 10000)) {
      error = "upgrade: no answer";
      return false;
    }
    if (r.status != 101) {
      error = "upgrade answered " + std::to_string(r.status);
      return false;
    }
    return true;
  }
  bool send(uint8_t opcode, const std::string& payload) {
    std::string frame;
    frame += char(0x80 | opcode);
    const size_t n = payload.size();
    if (n < 126) {
      frame += char(0x80 | n);
    } else if (n < 65536) {
      frame += char(0x80 | 126);
      frame += char(n >> 8);
      frame += char(n & 255);
    } else {
      frame += char(0x80 | 127);
      for (int s = 56; s >= 0; s -= 8) frame += char((uint64_t(n) >> s) & 255);
    }
    const uint32_t mask = rng_();
    const char m[4] = {char(mask), char(mask >> 8), char(mask >> 16), char(mask >> 24)};
    frame.append(m, 4);
    for (size_t i = 0; i < n; ++i) frame += char(payload[i] ^ m[i & 3]);
    return c_.send_all(frame);
  }
  bool send_text(const std::string& text) { return send(1, text); }
  // Whether a whole message is buffered or arrives within timeout_ms.
  bool readable(int timeout_ms) {
    if (complete()) return true;
    pollfd p{c_.fd, POLLIN, 0};
    return poll(&p, 1, timeout_ms) > 0;
  }
  // The next data message (text 1, binary 2); pings are answered, pongs skipped. False on a
  // close (closed = true), an error or the timeout.
  bool read(uint8_t& opcode, std::string& payload, int timeout_ms, bool& closed) {
    closed = false;
    payload.clear();
    uint8_t first_opcode = 0;
    for (;;) {
      if (!c_.need(2, timeout_ms)) return false;
      const auto* b = reinterpret_cast<const unsigned char*>(c_.buffer.data());
      const bool fin = b[0] & 0x80;
      const uint8_t op = b[0] & 15;
      const bool masked = b[1] & 0x80;
      uint64_t n = b[1] & 127;
      size_t head = 2;
      if (n == 126) head = 4;
      if (n == 127) head = 10;
      if (masked) head += 4;
      if (!c_.need(head, timeout_ms)) return false;
      b = reinterpret_cast<const unsigned char*>(c_.buffer.data());
      if (n == 126) n = uint64_t(b[2]) << 8 | b[3];
      if (n == 127) {
        n = 0;
        for (int i = 0; i < 8; ++i) n = n << 8 | b[2 + i];
      }
      if (!c_.need(head + n, timeout_ms)) return false;
      std::string data = c_.buffer.substr(head, n);
      if (masked) {
        for (size_t i = 0; i < data.size(); ++i) data[i] ^= c_.buffer[head - 4 + (i & 3)];
      }
      c_.buffer.erase(0, head + n);
      if (op == 9) {
        send(10, data);
        continue;
      }
      if (op == 10) continue;
      if (op == 8) {
        closed = true;
        return false;
      }
      if (op != 0) first_opcode = op;
      payload += data;
      if (fin) {
        opcode = first_opcode;
        return true;
      }
    }
  }
  void close_normal() {
    send(8, std::string("\x03\xe8", 2));
  }

 private:
  bool complete() const {
    const std::string& s = c_.buffer;
    if (s.size() < 2) return false;
    uint64_t n = uint8_t(s[1]) & 127;
    size_t head = 2 + ((uint8_t(s[1]) & 0x80) ? 4 : 0);
    if (n == 126) {
      if (s.size() < 4) return false;
      n = uint64_t(uint8_t(s[2])) << 8 | uint8_t(s[3]);
      head += 2;
    } else if (n == 127) {
      if (s.size() < 10) return false;
      n = 0;
      for (int i = 0; i < 8; ++i) n = n << 8 | uint8_t(s[2 + i]);
      head += 8;
    }
    return s.size() >= head + n;
  }
  Connection c_;
  std::mt19937 rng_{std::random_device{}()};
};

// --- decoding (libavcodec) ------------------------------------------------------------------------

struct Rgb {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;  // RGB, 3 bytes a pixel, rows top to bottom
};

class Decoder {
 public:
  ~Decoder() {
    if (sws_) sws_freeContext(sws_);
    av_frame_free(&frame_);
    av_packet_free(&packet_);
    avcodec_free_context(&context_);
  }
  bool open(const std::string& encoding, std::string& error) {
    encoding_ = encoding;
    const AVCodecID id = encoding == "jpeg" ? AV_CODEC_ID_MJPEG
                         : encoding == "png" ? AV_CODEC_ID_PNG
                         : encoding == "h264" ? AV_CODEC_ID_H264
                         : encoding == "vp8"  ? AV_CODEC_ID_VP8
                                              : AV_CODEC_ID_NONE;
    const AVCodec* codec = avcodec_find_decoder(id);
    if (!codec) {
      error = "no libavcodec decoder for '" + encoding + "'";
      return false;
    }
    context_ = avcodec_alloc_context3(codec);
    context_->thread_count = 1;  // frame threads would hold frames back
    context_->flags |= AV_CODEC_FLAG_LOW_DELAY;
    if (avcodec_open2(context_, codec, nullptr) < 0) {
      error = "cannot open the " + encoding + " decoder";
      return false;
    }
    packet_ = av_packet_alloc();
    frame_ = av_frame_alloc();
    return true;
  }
  // One encoded image or access unit in, its picture out (RGB) when want_rgb. Image files
  // (jpeg, png) each get a fresh context: libavcodec's PNG decoder carries state from one
  // packet to the next (the second image of a reused one came out garbled).
  bool decode(const std::string& bytes, bool want_rgb, Rgb& out, std::string& error) {
    if ((encoding_ == "png" || encoding_ == "jpeg") && used_) {
      av_frame_free(&frame_);
      av_packet_free(&packet_);
      avcodec_free_context(&context_);
      if (!open(encoding_, error)) return false;
    }
    used_ = true;
    av_packet_unref(packet_);
    if (av_new_packet(packet_, int(bytes.size())) < 0) return false;
    std::memcpy(packet_->data, bytes.data(), bytes.size());
    if (avcodec_send_packet(context_, packet_) < 0) {
      error = "decoder refused a packet";
      return false;
    }
    if (avcodec_receive_frame(context_, frame_) < 0) {
      error = "decoder gave no picture for a packet";
      return false;
    }
    if (want_rgb) {
      sws_ = sws_getCachedContext(sws_, frame_->width, frame_->height, AVPixelFormat(frame_->format),
                                  frame_->width, frame_->height, AV_PIX_FMT_RGB24, SWS_POINT, nullptr,
                                  nullptr, nullptr);
      out.width = frame_->width;
      out.height = frame_->height;
      out.pixels.resize(size_t(out.width) * out.height * 3);
      uint8_t* planes[1] = {out.pixels.data()};
      const int strides[1] = {out.width * 3};
      sws_scale(sws_, frame_->data, frame_->linesize, 0, frame_->height, planes, strides);
    }
    av_frame_unref(frame_);
    return true;
  }

 private:
  std::string encoding_;
  bool used_ = false;
  AVCodecContext* context_ = nullptr;
  AVPacket* packet_ = nullptr;
  AVFrame* frame_ = nullptr;
  SwsContext* sws_ = nullptr;
};

double psnr(const Rgb& a, const Rgb& b) {
  if (a.width != b.width || a.height != b.height || a.pixels.empty()) return -1;
  double sum = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(b.pixels[i]);
    sum += d * d;
  }
  const double mse = sum / double(a.pixels.size());
  return mse <= 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

// --- the viewers ------------------------------------------------------------------------------

struct Settings {
  uint32_t width = 1280, height = 720;
  int quality = 60;
  double pixel_error = 3;
  double seconds = 60;
  int max_kbps = 0;  // video: the hello's max_kbps (0: the server's default)
};

// The view parameters of a pose, as /api/frame takes them.
std::map<std::string, std::string> view_params(const Camera& c, const Settings& s) {
  char eye[128], target[128], up[96], fov[32];
  std::snprintf(eye, sizeof eye, "%.4f,%.4f,%.4f", c.eye_m.x, c.eye_m.y, c.eye_m.z);
  std::snprintf(target, sizeof target, "%.4f,%.4f,%.4f", c.target_m.x, c.target_m.y, c.target_m.z);
  std::snprintf(up, sizeof up, "%.3f,%.3f,%.3f", c.up.x, c.up.y, c.up.z);
  std::snprintf(fov, sizeof fov, "%.2f", c.fov_deg);
  char px[32];
  std::snprintf(px, sizeof px, "%g", s.pixel_error);
  return {{"eye", eye}, {"target", target}, {"up", up}, {"fov", fov}, {"w", std::to_string(s.width)},
          {"h", std::to_string(s.height)}, {"px", px}, {"mode", "interactive"}};
}

std::string frame_target(const Camera& c, const Settings& s, const std::string& format) {
  std::string t = "/api/frame?";
  for (const auto& [k, v] : view_params(c, s)) t += k + "=" + v + "&";
  t += "format=" + format;
  if (format == "jpeg") t += "&quality=" + std::to_string(s.quality);
  return t;
}

struct Sample {
  size_t pose = 0;
  Rgb image;
};

struct ViewerFigures {
  int frames = 0;
  uint64_t bytes = 0;
  std::vector<double> latency_ms, render_ms, encode_ms;
  std::vector<Sample> samples;
  bool psnr = true;      // keep samples
  std::string encoding;  // what the frames came as
  std::string error;     // the run failed (or the stream is not offered) for this viewer
  bool unavailable = false;
};

struct Walk {
  const std::vector<Camera>* path;
  size_t start;
  Clock::time_point t0;
  size_t pose_at(Clock::time_point t) const {
    const double s = std::chrono::duration<double>(t - t0).count();
    return (start + size_t(std::max(0.0, s) * kPosesPerSecond)) % path->size();
  }
};

using Connect = std::function<int(std::string& error)>;

void http_viewer(const Connect& connect, const Walk& walk, const Settings& s, ViewerFigures& f) {
  const int fd = connect(f.error);
  if (fd < 0) return;
  Connection c(fd);
  Decoder decoder;
  if (!decoder.open("jpeg", f.error)) return;
  f.encoding = "jpeg";
  const Clock::time_point end = walk.t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s.seconds));
  HttpReply r;
  while (!g_stop && Clock::now() < end) {
    const Clock::time_point sent = Clock::now();
    const size_t pose = walk.pose_at(sent);
    if (!http_get(c, frame_target((*walk.path)[pose], s, "jpeg"), r) || r.status != 200) {
      f.error = "frame request failed (status " + std::to_string(r.status) + ")";
      return;
    }
    const bool sample = f.psnr && f.frames % kPsnrEvery == 0 && int(f.samples.size()) < kPsnrMax;
    Rgb image;
    if (!decoder.decode(r.body, sample, image, f.error)) return;
    f.latency_ms.push_back(ms_since(sent));
    f.frames += 1;
    f.bytes += r.body.size();
    f.render_ms.push_back(std::atof(r.headers["x-frame-ms"].c_str()));
    f.encode_ms.push_back(std::atof(r.headers["x-encode-ms"].c_str()));
    if (sample) f.samples.push_back({pose, std::move(image)});
  }
}

void stream_viewer(const Connect& connect, const Walk& walk, const Settings& s, const std::string& codec,
                   ViewerFigures& f) {
  const int fd = connect(f.error);
  if (fd < 0) return;
  WebSocket ws(fd);
  if (!ws.open(f.error)) {
    f.unavailable = true;
    return;
  }
  nlohmann::json hello = {{"type", "hello"}, {"codec", codec}};
  if (s.max_kbps > 0 && codec != "jpeg") hello["max_kbps"] = s.max_kbps;
  ws.send_text(hello.dump());
  uint8_t op = 0;
  std::string message;
  bool closed = false;
  // The ready message says the codec the server took.
  while (ws.read(op, message, 10000, closed)) {
    if (op != 1) continue;
    const auto j = nlohmann::json::parse(message, nullptr, false);
    if (j.is_object() && j.value("type", "") == "ready") {
      f.encoding = j.value("codec", "");
      break;
    }
  }
  if (f.encoding.empty()) {
    f.error = "no ready message";
    return;
  }
  if (f.encoding != codec) {
    f.unavailable = true;
    f.error = "the server offers " + f.encoding + " instead of " + codec;
    ws.close_normal();
    return;
  }
  std::map<std::string, std::unique_ptr<Decoder>> decoders;
  std::vector<std::pair<Clock::time_point, size_t>> sent;  // by seq: when, which pose
  const Clock::time_point end = walk.t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s.seconds));
  size_t last_pose = SIZE_MAX;
  Clock::time_point next_view = Clock::now();
  while (!g_stop && Clock::now() < end) {
    const Clock::time_point now = Clock::now();
    if (now >= next_view) {
      const size_t pose = walk.pose_at(now);
      if (pose != last_pose) {
        nlohmann::json params;
        for (const auto& [k, v] : view_params((*walk.path)[pose], s)) params[k] = v;
        params["quality"] = s.quality;
        ws.send_text(nlohmann::json{{"type", "view"}, {"seq", sent.size()}, {"params", params}}.dump());
        sent.emplace_back(Clock::now(), pose);
        last_pose = pose;
      }
      next_view += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / kPosesPerSecond));
    }
    const int wait_ms = std::max(0, int(std::chrono::ceil<std::chrono::milliseconds>(next_view - Clock::now()).count()));
    if (!ws.readable(wait_ms)) continue;
    if (!ws.read(op, message, 10000, closed)) {
      f.error = closed ? "the server closed the stream" : "stream read failed";
      return;
    }
    if (op == 1) {
      const auto j = nlohmann::json::parse(message, nullptr, false);
      if (j.is_object() && j.value("type", "") == "error") {
        f.error = "server: " + j.value("message", std::string());
        return;
      }
      continue;
    }
    // "PVF1", u32 LE header length, JSON header, payload.
    if (message.size() < 8 || message.compare(0, 4, "PVF1") != 0) {
      f.error = "a binary message without the PVF1 header";
      return;
    }
    const uint32_t length = uint32_t(uint8_t(message[4])) | uint32_t(uint8_t(message[5])) << 8 |
                            uint32_t(uint8_t(message[6])) << 16 | uint32_t(uint8_t(message[7])) << 24;
    if (8 + size_t(length) > message.size()) {
      f.error = "a frame header longer than its message";
      return;
    }
    const auto header = nlohmann::json::parse(message.substr(8, length), nullptr, false);
    const std::string payload = message.substr(8 + length);
    if (!header.is_object()) {
      f.error = "a frame header that is not JSON";
      return;
    }
    const std::string encoding = header.value("encoding", "");
    auto& decoder = decoders[encoding];
    if (!decoder) {
      decoder = std::make_unique<Decoder>();
      if (!decoder->open(encoding, f.error)) return;
    }
    const size_t seq = header.value("seq", size_t(0));
    const bool sample = f.psnr && f.frames % kPsnrEvery == 0 && int(f.samples.size()) < kPsnrMax && seq < sent.size();
    Rgb image;
    if (!decoder->decode(payload, sample, image, f.error)) return;
    if (seq < sent.size()) f.latency_ms.push_back(ms_since(sent[seq].first));
    ws.send_text(nlohmann::json{{"type", "ack"}, {"frame", header.value("frame", 0)}}.dump());
    f.frames += 1;
    f.bytes += payload.size();
    f.render_ms.push_back(header.value("render_ms", 0.0));
    f.encode_ms.push_back(header.value("encode_ms", 0.0));
    if (sample) f.samples.push_back({sent[seq].second, std::move(image)});
  }
  ws.close_normal();
}

struct RunResult {
  std::string link, mode;
  int viewers = 0;
  double seconds = 0;
  std::vector<ViewerFigures> figures;
  double fps_mean = 0, fps_min = 0, bytes_per_frame = 0, latency_p50 = 0, latency_p95 = 0,
         render_p50 = 0, encode_p50 = 0, psnr_mean = 0;
  int psnr_count = 0;
  bool ran = false;
  std::string note;
};

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string store_dir, bin = PLANTVIEW_BIN, modes_arg = "http,jpeg,h264,vp8", viewers_arg = "1,4",
                         links_arg = "shaped,loopback", size = "1280x720";
  double seconds = 60, rate_mbit = 20, delay_ms = 25;
  int max_kbps = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") quick = true;
    else if (a == "--store") store_dir = next();
    else if (a == "--seconds") seconds = std::stod(next());
    else if (a == "--size") size = next();
    else if (a == "--rate") rate_mbit = std::stod(next());
    else if (a == "--delay") delay_ms = std::stod(next());
    else if (a == "--modes") modes_arg = next();
    else if (a == "--viewers") viewers_arg = next();
    else if (a == "--links") links_arg = next();
    else if (a == "--bin") bin = next();
    else if (a == "--max-kbps") max_kbps = std::stoi(next());
    else {
      std::fprintf(stderr, "bench_stream: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  char preset = 'c';
  if (quick) {
    preset = 'a';
    size = "320x180";
    seconds = 3;
    links_arg = "loopback";
    viewers_arg = "1";
    modes_arg = "http,jpeg,h264";
  }
  Settings settings;
  settings.seconds = seconds;
  settings.max_kbps = max_kbps;
  if (std::sscanf(size.c_str(), "%ux%u", &settings.width, &settings.height) != 2) return 2;
  const auto split = [](const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');)
      if (!item.empty()) out.push_back(item);
    return out;
  };
  const std::vector<std::string> modes = split(modes_arg), links = split(links_arg);
  std::vector<int> viewer_counts;
  for (const auto& v : split(viewers_arg)) viewer_counts.push_back(std::max(1, std::stoi(v)));

  av_log_set_level(AV_LOG_ERROR);  // not swscale's note on JPEG's full-range YUV per frame
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  signal(SIGPIPE, SIG_IGN);

  bool remove_after = false;
  if (store_dir.empty()) {
    store_dir = (fs::temp_directory_path() / ("plantview-bench-stream-" + std::to_string(::getpid()))).string();
    fs::remove_all(store_dir);
    const std::string command = bin + " gen --preset " + preset + " --store " + store_dir + " >/dev/null";
    if (std::system(command.c_str()) != 0) return 1;
    remove_after = true;
  }
  std::vector<Camera> path;
  {
    std::string error;
    auto store = Store::open(store_dir, Store::Mode::read_only, error);
    const size_t poses = size_t(std::max(60.0, seconds) * kPosesPerSecond);
    if (!store || !make_camera_path(PathKind::walkthrough, poses, *store, path, error)) {
      std::fprintf(stderr, "bench_stream: %s\n", error.c_str());
      return 1;
    }
  }
  int port = 0;
  const pid_t server = start_server(bin, store_dir, port);
  if (server < 0) {
    std::fprintf(stderr, "bench_stream: the server did not start\n");
    return 1;
  }
  int status = 0;
  std::vector<RunResult> results;
  {
    plantview::bench::ShapedLink link;
    plantview::bench::DelayProxy proxy;
    std::printf("%-9s %-5s %7s %8s %8s %9s %8s %8s %8s %8s %7s\n", "link", "mode", "viewers", "frames/s",
                "slowest", "KB/frame", "lat p50", "lat p95", "render", "encode", "PSNR dB");
    for (const std::string& link_name : links) {
      Connect connect;
      if (link_name == "shaped") {
        std::string error;
        if (!link.make(rate_mbit, error) || !proxy.start(link.host_address(), port, delay_ms, error)) {
          std::printf("%-9s skipped: %s\n", "shaped", error.c_str());
          link.remove();
          continue;
        }
        connect = [&](std::string& e) { return link.connect_in(link.host_address(), proxy.port(), e); };
      } else {
        connect = [&](std::string& e) { return connect_tcp("127.0.0.1", port, e); };
      }
      for (const int viewers : viewer_counts) {
        for (const std::string& mode : modes) {
          if (g_stop) break;
          RunResult run;
          run.link = link_name;
          run.mode = mode;
          run.viewers = viewers;
          run.seconds = seconds;
          run.figures.resize(size_t(viewers));
          std::vector<std::thread> threads;
          const Clock::time_point t0 = Clock::now();
          for (int v = 0; v < viewers; ++v) {
            run.figures[size_t(v)].psnr = viewers == 1;
            threads.emplace_back([&, v] {
              const Walk walk{&path, size_t(v) * path.size() / size_t(viewers), t0};
              if (mode == "http") http_viewer(connect, walk, settings, run.figures[size_t(v)]);
              else stream_viewer(connect, walk, settings, mode, run.figures[size_t(v)]);
            });
          }
          for (auto& t : threads) t.join();
          const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
          std::vector<double> latency, render, encode;
          uint64_t bytes = 0;
          int frames = 0;
          double fps_min = 1e30;
          for (const ViewerFigures& f : run.figures) {
            if (!f.error.empty() && run.note.empty()) run.note = f.error;
            if (f.unavailable) run.note = "not offered: " + f.error;
            latency.insert(latency.end(), f.latency_ms.begin(), f.latency_ms.end());
            render.insert(render.end(), f.render_ms.begin(), f.render_ms.end());
            encode.insert(encode.end(), f.encode_ms.begin(), f.encode_ms.end());
            bytes += f.bytes;
            frames += f.frames;
            fps_min = std::min(fps_min, f.frames / elapsed);
          }
          run.ran = frames > 0 && run.note.empty();
          if (run.note.rfind("not offered", 0) == 0) {
            std::printf("%-9s %-5s %7d skipped: %s\n", link_name.c_str(), mode.c_str(), viewers, run.note.c_str());
            continue;
          }
          if (!run.ran) {
            std::printf("%-9s %-5s %7d failed: %s\n", link_name.c_str(), mode.c_str(), viewers,
                        run.note.empty() ? "no frames" : run.note.c_str());
            status = 1;
            continue;
          }
          run.fps_mean = frames / elapsed / viewers;
          run.fps_min = fps_min;
          run.bytes_per_frame = double(bytes) / frames;
          run.latency_p50 = percentile(latency, 0.5);
          run.latency_p95 = percentile(latency, 0.95);
          run.render_p50 = percentile(render, 0.5);
          run.encode_p50 = percentile(encode, 0.5);
          results.push_back(std::move(run));
        }
      }
      proxy.stop();
      link.remove();
    }
    // PSNR against lossless renders of the sampled poses, on loopback with the server idle.
    std::string error;
    const int fd = connect_tcp("127.0.0.1", port, error);
    if (fd >= 0) {
      Connection c(fd);
      Decoder png;
      std::map<size_t, Rgb> references;
      if (png.open("png", error)) {
        for (RunResult& run : results) {
          double sum = 0;
          for (const ViewerFigures& f : run.figures) {
            for (const Sample& sample : f.samples) {
              if (g_stop) break;
              auto it = references.find(sample.pose);
              if (it == references.end()) {
                HttpReply r;
                Rgb image;
                if (!http_get(c, frame_target(path[sample.pose], settings, "png"), r) || r.status != 200 ||
                    !png.decode(r.body, true, image, error))
                  continue;
                it = references.emplace(sample.pose, std::move(image)).first;
              }
              const double p = psnr(sample.image, it->second);
              if (p < 0) continue;  // a degraded (smaller) frame: not comparable
              sum += p;
              run.psnr_count += 1;
            }
          }
          run.psnr_mean = run.psnr_count ? sum / run.psnr_count : 0;
        }
      }
    }
  }
  kill(server, SIGTERM);
  waitpid(server, nullptr, 0);
  for (const RunResult& run : results) {
    std::printf("%-9s %-5s %7d %8.2f %8.2f %9.1f %8.0f %8.0f %8.0f %8.1f %7.2f\n", run.link.c_str(),
                run.mode.c_str(), run.viewers, run.fps_mean, run.fps_mean > 0 ? run.fps_min / run.fps_mean : 0,
                run.bytes_per_frame / 1024, run.latency_p50, run.latency_p95, run.render_p50, run.encode_p50,
                run.psnr_mean);
  }
  for (const RunResult& run : results) {
    nlohmann::json j = {{"bench", "stream"},
                        {"link", run.link},
                        {"mode", run.mode},
                        {"viewers", run.viewers},
                        {"seconds", run.seconds},
                        {"width", settings.width},
                        {"height", settings.height},
                        {"rate_mbit", run.link == "shaped" ? rate_mbit : 0.0},
                        {"delay_ms_each_way", run.link == "shaped" ? delay_ms : 0.0},
                        {"frames_per_second", run.fps_mean},
                        {"slowest_over_mean", run.fps_mean > 0 ? run.fps_min / run.fps_mean : 0},
                        {"bytes_per_frame", run.bytes_per_frame},
                        {"latency_p50_ms", run.latency_p50},
                        {"latency_p95_ms", run.latency_p95},
                        {"render_p50_ms", run.render_p50},
                        {"encode_p50_ms", run.encode_p50},
                        {"psnr_db", run.psnr_mean},
                        {"psnr_frames", run.psnr_count},
                        {"max_kbps", run.mode == "http" || run.mode == "jpeg" ? 0 : max_kbps}};
    std::printf("json: %s\n", j.dump().c_str());
  }
  // The goals (issue 43), from the runs that ran.
  const auto find = [&](const std::string& link, const std::string& mode, int viewers) -> const RunResult* {
    for (const RunResult& r : results)
      if (r.link == link && r.mode == mode && r.viewers == viewers) return &r;
    return nullptr;
  };
  const RunResult* http = find("shaped", "http", 1);
  const RunResult* jpeg = find("shaped", "jpeg", 1);
  for (const char* video : {"h264", "vp8"}) {
    const RunResult* v = find("shaped", video, 1);
    if (v && jpeg)
      std::printf("goal: %s bytes/frame / jpeg's = %.0f / %.0f = %.2f (<= 0.25) at PSNR %.2f against %.2f dB (>=)\n",
                  video, v->bytes_per_frame, jpeg->bytes_per_frame, v->bytes_per_frame / jpeg->bytes_per_frame,
                  v->psnr_mean, jpeg->psnr_mean);
    if (v) {
      const double bound = 2 * delay_ms + v->render_p50 + v->encode_p50 + 40;
      std::printf("goal: %s motion-to-photon median %.0f ms (<= RTT + render + encode + 40 = %.0f)\n", video,
                  v->latency_p50, bound);
    }
  }
  if (http && jpeg)
    std::printf("goal: stream (jpeg) / HTTP frames/s at 20 Mbit/s = %.2f / %.2f = %.2f (>= 2)\n", jpeg->fps_mean,
                http->fps_mean, jpeg->fps_mean / http->fps_mean);
  for (const char* mode : {"jpeg", "h264", "vp8"})
    if (const RunResult* r = find("shaped", mode, 4))
      std::printf("goal: four viewers, %s, slowest / mean frames/s = %.2f (>= 0.7)\n", mode, r->fps_min / r->fps_mean);
  const RunResult* lhttp = find("loopback", "http", 1);
  for (const char* mode : {"jpeg", "h264", "vp8"})
    if (const RunResult* r = find("loopback", mode, 1); r && lhttp)
      std::printf("goal: loopback %s / HTTP: frames/s %.2f / %.2f, latency p50 %.0f / %.0f ms (no slower)\n", mode,
                  r->fps_mean, lhttp->fps_mean, r->latency_p50, lhttp->latency_p50);
  if (remove_after) fs::remove_all(store_dir);
  if (g_stop) return 130;
  return status;
}
