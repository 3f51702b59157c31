// Rules: connection.h.
#include "server/connection.h"

namespace plantview::service {

namespace {

constexpr size_t kMaxAnswersOwed = 16;  // answers a connection may owe before it stops being read

struct WriteRequest {
  uv_write_t req{};
  std::string data;  // owned until the write completes
};

uv_stream_t* stream(uv_tcp_t& tcp) { return reinterpret_cast<uv_stream_t*>(&tcp); }
uv_handle_t* handle(auto& h) { return reinterpret_cast<uv_handle_t*>(&h); }

std::string peer_address(uv_tcp_t& tcp) {
  sockaddr_storage peer{};
  int length = sizeof peer;
  if (uv_tcp_getpeername(&tcp, reinterpret_cast<sockaddr*>(&peer), &length) != 0) return {};
  char text[64] = {};
  const int rc = peer.ss_family == AF_INET6
                     ? uv_ip6_name(reinterpret_cast<const sockaddr_in6*>(&peer), text, sizeof text)
                     : uv_ip4_name(reinterpret_cast<const sockaddr_in*>(&peer), text, sizeof text);
  return rc == 0 ? std::string(text) : std::string();
}

}  // namespace

Connection::Connection(ConnectionHost& host, uint64_t id)
    : host_(host), id_(id), parser_(host.connection_limits().request),
      deframer_(host.connection_limits().max_message_bytes) {}

void Connection::on_closed(uv_handle_t* h) {
  auto* self = static_cast<Connection*>(h->data);
  if (--self->open_handles_ == 0) delete self;
}

Connection* Connection::accept(uv_stream_t* listener, ConnectionHost& host, uint64_t id) {
  auto* c = new Connection(host, id);
  uv_tcp_init(listener->loop, &c->tcp_);
  uv_timer_init(listener->loop, &c->timer_);
  uv_timer_init(listener->loop, &c->write_timer_);
  c->tcp_.data = c;
  c->timer_.data = c;
  c->write_timer_.data = c;
  if (uv_accept(listener, stream(c->tcp_)) != 0) {
    c->closing_ = true;
    uv_close(handle(c->timer_), on_closed);
    uv_close(handle(c->write_timer_), on_closed);
    uv_close(handle(c->tcp_), on_closed);
    return nullptr;
  }
  uv_tcp_nodelay(&c->tcp_, 1);
  c->address_ = peer_address(c->tcp_);
  return c;
}

void Connection::start() {
  // The first request's deadline runs from now, not from its first byte: a connection that
  // sends nothing (or one byte now and then) gives its slot back within request_timeout_ms.
  restart_timer(host_.connection_limits().request_timeout_ms);
  start_reading();
}

void Connection::refuse(const Reply& reply) {
  no_more_ = true;
  Reply closing = reply;
  closing.close = true;
  answer(push_pending("refused"), closing);
}

std::shared_ptr<Pending> Connection::push_pending(std::string endpoint) {
  auto p = std::make_shared<Pending>();
  p->endpoint = std::move(endpoint);
  pending_.push_back(p);
  return p;
}

void Connection::answer(const std::shared_ptr<Pending>& p, Reply reply, bool count) {
  if (reply.close) p->keep_alive = false;
  if (count) host_.on_answered(p->endpoint, reply.status);
  p->reply = std::move(reply);
  p->ready = true;
  flush();
}

void Connection::close() {
  if (closing_) return;
  closing_ = true;
  host_.on_closing(*this);
  pending_.clear();
  uv_timer_stop(&timer_);
  uv_timer_stop(&write_timer_);
  uv_close(handle(timer_), on_closed);
  uv_close(handle(write_timer_), on_closed);
  uv_close(handle(tcp_), on_closed);
}

void Connection::stop_reading() {
  uv_read_stop(stream(tcp_));
  reading_ = false;
}

// --- reading ------------------------------------------------------------------------------------

void Connection::start_reading() {
  reading_ = true;
  uv_read_start(
      stream(tcp_),
      [](uv_handle_t*, size_t suggested, uv_buf_t* buf) {
        *buf = uv_buf_init(new char[suggested], unsigned(suggested));
      },
      [](uv_stream_t* s, ssize_t n, const uv_buf_t* buf) {
        static_cast<Connection*>(s->data)->on_read(n, buf);
      });
}

void Connection::on_read(ssize_t n, const uv_buf_t* buf) {
  const std::unique_ptr<char[]> owned(buf->base);
  if (closing_) return;
  if (n == UV_EOF && websocket_) {
    close();  // a WebSocket peer that sends no more is gone (it owes a close frame first)
    return;
  }
  if (n == UV_EOF) {
    // A half-close: the client sends no more, but may still read. Answer what it completed;
    // a request cut short by the close is dropped.
    peer_done_ = true;
    no_more_ = true;
    stop_reading();
    if (finished()) close();
    return;
  }
  if (n < 0) {
    close();  // a reset: answers still owed are dropped with the connection
    return;
  }
  if (n > 0) last_read_ms_ = uv_now(tcp_.loop);
  if (n > 0 && websocket_) return read_ws(std::string_view(buf->base, size_t(n)));
  if (n > 0 && upgrading_) {
    // Frames sent before the 101 is written (answers owed before it): kept for the deframer,
    // within the message limit.
    if (early_bytes_.size() + size_t(n) > host_.connection_limits().max_message_bytes + 16) return close();
    early_bytes_.append(buf->base, size_t(n));
    return;
  }
  if (n > 0 && !no_more_) read_bytes(std::string_view(buf->base, size_t(n)));
}

// Hands each complete request to the host, in order, until the bytes run out or the
// connection will read no more.
void Connection::read_bytes(std::string_view bytes) {
  const ConnectionLimits& limits = host_.connection_limits();
  while (!bytes.empty() && !no_more_ && !closing_) {
    const bool was_in_request = parser_.in_request();
    size_t used = 0;
    const RequestParser::Result result = parser_.feed(bytes, used);
    bytes.remove_prefix(used);
    if (result == RequestParser::Result::error) return fail(parser_.error());
    if (result == RequestParser::Result::need_more) {
      // A later request's deadline runs from its first byte; the first one's from the accept.
      if (served_ && !was_in_request && parser_.in_request()) restart_timer(limits.request_timeout_ms);
      return;
    }
    served_ = true;
    restart_timer(limits.idle_timeout_ms);
    const Request& request = parser_.request();
    auto p = push_pending(endpoint_of(request.path));
    p->keep_alive = request.keep_alive;
    if (request.upgrade) {
      // Nothing after an upgrade request is HTTP: keep it for the WebSocket, or drop it with the
      // connection if the host refuses the upgrade.
      upgrading_ = true;
      no_more_ = true;
      early_bytes_.assign(bytes);
      p->keep_alive = false;
    }
    host_.on_request(*this, request, p);
    if (closing_ || request.upgrade) return;  // the rest of the bytes, if any, are WebSocket's
    if (!p->keep_alive) no_more_ = true;
  }
}

void Connection::accept_websocket(const std::shared_ptr<Pending>& p, std::string response) {
  p->upgrade = std::move(response);
  p->keep_alive = true;
  answer(p, Reply{101, {}, {}, {}, false});
}

// WebSocket frames: messages to the host, pings answered, a close answered and the connection
// closed once the answer is written, a broken rule closed with its code.
void Connection::read_ws(std::string_view bytes) {
  if (ws_close_sent_) return;
  std::vector<ws::Event> events;
  deframer_.feed(bytes, events);
  for (ws::Event& e : events) {
    if (closing_ || ws_close_sent_) return;
    switch (e.kind) {
      case ws::Event::Kind::message: host_.on_ws_message(*this, e.text, e.payload); break;
      case ws::Event::Kind::ping: send_ws(ws::Opcode::pong, e.payload); break;
      case ws::Event::Kind::pong: break;  // last_read_ms_ says the peer is alive
      case ws::Event::Kind::close:
        close_ws(e.code == ws::no_status ? uint16_t(ws::normal) : e.code, {});
        break;
      case ws::Event::Kind::error: close_ws(e.code, e.reason); break;
    }
  }
}

void Connection::send_ws(ws::Opcode opcode, std::string_view payload) {
  if (closing_ || !websocket_ || ws_close_sent_) return;
  write(ws::frame(opcode, payload));
  // A peer that floods pings and never reads its pongs: stop reading it (the write deadline
  // closes it if it never catches up).
  if (reading_ && unsent_bytes_ > host_.connection_limits().max_unsent_bytes) stop_reading();
}

void Connection::close_ws(uint16_t code, std::string_view reason) {
  if (closing_ || ws_close_sent_) return;
  if (!websocket_) return close();
  ws_close_sent_ = true;
  no_more_ = true;
  stop_reading();
  write(ws::close_frame(code, reason));
}

void Connection::fail(const RequestError& error) {
  no_more_ = true;
  stop_reading();
  answer(push_pending("malformed"), error_reply(error.status, error.message, {}, true));
}

// --- timers -------------------------------------------------------------------------------------

void Connection::restart_timer(uint32_t ms) {
  uv_timer_start(&timer_, [](uv_timer_t* t) { static_cast<Connection*>(t->data)->on_timer(); }, ms, 0);
}

void Connection::on_timer() {
  if (closing_ || websocket_) return;
  if (!no_more_ && parser_.in_request()) {
    // Too slow to send its request: answer and close.
    no_more_ = true;
    stop_reading();
    host_.on_timed_out();
    answer(push_pending("timeout"), error_reply(408, "the request did not arrive in time", {}, true));
  } else if (!served_ && finished()) {
    host_.on_timed_out();  // connected and never sent a byte
    close();
  } else if (finished()) {
    close();  // idle keep-alive connection
  } else {
    restart_timer(host_.connection_limits().idle_timeout_ms);
  }
}

uint64_t Connection::bytes_sent() const {
  return written_bytes_ - uv_stream_get_write_queue_size(reinterpret_cast<const uv_stream_t*>(&tcp_));
}

// Runs every write_timeout_ms while bytes wait: closes the connection when the client has
// taken none of them since the last look.
void Connection::on_write_timer() {
  if (closing_) return;
  if (unsent_bytes_ == 0) {
    uv_timer_stop(&write_timer_);
    return;
  }
  const uint64_t sent = bytes_sent();
  if (sent > sent_at_last_check_) {
    sent_at_last_check_ = sent;
    return;
  }
  host_.on_timed_out();
  close();
}

// --- writing ------------------------------------------------------------------------------------

void Connection::write(std::string data) {
  auto* w = new WriteRequest;
  w->data = std::move(data);
  w->req.data = this;
  if (unsent_bytes_ == 0) {
    sent_at_last_check_ = written_bytes_;
    const uint32_t ms = host_.connection_limits().write_timeout_ms;
    uv_timer_start(&write_timer_, [](uv_timer_t* t) { static_cast<Connection*>(t->data)->on_write_timer(); }, ms, ms);
  }
  unsent_bytes_ += w->data.size();
  written_bytes_ += w->data.size();
  uv_buf_t buf = uv_buf_init(w->data.data(), unsigned(w->data.size()));
  const auto on_done = [](uv_write_t* req, int status) {
    auto* done = reinterpret_cast<WriteRequest*>(req);
    auto* self = static_cast<Connection*>(req->data);
    const size_t bytes = done->data.size();
    delete done;
    self->on_written(bytes, status);
  };
  if (uv_write(&w->req, stream(tcp_), &buf, 1, on_done) != 0) {
    unsent_bytes_ -= w->data.size();
    delete w;
    close();
  }
}

void Connection::on_written(size_t bytes, int status) {
  unsent_bytes_ -= bytes;
  if (status < 0) return close();
  if (closing_) return;
  if (unsent_bytes_ == 0) uv_timer_stop(&write_timer_);
  if (websocket_ && ws_close_sent_ && unsent_bytes_ == 0) return close();  // the close frame is out
  // A slow reader has caught up: read its next requests.
  if (!reading_ && !no_more_ && unsent_bytes_ <= host_.connection_limits().max_unsent_bytes / 4 &&
      pending_.size() < kMaxAnswersOwed && !host_.shutting_down())
    start_reading();
  if ((no_more_ || host_.shutting_down()) && finished()) close();
}

// Writes the ready answers at the front, in order.
void Connection::flush() {
  if (closing_) return;
  while (!pending_.empty() && pending_.front()->ready) {
    const auto p = pending_.front();
    pending_.pop_front();
    // Draining: the last answer owed tells the client not to send more on this connection.
    const bool keep_alive = p->keep_alive && !(host_.shutting_down() && pending_.empty() && !parser_.in_request());
    if (!keep_alive) no_more_ = true;
    const Reply& r = p->reply;
    if (!p->upgrade.empty()) {
      // The 101: from here on the connection speaks WebSocket.
      write(std::move(p->upgrade));
      if (closing_) return;
      websocket_ = true;
      upgrading_ = false;
      no_more_ = false;
      uv_timer_stop(&timer_);
      last_read_ms_ = uv_now(tcp_.loop);
      pending_.clear();
      // Upgraded while the server drains (the request was read before): going away at once.
      if (host_.shutting_down()) return close_ws(ws::going_away, "the server is shutting down");
      std::string early = std::move(early_bytes_);
      if (!early.empty()) read_ws(early);
      if (!closing_ && !ws_close_sent_ && !reading_) start_reading();
      return;
    }
    write(http_response(r.status, r.content_type, r.body, keep_alive, r.headers));
    p->reply = Reply{};
    if (closing_) return;
    if (!keep_alive) {
      // Nothing after a closing answer: later pipelined requests are dropped.
      for (auto& later : pending_) later->ready = false;
      pending_.clear();
      break;
    }
  }
  // Stop reading a connection that does not read its answers, or floods requests.
  if (reading_ && (unsent_bytes_ > host_.connection_limits().max_unsent_bytes || pending_.size() >= kMaxAnswersOwed))
    stop_reading();
}

}  // namespace plantview::service
