// Piping branches: a line's start (name, spec, flange type), its branches member by member along
// the chosen route, and the tail every line kind ends with (finish_branch). Rule: members are
// emitted in flow order, each starting where the previous one ended, and a pipeline object is
// emitted only for a line that built at least one branch.
#include "pipelines.h"

#include <cassert>
#include <cmath>
#include <string>

namespace plantview::gen::pipelines {

namespace {

std::string four_digits(int n) {
  std::string s = std::to_string(n);
  return std::string(s.size() < 4 ? 4 - s.size() : 0, '0') + s;
}

}  // namespace

LineContext Piping::new_line(Service service, int bore) {
  pending_ = Mix{};
  LineContext line(unit_);
  line.service = service;
  line.bore = bore;
  line.name = std::string("/") + service_info(service).code + "-" + unit_.area + "-" +
              four_digits(++line_seq_);
  line.id = unit_.id(line.name);
  unit_.ledger.set_progress(uint64_t(lines_done_ + 1), uint64_t(lines_total_));
  if (service == Service::process) {
    static const char* const kSpecs[] = {"A1A", "B1A", "A3B", "E1A"};
    static const char* const kRatings[] = {"CL150", "CL300", "CL150", "CL150"};
    const uint32_t k = rng_.below(4);
    line.spec = kSpecs[k];
    line.rating = kRatings[k];
  }
  // Flange type of the spec: slip-on or weld neck (a hub cone per flange).
  Mix so, wn;
  for (int i = 0; i < 4; ++i) {
    so += part_mix(Part::flange_so);
    wn += part_mix(Part::flange_wn);
  }
  const Mix options[] = {so, wn};
  line.weld_neck = unit_.ledger.choose(options) == 1;
  line.bend_factor = bend_factor_;
  return line;
}

void Piping::finish_line(LineContext& line) {
  ++lines_done_;
  if (line.branches.empty()) return;
  // The pipeline object sits at its first branch's head; it has no primitives.
  ObjectBuilder b(unit_.origin_m, line_head_, ObjectClass::pipeline);
  Object& o = b.object();
  o.colour = service_info(line.service).colour;
  o.branches = std::move(line.branches);
  const ServiceInfo& svc = service_info(line.service);
  b.attribute("Line number", line.name.substr(1));
  b.attribute("Service", svc.code);
  b.attribute("Fluid", svc.fluid);
  b.attribute("Bore", "DN" + std::to_string(pipe_size(line.bore).dn) + " (" +
                          pipe_size(line.bore).label + ")");
  b.attribute("Spec", line.spec);
  b.attribute("Rating", line.rating);
  b.attribute("Flanges", line.weld_neck ? "Weld neck" : "Slip-on");
  b.attribute("Design pressure", fixed(3.5 + double(rng_.below(300)) / 10.0, 1) + " barg");
  b.attribute("Design temperature", std::to_string(40 + 10 * int(rng_.below(25))) + " degC");
  b.attribute("Insulation", rng_.chance(400) ? "Hot, 50 mm" : "None");
  b.attribute("From", line.from);
  b.attribute("To", line.to);
  b.attribute("Branches", std::to_string(o.branches.size()));
  unit_.emit(b, line.name);
}

bool Piping::pick_route(std::vector<std::vector<dvec3>>& options, int bore,
                        std::vector<dvec3>& pts) {
  if (options.empty()) return false;
  const double r = bend_radius(bore);
  auto mix_of_route = [&](const std::vector<dvec3>& route_pts) {
    Mix m;
    const int corners = int(route_pts.size()) - 2;
    for (int i = 0; i < corners; ++i) m += part_mix(Part::elbow);
    for (int i = route_pipes(route_pts, r); i > 0; --i) m += pipe_mix();
    return m;
  };
  std::vector<Mix> mixes;
  for (const auto& o : options) mixes.push_back(mix_of_route(o));
  pts = std::move(options[unit_.ledger.choose(mixes)]);
  // Jump-overs: a long horizontal run steps up over what it crosses, through four elbows welded
  // to each other at the rises (adds four elbows and two pipes).
  const double rise = 2.0 * r;
  const double width = 2.0 * r + kMinPipe + 0.6;
  Mix jump;
  for (int i = 0; i < 4; ++i) jump += part_mix(Part::elbow);
  jump += pipe_mix();
  jump += pipe_mix();
  for (size_t k = 0; k + 1 < pts.size(); ++k) {
    const dvec3 d = pts[k + 1] - pts[k];
    const double len = glm::length(d);
    const double need = 2.0 * r + 2.0 * kMinPipe + width + 2.0 * r + 1.0;
    if (std::abs(d.z) > 1e-9 || len < need + 4.0) continue;
    if (!unit_.ledger.wants(jump)) continue;
    const dvec3 dir = d / len;
    const double t = (k == 0 ? 0.0 : r) + kMinPipe + 0.5 + (len - need - 1.0) * rng_.unit();
    const dvec3 p = pts[k] + dir * (t + r);
    const dvec3 q = p + dir * width;
    const std::vector<dvec3> jumped{p, p + kUp * rise, q + kUp * rise, q};
    pts.insert(pts.begin() + std::ptrdiff_t(k + 1), jumped.begin(), jumped.end());
    k += 4;
  }
  return true;
}

void Piping::build_branch(LineContext& line, const Port& head, const std::vector<Item>& start_items,
                          const std::vector<dvec3>& pts, std::vector<SegmentSlots>& segs,
                          const std::vector<Item>& end_items,
                          std::vector<std::pair<Slot, Port>>* tee_ports) {
  Run run(line, int(line.branches.size()) + 1, head);
  if (line.branches.empty()) line_head_ = head.position;
  for (const Item& it : start_items) run.straight(it);
  const size_t n = pts.size();
  const Mix two_welds = [] {
    Mix m = part_mix(Part::weld);
    m += part_mix(Part::weld);
    return m;
  }();
  for (size_t k = 0; k + 1 < n; ++k) {
    const dvec3 dir = glm::normalize(pts[k + 1] - pts[k]);
    auto& slots = segs[k].slots;
    std::stable_sort(slots.begin(), slots.end(),
                     [](const Slot& a, const Slot& b) { return a.at < b.at; });
    for (const Slot& slot : slots) {
      const dvec3 p = pts[k] + dir * slot.at;
      if (glm::dot(p - run.position(), dir) > 1e-6) run.pipe_to(p);
      if (slot.tee != TeeUse::none) {
        const Port port = slot.olet ? run.olet(slot.branch_dir, slot.branch_bore)
                                    : run.tee(slot.branch_dir, slot.branch_bore);
        if (tee_ports) tee_ports->push_back({slot, port});
      } else {
        for (const Item& it : slot.items) run.straight(it);
      }
    }
    const bool corner = k + 2 < n;
    const dvec3 end = pts[k + 1] - dir * (corner ? bend_radius(run.bore()) : 0.0);
    if (glm::dot(end - run.position(), dir) > 1e-6) run.pipe_to(end);
    if (corner) {
      const bool welded = unit_.ledger.wants(two_welds);
      if (welded) run.weld();
      run.elbow(pts[k + 1], glm::normalize(pts[k + 2] - pts[k + 1]));
      if (welded) run.weld();
    }
  }
  for (const Item& it : end_items) run.straight(it);
  run.finish();
  add_supports(line, run);
}

// A vent or drain: a short pipe from the tee, then the closure group.
void Piping::build_stub(LineContext& line, const Slot& slot, const Port& port) {
  Run run(line, int(line.branches.size()) + 1, port);
  run.pipe_to(port.position + port.direction * 0.15);
  for (const Item& it : slot.sub_items) run.straight(it);
  run.finish();
}

void Piping::finish_branch(LineContext& line, const Port& head,
                           const std::vector<Item>& start_items, const std::vector<dvec3>& pts,
                           std::vector<SegmentSlots>& segs, const std::vector<Item>& end_items,
                           std::initializer_list<int> joined_nozzles, const TeeBuilder& on_tee) {
  add_optional(line, segs, pts, line.bore);
  std::vector<std::pair<Slot, Port>> ports;
  build_branch(line, head, start_items, pts, segs, end_items, &ports);
  for (const auto& [slot, port] : ports) {
    if (slot.tee == TeeUse::vent || slot.tee == TeeUse::drain) {
      build_stub(line, slot, port);
    } else {
      assert(on_tee && "a forced tee needs its line kind's builder");
      on_tee(slot, port);
    }
  }
  for (int n : joined_nozzles) {
    if (n >= 0) unit_.nozzles[size_t(n)].used = true;
  }
  finish_line(line);
}

}  // namespace plantview::gen::pipelines
