// Rules: websocket.h.
#include "server/websocket.h"

#include <openssl/evp.h>

namespace plantview::service::ws {

namespace {

constexpr std::string_view kGuid = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";

bool is_known(uint8_t opcode) {
  return opcode <= 2 || (opcode >= 8 && opcode <= 10);
}

// Codes a peer may send in a close frame (RFC 6455 7.4.1 and 7.4.2; the IANA registry's
// 1012-1014 too).
bool valid_close_code(uint16_t code) {
  if (code >= 3000 && code <= 4999) return true;
  return (code >= 1000 && code <= 1003) || (code >= 1007 && code <= 1014);
}

}  // namespace

std::string accept_key(std::string_view client_key) {
  const std::string text = std::string(client_key) + std::string(kGuid);
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(text.data(), text.size(), digest, &length, EVP_sha1(), nullptr);
  unsigned char base64[4 * ((EVP_MAX_MD_SIZE + 2) / 3) + 1];
  const int n = EVP_EncodeBlock(base64, digest, int(length));
  return std::string(reinterpret_cast<const char*>(base64), size_t(n));
}

bool valid_client_key(std::string_view key) {
  if (key.size() != 24 || key.substr(22) != "==") return false;
  for (size_t i = 0; i < 22; ++i) {
    const char c = key[i];
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '+' || c == '/'))
      return false;
  }
  // The last character before "==" carries 2 bits of the 16th byte and 4 zero bits.
  return std::string_view("AQgw").find(key[21]) != std::string_view::npos;
}

bool valid_utf8(std::string_view bytes) {
  size_t i = 0;
  const size_t n = bytes.size();
  while (i < n) {
    const uint8_t c = uint8_t(bytes[i]);
    if (c < 0x80) {
      ++i;
      continue;
    }
    size_t extra = 0;
    uint32_t cp = 0, min = 0;
    if ((c & 0xE0) == 0xC0) extra = 1, cp = c & 0x1F, min = 0x80;
    else if ((c & 0xF0) == 0xE0) extra = 2, cp = c & 0x0F, min = 0x800;
    else if ((c & 0xF8) == 0xF0) extra = 3, cp = c & 0x07, min = 0x10000;
    else return false;
    if (i + extra >= n) return false;
    for (size_t k = 1; k <= extra; ++k) {
      const uint8_t b = uint8_t(bytes[i + k]);
      if ((b & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (b & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += extra + 1;
  }
  return true;
}

std::string frame(Opcode opcode, std::string_view payload) {
  std::string f;
  f.reserve(payload.size() + 10);
  f += char(0x80 | uint8_t(opcode));
  const uint64_t n = payload.size();
  if (n < 126) {
    f += char(n);
  } else if (n <= 0xFFFF) {
    f += char(126);
    f += char(n >> 8);
    f += char(n & 0xFF);
  } else {
    f += char(127);
    for (int shift = 56; shift >= 0; shift -= 8) f += char((n >> shift) & 0xFF);
  }
  f += payload;
  return f;
}

std::string close_frame(uint16_t code, std::string_view reason) {
  std::string payload;
  payload += char(code >> 8);
  payload += char(code & 0xFF);
  if (reason.size() > 123) {
    reason = reason.substr(0, 123);
    while (!reason.empty() && !valid_utf8(reason)) reason.remove_suffix(1);
  }
  payload += reason;
  return frame(Opcode::close, payload);
}

void Deframer::fail(uint16_t code, std::string reason, std::vector<Event>& events) {
  done_ = true;
  buffer_.clear();
  buffer_.shrink_to_fit();
  message_.clear();
  message_.shrink_to_fit();
  Event e;
  e.kind = Event::Kind::error;
  e.code = code;
  e.reason = std::move(reason);
  events.push_back(std::move(e));
}

void Deframer::feed(std::string_view bytes, std::vector<Event>& events) {
  if (done_) return;
  buffer_.append(bytes);
  size_t at = 0;  // start of the frame being read in buffer_
  while (!done_) {
    const size_t available = buffer_.size() - at;
    if (available < 2) break;
    const auto* b = reinterpret_cast<const uint8_t*>(buffer_.data() + at);
    const bool fin = b[0] & 0x80;
    const uint8_t rsv = b[0] & 0x70, opcode = b[0] & 0x0F;
    const bool masked = b[1] & 0x80;
    uint64_t length = b[1] & 0x7F;
    size_t header = 2;
    if (rsv) return fail(protocol_error, "reserved bits set (no extension was agreed)", events);
    if (!is_known(opcode)) return fail(protocol_error, "unknown opcode " + std::to_string(opcode), events);
    const bool control = opcode >= 8;
    if (control && !fin) return fail(protocol_error, "a fragmented control frame", events);
    if (control && length > 125) return fail(protocol_error, "a control frame over 125 bytes", events);
    if (!masked) return fail(protocol_error, "a client frame that is not masked", events);
    if (length == 126) {
      if (available < 4) break;
      length = (uint64_t(b[2]) << 8) | b[3];
      header = 4;
    } else if (length == 127) {
      if (available < 10) break;
      length = 0;
      for (int k = 0; k < 8; ++k) length = (length << 8) | b[2 + k];
      header = 10;
      if (length >> 63) return fail(protocol_error, "a frame length with its top bit set", events);
    }
    if (!control) {
      if (opcode == 0 && !in_message_) return fail(protocol_error, "a continuation frame with no message begun", events);
      if (opcode != 0 && in_message_) return fail(protocol_error, "a new message before the last one ended", events);
      if (length > max_message_bytes_ || message_.size() + length > max_message_bytes_)
        return fail(too_big, "a message over " + std::to_string(max_message_bytes_) + " bytes", events);
    }
    header += 4;  // the masking key
    if (available < header + length) break;
    const uint8_t* key = b + header - 4;
    std::string payload(buffer_.data() + at + header, size_t(length));
    for (size_t k = 0; k < payload.size(); ++k) payload[k] = char(uint8_t(payload[k]) ^ key[k & 3]);
    at += header + size_t(length);

    if (!control) {
      if (opcode != 0) {
        in_message_ = true;
        message_text_ = opcode == 1;
      }
      message_ += payload;
      if (!fin) continue;
      in_message_ = false;
      if (message_text_ && !valid_utf8(message_)) return fail(invalid_data, "a text message that is not UTF-8", events);
      Event e;
      e.kind = Event::Kind::message;
      e.text = message_text_;
      e.payload = std::move(message_);
      message_.clear();
      events.push_back(std::move(e));
      continue;
    }
    Event e;
    e.payload = std::move(payload);
    if (opcode == uint8_t(Opcode::ping)) {
      e.kind = Event::Kind::ping;
    } else if (opcode == uint8_t(Opcode::pong)) {
      e.kind = Event::Kind::pong;
    } else {
      if (e.payload.size() == 1) return fail(protocol_error, "a close frame with a one-byte payload", events);
      e.kind = Event::Kind::close;
      e.code = no_status;
      if (e.payload.size() >= 2) {
        e.code = uint16_t((uint8_t(e.payload[0]) << 8) | uint8_t(e.payload[1]));
        if (!valid_close_code(e.code)) return fail(protocol_error, "close code " + std::to_string(e.code) + " is not allowed", events);
        e.reason = e.payload.substr(2);
        if (!valid_utf8(e.reason)) return fail(invalid_data, "a close reason that is not UTF-8", events);
      }
      e.payload.clear();
      done_ = true;
    }
    events.push_back(std::move(e));
  }
  buffer_.erase(0, at);
  if (done_) buffer_.clear();
}

}  // namespace plantview::service::ws
