// `plantview measure --store S --a TAG|ID --b TAG|ID [--json]`: the minimum distance between two
// objects, the two closest points and the error bound (plantview/measure.h). Exit 1 for an
// unknown, ambiguous or empty object or an unreadable store (the message names it), 2 for usage.
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "plantview/measure.h"
#include "plantview/store.h"

namespace plantview::cli {

namespace {

int fail(const std::string& message) {
  std::cerr << "plantview measure: " << message << "\n";
  return 1;
}

std::string label(const Object& o) { return (o.name.empty() ? std::string("(no tag)") : o.name) + " (id " + std::to_string(o.id) + ")"; }

std::string xyz(const glm::dvec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.4f, %.4f, %.4f", p.x, p.y, p.z);
  return buf;
}

int run_measure(const std::string& directory, const std::string& a, const std::string& b, bool json) {
  if (a.empty() || b.empty()) return usage_error("measure: --a and --b name objects (a tag or an id)");
  std::string error;
  const auto store = Store::open(directory, Store::Mode::read_only, error);
  if (!store) return fail(error);
  const auto view = store->read(error);
  if (!view) return fail(error);
  const StoreMeasurement m = measure_in_store(*view, a, b);
  if (m.outcome != StoreMeasurement::Outcome::measured) return fail(m.message);
  const Clearance& c = m.clearance;
  if (json) {
    std::cout << clearance_json(m.a, m.b, c) << "\n";
    return 0;
  }
  const glm::dvec3 d = c.point_b_m - c.point_a_m;
  char line[160];
  std::snprintf(line, sizeof line, "distance %.4f m (%.1f mm)", c.distance_m, c.distance_m * 1000.0);
  std::cout << line;
  if (c.overlapping) {
    std::snprintf(line, sizeof line, ": they overlap (penetration %.1f mm%s)", c.penetration_m * 1000.0,
                  c.penetration_m > 0 ? "" : ", depth unknown");
    std::cout << line;
  }
  std::cout << "\n";
  std::cout << "  A " << label(m.a) << " at " << xyz(c.point_a_m) << "\n";
  std::cout << "  B " << label(m.b) << " at " << xyz(c.point_b_m) << "\n";
  std::snprintf(line, sizeof line, "  dx %.4f  dy %.4f  dz %.4f m (B - A)", d.x, d.y, d.z);
  std::cout << line << "\n";
  if (c.analytic) {
    std::cout << "  method analytic (exact primitives), error 0\n";
  } else {
    std::snprintf(line, sizeof line, "  method tessellated, error at most %.2f mm", c.error_m * 1000.0);
    std::cout << line << "\n";
  }
  return 0;
}

}  // namespace

Action add_measure_command(CLI::App& app) {
  auto store = std::make_shared<std::string>(), a = std::make_shared<std::string>(),
       b = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* measure = app.add_subcommand("measure", "Minimum distance between two objects and their closest points");
  measure->add_option("--store", *store, "Store directory")->required();
  measure->add_option("--a", *a, "First object: a tag or an id")->required();
  measure->add_option("--b", *b, "Second object: a tag or an id")->required();
  measure->add_flag("--json", *json, "Print one JSON object");
  return [=]() -> int { return measure->parsed() ? run_measure(*store, *a, *b, *json) : -1; };
}

}  // namespace plantview::cli
