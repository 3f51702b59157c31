// HTTP/1.1 requests from bytes: http-parser's glue, pure (no sockets, no libuv), so that it is
// tested and fuzzed on its own.
//
// Rules
//   - Bytes arrive in any split (one at a time, or many requests at once); feed() stops at the end
//     of each complete request, so that a connection answers requests one by one, in order.
//   - Limits: the request line and headers together at most max_header_bytes (else 431); a body
//     (declared or sent) at most max_body_bytes (else 413); anything http-parser refuses is 400
//     "malformed HTTP: <http-parser's reason>". An error is final: the connection answers it and
//     closes, and the parser accepts nothing more.
//   - A malformed query string is not a parse error: the request is complete and carries
//     query_error, answered 400 by the routes (after the token and method checks), and the
//     connection stays open.
//   - Memory: what one request holds is bounded by the limits; a body is counted, never kept.
// Threads: one parser per connection, used by one thread at a time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "server/http.h"

namespace plantview::service {

struct RequestLimits {
  uint32_t max_header_bytes = 16384;  // request line and headers, as sent
  uint32_t max_body_bytes = 65536;
};

// One complete request: what the server uses of it.
struct Request {
  std::string method;         // as http-parser names it: "GET", "POST", ...
  std::string path;           // the target up to '?', as sent (not percent-decoded)
  Fields query;               // the decoded query fields, in order (empty if query_error is set)
  std::string query_error;    // non-empty: the query string is malformed (parse_query's reason)
  std::string authorization;  // the last Authorization header's value, "" if none
  bool keep_alive = true;     // HTTP/1.1 without "Connection: close", or 1.0 with keep-alive
  // An upgrade (Connection: upgrade and an Upgrade header, as http-parser sees them): nothing
  // after it is HTTP, so the parser takes no more bytes (feed() is not to be called again).
  bool upgrade = false;
  std::string upgrade_to;           // the Upgrade header's value
  std::string websocket_key;        // Sec-WebSocket-Key
  std::string websocket_version;    // Sec-WebSocket-Version
  std::string websocket_protocols;  // every Sec-WebSocket-Protocol value, joined by ","
};

// Why the bytes are not (or cannot be) a request: a 4xx status and a message for the client.
struct RequestError {
  int status = 0;  // 400, 413 or 431
  std::string message;
};

class RequestParser {
 public:
  explicit RequestParser(RequestLimits limits = {});
  ~RequestParser();
  RequestParser(const RequestParser&) = delete;
  RequestParser& operator=(const RequestParser&) = delete;

  enum class Result {
    need_more,  // every byte was used; the request (if one has begun) is not complete yet
    request,    // a request is complete: request(); `used` ends at its last byte
    error,      // error(); final
  };
  // Parses `bytes` up to the end of the next complete request; `used` says how many bytes it
  // took (the rest belongs to the next request: feed it again). Not to be called after an error.
  Result feed(std::string_view bytes, size_t& used);

  // The request completed by the last feed() that returned Result::request; valid (and movable
  // from) until the next feed().
  Request& request();
  const RequestError& error() const;
  // Some bytes of a request have arrived and it is not complete (for the request timeout).
  bool in_request() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace plantview::service
