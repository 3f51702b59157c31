// `plantview serve`: the HTTP service and its viewer page.
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "plantview/server.h"

namespace plantview::cli {

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
  serve->add_option("--token", options->token, "Bearer token every request must carry (required off loopback)");
  serve->add_option("--device", options->device, "EGL device index");
  serve->add_option("--renderers", options->renderers,
                    "Render threads, each with its own context and vertex arena (0: one per EGL device; "
                    "on a software renderer as the cores allow)")
      ->check(CLI::Range(0u, 64u))->capture_default_str();
  serve->add_option("--web", options->web_directory, "Directory of the viewer page")->capture_default_str();
  auto request_timeout_s = std::make_shared<double>(10.0);
  serve->add_option("--request-timeout", *request_timeout_s,
                    "Seconds a client has to send a whole request (then 408)")
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
    std::string error;
    const int status = service::run_server(o, error);
    if (status != 0) std::cerr << "plantview: " << error << "\n";
    return status;
  };
}

}  // namespace plantview::cli
