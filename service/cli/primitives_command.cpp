// `plantview primitives [--diameter M] [--json]`: for one representative primitive of every kind
// at the given part diameter, the vertices, triangles (or lines) and geometric error of every
// level. Text on a terminal, JSON (one document on stdout) with --json.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "plantview/primitives.h"

namespace plantview::cli {

namespace {
struct Options {
  float diameter_m = 0.2f;
  bool json = false;
};

int run(const Options& o) {
  if (!(o.diameter_m > 0.0f) || o.diameter_m > 1e4f) {
    char given[32];
    std::snprintf(given, sizeof given, "%g", double(o.diameter_m));
    return usage_error(std::string("primitives: --diameter must be in (0, 10000] metres, got ") + given);
  }
  nlohmann::json kinds = nlohmann::json::array();
  for (const Primitive& p : representative_primitives(o.diameter_m)) {
    const MeshPlan plan = plan_mesh(p);
    nlohmann::json levels = nlohmann::json::array();
    for (uint32_t l = 0; l < plan.level_count; ++l) {
      levels.push_back({{"level", l},
                        {plan.topology == Topology::lines ? "lines" : "triangles",
                         element_count(plan, l)},
                        {"error_m", plan.error_m[l]}});
    }
    kinds.push_back({{"kind", kind_name(p.kind())},
                     {"vertices", plan.vertex_count},
                     {"closed", plan.closed},
                     {"segments", plan.segments[0]},
                     {"levels", levels}});
  }
  if (o.json) {
    std::cout << nlohmann::json{{"diameter_m", o.diameter_m}, {"kinds", kinds}}.dump(2) << "\n";
    return 0;
  }
  std::printf("Tessellation of each primitive kind for a %.3g m part (level 0 = finest)\n",
              double(o.diameter_m));
  std::printf("%-18s %8s  %s\n", "kind", "vertices", "triangles per level (error mm)");
  for (const auto& k : kinds) {
    std::printf("%-18s %8u ", k["kind"].get<std::string>().c_str(), k["vertices"].get<unsigned>());
    for (const auto& l : k["levels"]) {
      const unsigned n = l.contains("lines") ? l["lines"].get<unsigned>()
                                             : l["triangles"].get<unsigned>();
      std::printf(" %6u (%.3g)", n, 1000.0 * l["error_m"].get<double>());
    }
    std::printf("%s\n", k["levels"][0].contains("lines") ? "  [lines]" : "");
  }
  return 0;
}
}  // namespace

Action add_primitives_command(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand(
      "primitives", "Show how every primitive kind tessellates at each level of detail");
  sub->add_option("--diameter", options->diameter_m, "Part diameter in metres (default 0.2)");
  sub->add_flag("--json", options->json, "Write JSON to stdout");
  return [options, sub]() { return sub->parsed() ? run(*options) : -1; };
}

}  // namespace plantview::cli
