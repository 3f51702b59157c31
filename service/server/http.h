// HTTP/1.1 pieces of the service: query strings and response bytes. Pure functions, any thread.
// Requests themselves are parsed in request_parser.h.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace plantview::service {

using Fields = std::vector<std::pair<std::string, std::string>>;

// Splits "a=1&b=x%2Cy" into decoded pairs. False (with a message naming the part) on bad
// percent escapes, empty keys or a repeated key (except those repeatable_parameter allows).
bool parse_query(std::string_view query, Fields& out, std::string& error);
// Keys that may be given more than once, each time adding a value: clip (a clip plane each).
bool repeatable_parameter(std::string_view key);

std::string_view status_text(int status);

// A complete response: status line, headers (Content-Length, Connection and the given ones),
// body.
std::string http_response(int status, std::string_view content_type, std::string_view body,
                          bool keep_alive, const Fields& headers = {});
// The JSON body of an error answer: {"error": message} and a newline.
std::string error_body(std::string_view message);
// {"error": message} with that status.
std::string http_error(int status, std::string_view message, bool keep_alive,
                       const Fields& headers = {});
// JSON string literal of arbitrary bytes (invalid UTF-8 replaced).
std::string json_string(std::string_view bytes);

}  // namespace plantview::service
