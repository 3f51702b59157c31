#include "support/http_client.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdlib>

namespace plantview::test_support {

HttpClient::HttpClient(int port, int receive_timeout_s)
    : HttpClient(port, ConnectOptions{"", 0, receive_timeout_s}) {}

HttpClient::HttpClient(int port, const ConnectOptions& options) {
  fd_ = socket(AF_INET, SOCK_STREAM, 0);
  if (options.receive_buffer_bytes > 0)
    setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes, sizeof options.receive_buffer_bytes);
  if (!options.source_address.empty()) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    if (inet_pton(AF_INET, options.source_address.c_str(), &local.sin_addr) != 1 ||
        bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0)
      return;  // not connected
  }
  const int receive_timeout_s = options.receive_timeout_s;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  timeval tv{receive_timeout_s, 0};
  setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
}

HttpClient::~HttpClient() { close(fd_); }

bool HttpClient::send(const std::string& data) {
  size_t at = 0;
  while (at < data.size()) {
    const ssize_t n = ::send(fd_, data.data() + at, data.size() - at, MSG_NOSIGNAL);
    if (n <= 0) return false;
    at += size_t(n);
  }
  return true;
}

bool HttpClient::get(const std::string& target, const std::string& headers) {
  return send("GET " + target + " HTTP/1.1\r\nHost: test\r\n" + headers + "\r\n");
}

HttpResponse HttpClient::read() {
  HttpResponse r;
  size_t end;
  while ((end = buffer_.find("\r\n\r\n")) == std::string::npos)
    if (!fill()) return r;
  const std::string head = buffer_.substr(0, end);
  buffer_.erase(0, end + 4);
  r.status = std::atoi(head.c_str() + 9);
  size_t line = head.find("\r\n");
  while (line != std::string::npos) {
    const size_t next = head.find("\r\n", line + 2);
    const std::string h = head.substr(line + 2, next == std::string::npos ? std::string::npos : next - line - 2);
    const size_t colon = h.find(':');
    if (colon != std::string::npos) {
      std::string name = h.substr(0, colon);
      for (auto& ch : name) ch = char(std::tolower(static_cast<unsigned char>(ch)));
      r.headers[name] = h.substr(colon + 2);
    }
    line = next;
  }
  const size_t length = std::stoul(r.headers.count("content-length") ? r.headers["content-length"] : "0");
  while (buffer_.size() < length)
    if (!fill()) return HttpResponse{};
  r.body = buffer_.substr(0, length);
  buffer_.erase(0, length);
  return r;
}

HttpResponse HttpClient::request(const std::string& target, const std::string& headers) {
  if (!get(target, headers)) return {};
  return read();
}

bool HttpClient::closed_by_server() {
  char c;
  return recv(fd_, &c, 1, 0) == 0;
}

void HttpClient::half_close() { shutdown(fd_, SHUT_WR); }

size_t HttpClient::read_until_closed(bool& closed) {
  size_t total = buffer_.size();
  buffer_.clear();
  char chunk[65536];
  for (;;) {
    const ssize_t n = recv(fd_, chunk, sizeof chunk, 0);
    if (n > 0) {
      total += size_t(n);
      continue;
    }
    closed = n == 0 || errno == ECONNRESET;
    return total;
  }
}

bool HttpClient::fill() {
  char chunk[65536];
  const ssize_t n = recv(fd_, chunk, sizeof chunk, 0);
  if (n <= 0) return false;
  buffer_.append(chunk, size_t(n));
  return true;
}

}  // namespace plantview::test_support
