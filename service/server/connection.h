// Connections: one per accepted socket. Reads requests (request_parser.h), hands each to the
// host (the server) in order, and writes the answers back in request order (pipelining).
//
// Rules
//   - Threads: the loop thread only, like every libuv handle.
//   - Ownership: a Connection owns its TCP handle and its two timers and deletes itself in the
//     close callback of the last of them. Anyone holding a Connection* learns of its end through
//     ConnectionHost::on_closing (called once, before the handles close) and must drop it then.
//   - Answers are Pending entries, queued when the request completes and filled (answer())
//     now or later; the front is written as soon as it is filled. A Pending stays valid for
//     its holder after the connection closes (it is shared), but filling it then does nothing.
//   - Deadlines (ConnectionLimits, milliseconds):
//       * request_timeout_ms: a new connection must deliver its first complete request within
//         it of being accepted, and every later request within it of its first byte; else 408
//         (when some bytes of a request came) and close, or a silent close (when none came), so
//         that connections that never send a byte cannot hold a slot for long;
//       * idle_timeout_ms: a keep-alive connection with nothing to do closes;
//       * write_timeout_ms: while answer bytes wait to be sent, the client must take some of
//         them within it; a client that stops reading is closed.
//   - Buffering: one with more than max_unsent_bytes written but not yet sent, or 16 answers
//     owed, stops being read until the client catches up; with the write deadline this bounds
//     what a client that never reads costs. A request line and headers over the parser's
//     limits, or malformed HTTP, is answered (431, 413 or 400) and the connection closes.
//   - After an answer with "Connection: close" nothing more is read or answered.
//   - A client that half-closes (shutdown(SHUT_WR) after its requests) gets every answer owed
//     for the requests it completed, then the connection closes.
//   - While the host shuts down (drains), the last answer a connection owes says
//     "Connection: close", and the connection closes once it has been sent.
//   - WebSocket (websocket.h): a request that asks to upgrade is the last one read as HTTP. The
//     host either answers it with accept_websocket() (101; once it is written the connection
//     carries WebSocket frames, and the bytes after the request are the first of them) or with
//     an error reply, after which the connection closes. On a WebSocket the request and idle
//     deadlines no longer apply (the host keeps the stream alive: ping, idle close); the write
//     deadline and max_unsent_bytes still do. Pings are answered with pongs here; messages go
//     to the host (on_ws_message); a frame that breaks the RFC's rules is answered with a close
//     frame with its code, and the connection closes once that is sent.
// Errors: a failed write or a reset closes the connection; answers still owed are dropped.
#pragma once

#include <uv.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <string>

#include "server/request_parser.h"
#include "server/routes.h"
#include "server/websocket.h"

namespace plantview::service {

// One request's place in its connection's answer order.
struct Pending {
  bool ready = false;
  bool keep_alive = true;
  Reply reply;           // the answer, once ready (made into bytes when it is written)
  std::string endpoint;  // for the metrics
  std::string upgrade;   // accept_websocket: the 101 response, written as is
};

struct ConnectionLimits {
  RequestLimits request;
  uint32_t request_timeout_ms = 10000;
  uint32_t idle_timeout_ms = 120000;
  uint32_t write_timeout_ms = 30000;
  uint64_t max_unsent_bytes = 32ull << 20;
  size_t max_message_bytes = 65536;  // a WebSocket message from the client (else 1009)
};

class Connection;

// What a connection needs of its server (loop thread).
class ConnectionHost {
 public:
  virtual const ConnectionLimits& connection_limits() const = 0;
  virtual bool shutting_down() const = 0;
  // A complete request: answer it through connection.answer(pending, ...), now or later.
  virtual void on_request(Connection& connection, const Request& request,
                          const std::shared_ptr<Pending>& pending) = 0;
  // An answer left for the client (for the metrics).
  virtual void on_answered(const std::string& endpoint, int status) = 0;
  // A deadline passed and the connection closes (for the metrics).
  virtual void on_timed_out() = 0;
  // The connection is closing: forget it (its answers owed will not be sent).
  virtual void on_closing(Connection& connection) = 0;
  // A complete WebSocket message from the client (text: valid UTF-8).
  virtual void on_ws_message(Connection& /*connection*/, bool /*text*/, std::string& /*payload*/) {}

