// Fuzz harness for the service's WebSocket deframer (service/server/websocket.h). For any bytes
// from a client:
//   - deframing never crashes, and holds at most the message limit plus one frame header;
//   - every message is within the limit and a text message is valid UTF-8; control payloads
//     are at most 125 bytes;
//   - an error carries 1002, 1007 or 1009 and a reason; an error or a close is the last event;
//   - the bytes whole and fed in chunks (sizes chosen from the first two bytes) give the same
//     events;
//   - every message, framed again by the server's framer and masked, deframes the same.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "server/websocket.h"

namespace {

namespace ws = plantview::service::ws;

constexpr size_t kMaxMessage = 4096;  // small, so that fuzzing reaches it

void check(bool condition) {
  if (!condition) __builtin_trap();
}

std::vector<ws::Event> deframe(std::string_view bytes, const std::vector<size_t>& sizes) {
  ws::Deframer deframer(kMaxMessage);
  std::vector<ws::Event> events;
  size_t at = 0, k = 0;
  while (at < bytes.size()) {
    const size_t n = sizes.empty() ? bytes.size() : std::max<size_t>(1, sizes[k++ % sizes.size()]);
    deframer.feed(bytes.substr(at, n), events);
    at += std::min(n, bytes.size() - at);
    check(deframer.held_bytes() <= 2 * kMaxMessage + 14 + 125);
  }
  return events;
}

bool same(const ws::Event& a, const ws::Event& b) {
  return a.kind == b.kind && a.text == b.text && a.payload == b.payload && a.code == b.code && a.reason == b.reason;
}

// A client's frame of `payload`: FIN, masked with a fixed key.
std::string client_frame(ws::Opcode opcode, std::string_view payload) {
  std::string f = ws::frame(opcode, payload);
  const size_t header = f.size() - payload.size();
  f[1] = char(uint8_t(f[1]) | 0x80);
  const uint8_t key[4] = {0x12, 0x34, 0x56, 0x78};
  std::string masked(reinterpret_cast<const char*>(key), 4);
  for (size_t i = 0; i < payload.size(); ++i) masked += char(uint8_t(payload[i]) ^ key[i & 3]);
  return f.substr(0, header) + masked;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const std::vector<ws::Event> whole = deframe(bytes, {});
  for (size_t i = 0; i < whole.size(); ++i) {
    const ws::Event& e = whole[i];
    switch (e.kind) {
      case ws::Event::Kind::message:
        check(e.payload.size() <= kMaxMessage);
        check(!e.text || ws::valid_utf8(e.payload));
        break;
      case ws::Event::Kind::ping:
      case ws::Event::Kind::pong: check(e.payload.size() <= 125); break;
      case ws::Event::Kind::close:
        check(i + 1 == whole.size());
        check(ws::valid_utf8(e.reason));
        break;
      case ws::Event::Kind::error:
        check(i + 1 == whole.size());
        check(e.code == ws::protocol_error || e.code == ws::invalid_data || e.code == ws::too_big);
        check(!e.reason.empty());
        break;
    }
  }
  if (size >= 2) {
    const std::vector<size_t> sizes = {size_t(data[0] % 17) + 1, size_t(data[1] % 5) + 1};
    const std::vector<ws::Event> chunked = deframe(bytes, sizes);
    check(chunked.size() == whole.size());
    for (size_t i = 0; i < whole.size(); ++i) check(same(whole[i], chunked[i]));
  }
  for (const ws::Event& e : whole) {
    if (e.kind != ws::Event::Kind::message) continue;
    const std::string again = client_frame(e.text ? ws::Opcode::text : ws::Opcode::binary, e.payload);
    const std::vector<ws::Event> back = deframe(again, {});
    check(back.size() == 1 && same(back[0], e));
  }
  return 0;
}
