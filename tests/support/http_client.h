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

class HttpClient {
 public:
  explicit HttpClient(int port, int receive_timeout_s = 60);
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

 private:
  bool fill();
  int fd_ = -1;
  bool connected_ = false;
  std::string buffer_;  // received, not yet read
};

}  // namespace plantview::test_support
