// Fuzz harness for the service's HTTP request parser (service/server/request_parser.h). For any
// bytes:
//   - parsing never crashes, and never uses more bytes than it was given;
//   - an error has a 4xx status (400, 413 or 431) and a message, and ends the input;
//   - a request has a method, a path within the header limit, and either decoded query fields
//     or a query error (never both), and a request without keep-alive ends the input;
//   - parsing the bytes whole and fed in chunks (sizes chosen from the first two bytes) gives
//     the same requests and the same error.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "server/request_parser.h"

namespace {

using plantview::service::Request;
using plantview::service::RequestLimits;
using plantview::service::RequestParser;

constexpr RequestLimits kLimits{1024, 256};  // small, so that fuzzing reaches them

void check(bool condition) {
  if (!condition) __builtin_trap();
}

struct Outcome {
  std::vector<Request> requests;
  int error_status = 0;
  std::string error_message;
};

void check_request(const Request& r) {
  check(!r.method.empty());
  check(r.path.size() <= kLimits.max_header_bytes);
  check(r.query_error.empty() || r.query.empty());
  size_t query_bytes = 0;
  for (const auto& [key, value] : r.query) {
    check(!key.empty());
    query_bytes += key.size() + value.size();
  }
  check(query_bytes <= kLimits.max_header_bytes);  // decoding only shrinks
  check(r.authorization.size() <= kLimits.max_header_bytes);
}

// Feeds `bytes` in pieces whose sizes cycle through `sizes` (empty: whole).
Outcome parse(std::string_view bytes, const std::vector<size_t>& sizes) {
  RequestParser parser(kLimits);
  Outcome out;
  size_t next = 0;
  while (!bytes.empty()) {
    const size_t n = sizes.empty() ? bytes.size() : std::min(bytes.size(), sizes[next++ % sizes.size()]);
    std::string_view piece = bytes.substr(0, n);
    bytes.remove_prefix(n);
    while (!piece.empty()) {
      size_t used = 0;
      const auto result = parser.feed(piece, used);
      check(used <= piece.size());
      if (result == RequestParser::Result::error) {
        const auto& e = parser.error();
        check(e.status == 400 || e.status == 413 || e.status == 431);
        check(!e.message.empty());
        out.error_status = e.status;
        out.error_message = e.message;
        return out;
      }
      piece.remove_prefix(used);
      if (result == RequestParser::Result::need_more) {
        check(piece.empty());
        continue;
      }
      check_request(parser.request());
      out.requests.push_back(std::move(parser.request()));
      if (!out.requests.back().keep_alive) return out;  // a connection reads no further
    }
  }
  return out;
}

bool same(const Request& a, const Request& b) {
  return a.method == b.method && a.path == b.path && a.query == b.query && a.query_error == b.query_error &&
         a.authorization == b.authorization && a.keep_alive == b.keep_alive;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const Outcome whole = parse(bytes, {});
  std::vector<size_t> sizes = {1 + (size > 0 ? data[0] % 16 : 0u), 1 + (size > 1 ? data[1] % 64 : 0u)};
  for (const std::vector<size_t>& split : {sizes, std::vector<size_t>{1}}) {
    const Outcome pieces = parse(bytes, split);
    check(pieces.error_status == whole.error_status);
    check(pieces.error_message == whole.error_message);
    check(pieces.requests.size() == whole.requests.size());
    for (size_t i = 0; i < whole.requests.size(); ++i) check(same(pieces.requests[i], whole.requests[i]));
  }
  return 0;
}
