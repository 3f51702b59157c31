// `plantview serve`: the HTTP service and its viewer page.
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "plantview/server.h"

namespace plantview::cli {

namespace {

// The bearer token from --token, --token-file or PLANTVIEW_TOKEN (in that order; --token and
// --token-file together are a usage error). A file holds the token on its first line; the line
// end is not part of it. False with a message (exit status in `status`: 2 usage, 1 runtime).
bool resolve_token(const std::string& flag, const std::string& file, std::string& token, std::string& error,
                   int& status) {
  status = 2;
  if (!flag.empty() && !file.empty()) {
    error = "--token and --token-file: give one of them";
    return false;
  }
  if (!flag.empty()) {
    token = flag;
    return true;
  }
  if (!file.empty()) {
    std::ifstream in(file, std::ios::binary);
    status = 1;
    if (!in) {
      error = "--token-file: cannot read '" + file + "'";
      return false;
    }
    std::getline(in, token);
    if (!token.empty() && token.back() == '\r') token.pop_back();
    if (token.empty()) {
      error = "--token-file: '" + file + "' has no token on its first line";
      return false;
    }
    return true;
  }
  if (const char* env = std::getenv("PLANTVIEW_TOKEN"); env && *env) token = env;
  return true;
}

}  // namespace

Action add_serve_command(CLI::App& app) {
  auto options = std::make_shared<service::ServerOptions>();
  auto listen = std::make_shared<std::string>("127.0.0.1:8080");
  auto budget_mb = std::make_shared<uint64_t>(512);
  options->web_directory = PLANTVIEW_WEB_DIR;
  auto* serve = app.add_subcommand("serve", "Serve frames, statistics, picks and the viewer page over HTTP");
  serve->add_option("--store", options->store_directory, "Store directory")->required();
  serve->add_option("--listen", *listen, "HOST:PORT to listen on (port 0: any free port)")->capture_default_str();
  serve->add_option("--vertex-budget", *budget_mb, "GPU vertex arena (MB)")->capture_default_str();
  serve->add_option("--max-clients", options->max_clients, "Open connections at most")->capture_default_str();
  serve->add_option("--max-queue", options->max_queue, "Render requests waiting at most (then 503)")->capture_default_str();
  auto token = std::make_shared<std::string>(), token_file = std::make_shared<std::string>();
  serve->add_option("--token", *token,
                    "Bearer token every request must carry (required off loopback; visible in ps: "
                    "prefer --token-file or PLANTVIEW_TOKEN)");
  serve->add_option("--token-file", *token_file, "File whose first line is the bearer token");
  serve->add_option("--device", options->device, "EGL device index");
  serve->add_option("--renderers", options->renderers,
                    "Render threads, each with its own context and vertex arena (0: one per EGL device; "
                    "on a software renderer as the cores allow)")
      ->check(CLI::Range(0u, 64u))->capture_default_str();
  serve->add_option("--web", options->web_directory, "Directory of the viewer page")->capture_default_str();
  auto request_timeout_s = std::make_shared<double>(10.0);
  serve->add_option("--request-timeout", *request_timeout_s,
                    "Seconds a client has to send a whole request (then 408), its first counted from connecting")
      ->check(CLI::Range(0.05, 3600.0))->capture_default_str();
  auto write_timeout_s = std::make_shared<double>(30.0);
  serve->add_option("--write-timeout", *write_timeout_s,
                    "Seconds a client may leave answers unread before it is disconnected")
      ->check(CLI::Range(0.05, 3600.0))->capture_default_str();
  auto idle_timeout_s = std::make_shared<double>(120.0);
  serve->add_option("--idle-timeout", *idle_timeout_s, "Seconds a keep-alive connection may idle")
      ->check(CLI::Range(0.05, 86400.0))->capture_default_str();
  auto shutdown_timeout_s = std::make_shared<double>(30.0);
  serve->add_option("--shutdown-timeout", *shutdown_timeout_s,
                    "Seconds after SIGTERM before connections still open are closed")
      ->check(CLI::Range(0.0, 3600.0))->capture_default_str();
  serve->add_option("--max-per-address", options->max_clients_per_address,
                    "Open connections from one IP address at most (a load balancer is one address)")
      ->check(CLI::Range(1u, 1u << 20))->capture_default_str();
  serve->add_option("--reserved-clients", options->reserved_clients,
                    "Of --max-clients, connections kept for addresses already served (default: a quarter)");
  auto stream_ping_s = std::make_shared<double>(15.0);
  serve->add_option("--stream-ping", *stream_ping_s,
                    "Seconds between pings on a frame stream (/api/stream); silent for 3 times that, it is closed")
      ->check(CLI::Range(0.05, 3600.0))->capture_default_str();
  return [=]() -> int {
    if (!serve->parsed()) return -1;
    const size_t colon = listen->rfind(':');
    if (colon == std::string::npos) {
      std::cerr << "plantview: --listen: expected HOST:PORT, got '" << *listen << "'\n";
      return 2;
    }
    std::string host = listen->substr(0, colon);
    if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
    int port = -1;
    try {
      size_t used = 0;
      port = std::stoi(listen->substr(colon + 1), &used);
      if (used != listen->size() - colon - 1) port = -1;
    } catch (...) {
      port = -1;
    }
    if (port < 0 || port > 65535 || host.empty()) {
      std::cerr << "plantview: --listen: bad address '" << *listen << "'\n";
      return 2;
    }
    if (*budget_mb < 1 || *budget_mb > 65536) {
      std::cerr << "plantview: --vertex-budget: 1..65536 MB\n";
      return 2;
    }
    service::ServerOptions o = *options;
    o.host = host;
    o.port = uint16_t(port);
    o.vertex_budget_bytes = *budget_mb << 20;
    o.request_timeout_ms = uint32_t(*request_timeout_s * 1000.0);
    o.write_timeout_ms = uint32_t(*write_timeout_s * 1000.0);
    o.idle_timeout_ms = uint32_t(*idle_timeout_s * 1000.0);
    o.shutdown_timeout_ms = uint32_t(*shutdown_timeout_s * 1000.0);
    o.stream_ping_ms = uint32_t(*stream_ping_s * 1000.0);
    if (serve->count("--reserved-clients") == 0) o.reserved_clients = o.max_clients / 4;
    if (o.reserved_clients >= o.max_clients)
      return usage_error("--reserved-clients must be less than --max-clients (" + std::to_string(o.max_clients) + ")");
    std::string error;
    int token_status = 0;
    if (!resolve_token(*token, *token_file, o.token, error, token_status)) {
      std::cerr << "plantview: " << error << "\n";
      return token_status;
    }
    const int status = service::run_server(o, error);
    if (status != 0) std::cerr << "plantview: " << error << "\n";
    return status;
  };
}

}  // namespace plantview::cli