 protected:
  ~ConnectionHost() = default;
};

class Connection {
 public:
  // Accepts a connection from `listener`; null if that failed (nothing to clean up then). It
  // reads nothing until start() or refuse().
  static Connection* accept(uv_stream_t* listener, ConnectionHost& host, uint64_t id);
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  void start();                     // reads requests
  void refuse(const Reply& reply);  // answers once (with reply, e.g. 503) and closes
  uint64_t id() const { return id_; }
  // The peer's IP address as text ("127.0.0.1", "::1"); "" if the socket could not tell.
  const std::string& address() const { return address_; }

  // Fills `pending` with the reply (counted in the metrics unless `count` is false) and writes
  // what is ready. reply.close, or a request without keep-alive: the connection closes after it.
  void answer(const std::shared_ptr<Pending>& pending, Reply reply, bool count = true);
  void stop_reading();
  // Answers an upgrade request with `response` (a complete 101 response); the connection speaks
  // WebSocket once it has been written.
  void accept_websocket(const std::shared_ptr<Pending>& pending, std::string response);
  bool websocket() const { return websocket_; }
  // Sends one message (a text or binary frame, or a ping). Nothing once a close has been sent.
  void send_ws(ws::Opcode opcode, std::string_view payload);
  // Sends a close frame and reads no more; the connection closes once it is written (or at the
  // write deadline).
  void close_ws(uint16_t code, std::string_view reason);
  bool ws_closing() const { return ws_close_sent_; }
  uint64_t last_read_ms() const { return last_read_ms_; }  // uv_now when bytes last arrived
  uint64_t unsent_bytes() const { return unsent_bytes_; }
  bool finished() const { return pending_.empty() && unsent_bytes_ == 0; }  // nothing owed
  void close();

 private:
  Connection(ConnectionHost& host, uint64_t id);
  ~Connection() = default;  // in the last close callback
  static void on_closed(uv_handle_t* handle);

  void on_read(ssize_t n, const uv_buf_t* buf);
  void on_written(size_t bytes, int status);
  void on_timer();
  void on_write_timer();
  void read_bytes(std::string_view bytes);
  void read_ws(std::string_view bytes);
  void fail(const RequestError& error);  // answers a request that cannot be parsed, and closes
  void write(std::string data);
  void flush();
  void start_reading();
  void restart_timer(uint32_t ms);
  uint64_t bytes_sent() const;  // bytes handed to the kernel so far
  std::shared_ptr<Pending> push_pending(std::string endpoint);

  uv_tcp_t tcp_{};
  uv_timer_t timer_{};        // request, idle deadlines
  uv_timer_t write_timer_{};  // write deadline: runs while bytes wait to be sent
  int open_handles_ = 3;
  ConnectionHost& host_;
  uint64_t id_ = 0;
  std::string address_;
  RequestParser parser_;
  std::deque<std::shared_ptr<Pending>> pending_;  // answers in request order
  uint64_t unsent_bytes_ = 0;                     // written, not yet completed
  uint64_t written_bytes_ = 0;                    // every byte ever passed to write()
  uint64_t sent_at_last_check_ = 0;               // bytes_sent() when the write deadline last looked
  bool reading_ = false, closing_ = false;
  bool no_more_ = false;   // a request said Connection: close, or an error is being answered
  bool peer_done_ = false;  // the client half-closed: answer what it asked, then close
  bool served_ = false;     // a request has completed on this connection
  // WebSocket: upgrading_ from the upgrade request until its answer is written; then websocket_.
  bool upgrading_ = false, websocket_ = false, ws_close_sent_ = false;
  std::string early_bytes_;  // bytes after the upgrade request, for the deframer
  ws::Deframer deframer_;
  uint64_t last_read_ms_ = 0;
};

}  // namespace plantview::service
