#include "server/request_parser.h"

#include <http_parser.h>
#include <strings.h>

#include <algorithm>
#include <cassert>
#include <climits>

namespace plantview::service {

struct RequestParser::State {
  http_parser parser{};
  RequestLimits limits;
  // The request being parsed.
  std::string url, field, value;
  bool value_last = false;
  size_t body_bytes = 0;
  // The head (request line and headers, as sent, with any blank lines before them) is counted
  // here, byte by byte, not in http-parser's callbacks: those report a token only when it ends or
  // the buffer does, so whether a malformed byte or the limit came first would depend on how the
  // bytes were split. Counted as sent, the first of the two in byte order decides.
  size_t head_bytes = 0;
  bool in_head = true;
  bool in_request = false, complete = false, failed = false;
  int limit_status = 0;  // set by a callback that stopped http-parser for a limit
  Request request;
  RequestError error;

  static State& of(http_parser* p) { return *static_cast<State*>(p->data); }

  // Keeps what the server uses of a header (the rest is counted, not kept).
  void end_header() {
    if (strcasecmp(field.c_str(), "authorization") == 0) request.authorization = value;
    else if (strcasecmp(field.c_str(), "upgrade") == 0) request.upgrade_to = value;
    else if (strcasecmp(field.c_str(), "sec-websocket-key") == 0) request.websocket_key = value;
    else if (strcasecmp(field.c_str(), "sec-websocket-version") == 0) request.websocket_version = value;
    else if (strcasecmp(field.c_str(), "sec-websocket-protocol") == 0)
      request.websocket_protocols += (request.websocket_protocols.empty() ? "" : ",") + value;
    field.clear();
    value.clear();
  }

  void finish_request(http_parser* p) {
    const size_t q = url.find('?');
    request.path = url.substr(0, q);
    request.method = http_method_str(static_cast<http_method>(p->method));
    request.keep_alive = http_should_keep_alive(p) != 0;
    request.upgrade = p->upgrade != 0;
    if (q != std::string::npos && !parse_query(std::string_view(url).substr(q + 1), request.query, request.query_error))
      request.query.clear();
  }

  static const http_parser_settings& settings();
};

const http_parser_settings& RequestParser::State::settings() {
  static const http_parser_settings settings = [] {
    http_parser_settings s{};
    http_parser_settings_init(&s);
    s.on_message_begin = [](http_parser* p) {
      State& st = of(p);
      st.url.clear();
      st.field.clear();
      st.value.clear();
      st.value_last = false;
      st.body_bytes = 0;
      st.request = Request{};
      st.in_request = true;
      return 0;
    };
    s.on_url = [](http_parser* p, const char* at, size_t n) {
      State& st = of(p);
      st.url.append(at, n);
      return 0;
    };
    s.on_header_field = [](http_parser* p, const char* at, size_t n) {
      State& st = of(p);
      if (st.value_last) st.end_header();
      st.value_last = false;
      st.field.append(at, n);
      return 0;
    };
    s.on_header_value = [](http_parser* p, const char* at, size_t n) {
      State& st = of(p);
      st.value_last = true;
      st.value.append(at, n);
      return 0;
    };
    s.on_headers_complete = [](http_parser* p) {
      State& st = of(p);
      if (st.value_last) st.end_header();
      st.in_head = false;
      if (p->content_length != ULLONG_MAX && p->content_length > st.limits.max_body_bytes) {
        st.limit_status = 413;
        return -1;  // http-parser: -1 is an error here (1 would mean "no body")
      }
      return 0;
    };
    s.on_body = [](http_parser* p, const char*, size_t n) {
      State& st = of(p);
      st.body_bytes += n;
      if (st.body_bytes <= st.limits.max_body_bytes) return 0;
      st.limit_status = 413;
      return 1;
    };
    s.on_message_complete = [](http_parser* p) {
      State& st = of(p);
      st.finish_request(p);
      st.in_request = false;
      st.complete = true;
      st.in_head = true;  // what follows is the next request's head
      st.head_bytes = 0;
      http_parser_pause(p, 1);  // feed() returns here, one request at a time
      return 0;
    };
    return s;
  }();
  return settings;
}

RequestParser::RequestParser(RequestLimits limits) : state_(std::make_unique<State>()) {
  state_->limits = limits;
  http_parser_init(&state_->parser, HTTP_REQUEST);
  state_->parser.data = state_.get();
}

RequestParser::~RequestParser() = default;

RequestParser::Result RequestParser::feed(std::string_view bytes, size_t& used) {
  State& st = *state_;
  assert(!st.failed && "RequestParser::feed after an error");
  used = 0;
  if (bytes.empty()) return Result::need_more;  // http-parser reads an empty call as end of input
  if (HTTP_PARSER_ERRNO(&st.parser) == HPE_PAUSED) http_parser_pause(&st.parser, 0);
  st.complete = false;
  // In the head, http-parser sees at most what is left of the limit at a time: a head that needs
  // more is 431 however the bytes arrive, unless a malformed byte within the limit came first.
  auto err = HPE_OK;
  while (used < bytes.size()) {
    size_t n = bytes.size() - used;
    if (st.in_head) {
      if (st.head_bytes >= st.limits.max_header_bytes) {
        st.limit_status = 431;
        break;
      }
      n = std::min<size_t>(n, st.limits.max_header_bytes - st.head_bytes);
    }
    const bool was_in_head = st.in_head;
    const size_t done = http_parser_execute(&st.parser, &State::settings(), bytes.data() + used, n);
    used += done;
    if (st.complete) return Result::request;
    if (was_in_head && st.in_head) st.head_bytes += done;
    err = HTTP_PARSER_ERRNO(&st.parser);
    if (err != HPE_OK || done < n) break;
  }
  if (err == HPE_OK && st.limit_status == 0 && used == bytes.size()) return Result::need_more;
  st.failed = true;
  st.in_request = false;
  if (st.limit_status == 431 || err == HPE_HEADER_OVERFLOW) {
    st.error = {431, "request headers larger than " + std::to_string(st.limits.max_header_bytes) + " bytes"};
  } else if (st.limit_status == 413) {
    st.error = {413, "request body larger than " + std::to_string(st.limits.max_body_bytes) + " bytes"};
  } else {
    st.error = {400, std::string("malformed HTTP: ") + http_errno_description(err)};
  }
  return Result::error;
}

Request& RequestParser::request() { return state_->request; }
const RequestError& RequestParser::error() const { return state_->error; }
bool RequestParser::in_request() const { return state_->in_request; }

}  // namespace plantview::service
