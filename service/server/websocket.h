// WebSocket (RFC 6455) framing for the server side: the opening handshake's accept key, frames
// from the server, and a deframer for the client's bytes. Pure (no sockets, no libuv), so that it
// is tested and fuzzed on its own (tests/fuzz/fuzz_websocket.cpp).
//
// Rules
//   - The deframer takes bytes in any split and turns them into events: a whole message (text or
//     binary, its fragments joined), a ping, a pong, a close, or one error. An error and a close
//     are final: the deframer accepts nothing more, and the connection answers with a close
//     frame (close_frame) carrying the error's code, then closes.
//   - The RFC's rules, each with its close code (ws::Close):
//       * a client frame that is not masked, has a reserved bit set (no extension is agreed), an
//         unknown opcode, a fragmented or over-125-byte control frame, a continuation with no
//         message begun or a new message before the last one ended, a 64-bit length with its top
//         bit set, a close payload of one byte or a close code not allowed on the wire:
//         protocol_error (1002);
//       * a text message or close reason that is not UTF-8: invalid_data (1007);
//       * a message (all its fragments) over max_message_bytes: too_big (1009), said as soon as
//         a frame header announces it, before its payload is read.
//   - Memory: at most max_message_bytes of a message plus one frame header are held.
// Threads: one deframer per connection, used by one thread at a time; the functions are pure.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace plantview::service::ws {

enum class Opcode : uint8_t { continuation = 0, text = 1, binary = 2, close = 8, ping = 9, pong = 10 };

// Close codes used here (RFC 6455 section 7.4.1).
enum Close : uint16_t {
  normal = 1000,
  going_away = 1001,
  protocol_error = 1002,
  no_status = 1005,  // a close frame without a code: never sent, reported as received
  invalid_data = 1007,
  policy = 1008,
  too_big = 1009,
  server_error = 1011,
};

// Sec-WebSocket-Accept for a client's Sec-WebSocket-Key: base64(SHA-1(key + the RFC's GUID)).
std::string accept_key(std::string_view client_key);
// A Sec-WebSocket-Key as the RFC requires: base64 of 16 bytes (24 characters, "==" at the end).
bool valid_client_key(std::string_view key);
bool valid_utf8(std::string_view bytes);

// One unfragmented server frame (FIN set, not masked).
std::string frame(Opcode opcode, std::string_view payload);
// A close frame: the code, then the reason (cut to fit 125 bytes, at a UTF-8 boundary).
std::string close_frame(uint16_t code, std::string_view reason);

struct Event {
  enum class Kind { message, ping, pong, close, error } kind = Kind::message;
  bool text = false;     // message: a text message (valid UTF-8)
  std::string payload;   // message, ping, pong: the bytes
  uint16_t code = 0;     // close: the peer's code (no_status if none); error: the code to send
  std::string reason;    // close: the peer's reason; error: what was wrong (for the close frame)
};

class Deframer {
 public:
  explicit Deframer(size_t max_message_bytes = 1 << 20) : max_message_bytes_(max_message_bytes) {}

  // Appends the events the bytes complete to `events`. After a close or error event it takes
  // nothing more (done() is true).
  void feed(std::string_view bytes, std::vector<Event>& events);
  bool done() const { return done_; }
  // Bytes held: a partial frame and a partial message.
  size_t held_bytes() const { return buffer_.size() + message_.size(); }

 private:
  void fail(uint16_t code, std::string reason, std::vector<Event>& events);

  size_t max_message_bytes_;
  std::string buffer_;   // bytes of the frame being received
  std::string message_;  // fragments of the message being received
  bool in_message_ = false, message_text_ = false, done_ = false;
};

}  // namespace plantview::service::ws
