#include "server/http.h"

#include <nlohmann/json.hpp>

namespace plantview::service {

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool decode(std::string_view in, std::string& out) {
  out.clear();
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] == '+') {
      out += ' ';
    } else if (in[i] == '%') {
      if (i + 2 >= in.size()) return false;
      const int hi = hex_value(in[i + 1]), lo = hex_value(in[i + 2]);
      if (hi < 0 || lo < 0) return false;
      out += char(hi * 16 + lo);
      i += 2;
    } else {
      out += in[i];
    }
  }
  return true;
}

}  // namespace

bool repeatable_parameter(std::string_view key) { return key == "clip"; }

bool parse_query(std::string_view query, Fields& out, std::string& error) {
  out.clear();
  size_t at = 0;
  while (at < query.size()) {
    size_t end = query.find('&', at);
    if (end == std::string_view::npos) end = query.size();
    const std::string_view part = query.substr(at, end - at);
    at = end + 1;
    if (part.empty()) continue;
    const size_t eq = part.find('=');
    std::string key, value;
    if (!decode(part.substr(0, eq), key) ||
        (eq != std::string_view::npos && !decode(part.substr(eq + 1), value))) {
      error = "bad percent escape in '" + std::string(part.substr(0, 64)) + "'";
      return false;
    }
    if (key.empty()) {
      error = "a query parameter has no name";
      return false;
    }
    for (const auto& [k, v] : out) {
      if (k == key && !repeatable_parameter(key)) {
        error = "parameter '" + key + "' is given twice";
        return false;
      }
    }
    out.emplace_back(std::move(key), std::move(value));
  }
  return true;
}

std::string_view status_text(int status) {
  switch (status) {
    case 101: return "Switching Protocols";
    case 200: return "OK";
    case 204: return "No Content";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 408: return "Request Timeout";
    case 409: return "Conflict";
    case 413: return "Content Too Large";
    case 426: return "Upgrade Required";
    case 431: return "Request Header Fields Too Large";
    case 500: return "Internal Server Error";
    case 503: return "Service Unavailable";
    default: return "Unknown";
  }
}

std::string http_response(int status, std::string_view content_type, std::string_view body,
                          bool keep_alive, const Fields& headers) {
  std::string r;
  r.reserve(body.size() + 256);
  r += "HTTP/1.1 " + std::to_string(status) + " " + std::string(status_text(status)) + "\r\n";
  if (!content_type.empty()) r += "Content-Type: " + std::string(content_type) + "\r\n";
  r += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  r += keep_alive ? "Connection: keep-alive\r\n" : "Connection: close\r\n";
  r += "Cache-Control: no-store\r\n";
  for (const auto& [k, v] : headers) r += k + ": " + v + "\r\n";
  r += "\r\n";
  r += body;
  return r;
}

std::string json_string(std::string_view bytes) {
  return nlohmann::json(std::string(bytes)).dump(-1, ' ', false,
                                                   nlohmann::json::error_handler_t::replace);
}

std::string error_body(std::string_view message) { return "{\"error\":" + json_string(message) + "}\n"; }

std::string http_error(int status, std::string_view message, bool keep_alive,
                       const Fields& headers) {
  return http_response(status, "application/json", error_body(message), keep_alive, headers);
}

}  // namespace plantview::service
