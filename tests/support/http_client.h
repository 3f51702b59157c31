// A small blocking HTTP/1.1 client over one loopback TCP connection, for the service's tests
// and benchmark: send requests (pipelined if wanted), read responses one at a time.
// Threads: one client per thread. Errors: a failed send is false; a failed or closed read is a
// response with status 0. Reads wait at most the receive timeout given at construction.
#pragma once

#include <map>
#include <string>

namespace plantview::test_support {

struct HttpResponse {
  int status = 0;                              // 0: no (complete) response
  std::map<std::string, std::string> headers;  // lower-case names
  std::string body;
};

// How to connect, for tests of per-address limits and of clients that do not read.
struct ConnectOptions {
  std::string source_address;     // "": any; else a local IPv4 address, e.g. "127.0.0.2"
  int receive_buffer_bytes = 0;   // 0: the system's; else SO_RCVBUF, set before connecting
  int receive_timeout_s = 60;
};

class HttpClient {
 public:
  explicit HttpClient(int port, int receive_timeout_s = 60);
  HttpClient(int port, const ConnectOptions& options);
  ~HttpClient();
  HttpClient(const HttpClient&) = delete;
  HttpClient& operator=(const HttpClient&) = delete;

  bool connected() const { return connected_; }
  bool send(const std::string& data);
  // Sends "GET target HTTP/1.1" with a Host header and the given header lines (each ending "\r\n").
  bool get(const std::string& target, const std::string& headers = "");
  // Reads one response (Content-Length framed).
  HttpResponse read();
  HttpResponse request(const std::string& target, const std::string& headers = "");
  // True if the server closed the connection (a read returns 0) within the timeout.
  bool closed_by_server();
  // Sends no more (shutdown(SHUT_WR)); responses can still be read.
  void half_close();
  // Reads and discards until the server closes or resets the connection, or the receive
  // timeout passes. The bytes read (buffered ones included); `closed` says whether it ended by
  // the server's close or reset.
  size_t read_until_closed(bool& closed);

 private:
  bool fill();
  int fd_ = -1;
  bool connected_ = false;
  std::string buffer_;  // received, not yet read
};

}  // namespace plantview::test_support
