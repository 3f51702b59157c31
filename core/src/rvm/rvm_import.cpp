// RVM groups to plant objects: classification by PDMS type, pipelines and their derived topology.
#include "plantview/rvm_import.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <unordered_map>

namespace plantview {

namespace {

enum class Role { container, equipment, pipeline, branch, pipe, component, structure, element, other };

Role role_of(std::string_view type) {
  static const std::unordered_map<std::string_view, Role> roles = {
      {"WORL", Role::container}, {"SITE", Role::container}, {"ZONE", Role::container},
      {"EQUI", Role::equipment},
      {"PIPE", Role::pipeline},  {"BRAN", Role::branch},
      {"TUBE", Role::pipe},      {"TUBI", Role::pipe},
      {"ELBO", Role::component}, {"BEND", Role::component}, {"TEE", Role::component},
      {"OLET", Role::component}, {"FLAN", Role::component}, {"GASK", Role::component},
      {"VALV", Role::component}, {"VTWA", Role::component}, {"VFWA", Role::component},
      {"REDU", Role::component}, {"CAP", Role::component},  {"INST", Role::component},
      {"PCOM", Role::component}, {"FBLI", Role::component}, {"COUP", Role::component},
      {"CROS", Role::component}, {"UNIO", Role::component}, {"WELD", Role::component},
      {"ATTA", Role::component}, {"FTUB", Role::component}, {"TRAP", Role::component},
      {"FILT", Role::component}, {"LJSE", Role::component}, {"CLOS", Role::component},
      {"STRU", Role::structure}, {"FRMW", Role::structure}, {"SBFR", Role::structure},
      {"SUBS", Role::structure}, {"SCTN", Role::structure}, {"PANE", Role::structure},
      {"GENSEC", Role::structure}, {"FITT", Role::structure}, {"PFIT", Role::structure},
      {"SJOI", Role::structure}, {"PJOI", Role::structure}, {"GWALL", Role::structure},
      {"FLOOR", Role::structure}, {"SCREED", Role::structure}, {"STWALL", Role::structure},
      {"BOX", Role::element},  {"CYLI", Role::element}, {"CONE", Role::element},
      {"SNOU", Role::element}, {"DISH", Role::element}, {"PYRA", Role::element},
      {"TORU", Role::element}, {"RTOR", Role::element}, {"SLCY", Role::element},
      {"EXTR", Role::element}, {"REVO", Role::element}, {"POHE", Role::element},
      {"POLY", Role::element}, {"TEXT", Role::element}, {"DRAW", Role::element},
      {"NBOX", Role::element}, {"NCYL", Role::element}, {"NCON", Role::element},
      {"NSNO", Role::element}, {"NDIS", Role::element}, {"NPYR", Role::element},
      {"NTOR", Role::element}, {"NRTO", Role::element}, {"NSLC", Role::element},
      {"NXTR", Role::element}, {"NREV", Role::element}, {"SPHE", Role::element},
      {"ELPS", Role::element}, {"LOOP", Role::element}, {"VERT", Role::element},
  };
  const auto it = roles.find(type);
  return it == roles.end() ? Role::other : it->second;
}

Colour class_colour(ObjectClass c, uint8_t transparency_percent) {
  Colour colour;
  switch (c) {
    case ObjectClass::equipment: colour = {96, 140, 196, 255}; break;
    case ObjectClass::pipeline:
    case ObjectClass::pipe: colour = {214, 196, 92, 255}; break;
    case ObjectClass::component: colour = {222, 128, 58, 255}; break;
    case ObjectClass::structure: colour = {150, 146, 138, 255}; break;
    case ObjectClass::other: colour = {170, 170, 170, 255}; break;
  }
  colour.a = uint8_t(255 * (100 - std::min<int>(transparency_percent, 100)) / 100);
  return colour;
}

float column_length(const glm::mat3& m, int c) { return glm::length(m[c]); }

struct End {
  glm::vec3 position, direction;
  float diameter;
};

// The two ends of a piping part's run, in object-relative coordinates; false if it has none.
// Also fills the centreline.
bool piping_ends(const Object& o, End& a, End& b, std::vector<CentrelineSegment>& centreline) {
  const Primitive* best = nullptr;
  float best_length = -1;
  for (const Primitive& p : o.primitives) {
    if (const auto* t = std::get_if<CircularTorus>(&p.shape)) {
      const float len = t->bend_radius_m * t->angle_rad * column_length(p.placement.linear, 0);
      if (len > best_length + 1e-6f || (best && !std::holds_alternative<CircularTorus>(best->shape))) {
        best = &p;
        best_length = len;
      }
    }
  }
  if (best) {  // an elbow: its sweep's ends
    const auto& t = std::get<CircularTorus>(best->shape);
    const glm::mat3& m = best->placement.linear;
    const glm::vec3& tr = best->placement.translation_m;
    const float R = t.bend_radius_m, phi = t.angle_rad;
    const glm::vec3 p0(R, 0, 0), p1(R * std::cos(phi), R * std::sin(phi), 0);
    const glm::vec3 d0(0, -1, 0), d1(-std::sin(phi), std::cos(phi), 0);
    const float scale = column_length(m, 0);
    a = {m * p0 + tr, glm::normalize(m * d0), 2 * t.tube_radius_m * scale};
    b = {m * p1 + tr, glm::normalize(m * d1), 2 * t.tube_radius_m * scale};
    const float reach = std::abs(phi - std::numbers::pi_v<float>) < 1e-3f ? 0.0f : R * std::tan(0.5f * phi);
    const glm::vec3 corner = m * (p0 + reach * glm::vec3(0, 1, 0)) + tr;
    centreline.push_back({a.position, corner, a.diameter});
    centreline.push_back({corner, b.position, b.diameter});
    return true;
  }
  for (const Primitive& p : o.primitives) {
    float len = -1;
    if (const auto* c = std::get_if<Cylinder>(&p.shape)) len = c->height_m;
    if (const auto* s = std::get_if<Snout>(&p.shape)) len = s->height_m;
    len *= column_length(p.placement.linear, 2);
    if (len > best_length) {
      best = &p;
      best_length = len;
    }
  }
  if (!best || best_length <= 0) return false;
  glm::vec3 bottom, top;
  float rb, rt;
  if (const auto* c = std::get_if<Cylinder>(&best->shape)) {
    bottom = {0, 0, -0.5f * c->height_m};
    top = {0, 0, 0.5f * c->height_m};
    rb = rt = c->radius_m;
  } else {
    const auto& s = std::get<Snout>(best->shape);
    bottom = {-0.5f * s.offset_x_m, -0.5f * s.offset_y_m, -0.5f * s.height_m};
    top = {0.5f * s.offset_x_m, 0.5f * s.offset_y_m, 0.5f * s.height_m};
    rb = s.radius_bottom_m;
    rt = s.radius_top_m;
  }
  const glm::mat3& m = best->placement.linear;
  const glm::vec3& tr = best->placement.translation_m;
  const glm::vec3 axis = glm::normalize(m * glm::vec3(0, 0, 1));
  const float scale = column_length(m, 0);
  a = {m * bottom + tr, -axis, 2 * rb * scale};
  b = {m * top + tr, axis, 2 * rt * scale};
  centreline.push_back({a.position, b.position, std::max(a.diameter, b.diameter)});
  return true;
}

void derive_piping(Object& o) {
  End a, b;
  o.connections.clear();
  o.centreline.clear();
  if (!piping_ends(o, a, b, o.centreline)) return;
  o.connections.push_back({a.position, a.direction, a.diameter});
  o.connections.push_back({b.position, b.direction, b.diameter});
}

class Converter {
 public:
  Converter(const AttributeFile* attributes, std::string_view source, RvmImportSummary& summary)
      : source_(source), summary_(summary) {
    if (attributes) {
      index_ = index_attribute_blocks(*attributes);
      have_attributes_ = true;
    }
  }

  void visit(const RvmGroup& g, ObjectClass enclosing) {
    const AttributeBlock* block = block_of(g);
    if (!have_attributes_) {
      emit_own(g, ObjectClass::other, false);
      for (const RvmGroup& child : g.children) visit(child, ObjectClass::other);
      return;
    }
    const std::string* type = block ? block->find("Type") : nullptr;
    const Role role = type ? role_of(*type) : Role::other;
    switch (role) {
      case Role::container: {
        // Objects below remember their site and zone (areas of review views); the groups
        // themselves are not objects.
        std::string* level = *type == "SITE" ? &site_ : *type == "ZONE" ? &zone_ : nullptr;
        const std::string outer = level ? *level : std::string();
        if (level) *level = g.name;
        for (const RvmGroup& child : g.children) visit(child, ObjectClass::other);
        if (level) *level = outer;
        return;
      }
      case Role::equipment:
        emit_whole(g, ObjectClass::equipment, 0);
        return;
      case Role::pipeline:
        visit_pipeline(g);
        return;
      case Role::pipe:
      case Role::component:
        emit_whole(g, role == Role::pipe ? ObjectClass::pipe : ObjectClass::component, 0);
        return;
      case Role::element:
        emit_whole(g, enclosing, 0);
        return;
      case Role::structure:
      case Role::branch:  // a branch outside a pipeline: its parts as objects of their own
      case Role::other: {
        const ObjectClass c = role == Role::structure ? ObjectClass::structure : enclosing;
        emit_own(g, c, true);
        for (const RvmGroup& child : g.children) {
          if (!is_element(child)) visit(child, c);
        }
        return;
      }
    }
  }

  std::vector<Object> take() { return std::move(objects_); }

 private:
  const AttributeBlock* block_of(const RvmGroup& g) {
    if (!have_attributes_) return nullptr;
    const auto it = index_.find(g.name);
    if (it == index_.end()) return nullptr;
    return it->second;
  }

  bool is_element(const RvmGroup& g) {
    const AttributeBlock* b = block_of(g);
    const std::string* type = b ? b->find("Type") : nullptr;
    return type && role_of(*type) == Role::element;
  }

  Object make(const RvmGroup& g, ObjectClass c) {
    Object o;
    const int n = ++name_counts_[g.name];
    o.name = n == 1 ? g.name : g.name + " #" + std::to_string(n);
    if (n > 1) {
      summary_.warnings.push_back("group name '" + g.name + "' repeats; renamed '" + o.name + "'");
    }
    o.source = source_;
    o.id = object_id(source_, o.name);
    o.object_class = c;
    o.colour = class_colour(c, g.transparency_percent);
    const AttributeBlock* b = block_of(g);
    if (b) {
      for (const auto& [k, v] : b->attributes) o.attributes.push_back({k, v});
    }
    if (!site_.empty() && !(b && b->find("Site"))) o.attributes.push_back({"Site", site_});
    if (!zone_.empty() && !(b && b->find("Zone"))) o.attributes.push_back({"Zone", zone_});
    return o;
  }

  void add(Object& o, const RvmPrimitive& p) {
    if (o.primitives.empty()) o.origin_m = glm::dvec3(p.primitive.placement.translation_m);
    Primitive copy = p.primitive;
    copy.placement.translation_m =
        glm::vec3(glm::dvec3(p.primitive.placement.translation_m) - o.origin_m);
    o.primitives.push_back(std::move(copy));
  }

  void add_subtree(Object& o, const RvmGroup& g) {
    for (const RvmPrimitive& p : g.primitives) add(o, p);
    for (const RvmGroup& child : g.children) add_subtree(o, child);
  }

  // One object with every primitive of the subtree.
  void emit_whole(const RvmGroup& g, ObjectClass c, uint64_t pipeline_id) {
    Object o = make(g, c);
    add_subtree(o, g);
    o.pipeline_id = pipeline_id;
    if (c == ObjectClass::pipe || c == ObjectClass::component) derive_piping(o);
    if (o.primitives.empty() && c != ObjectClass::pipeline) return;
    objects_.push_back(std::move(o));
  }

  // One object with the group's own primitives (and its primitive-element children's), if any.
  void emit_own(const RvmGroup& g, ObjectClass c, bool with_elements) {
    Object o = make(g, c);
    for (const RvmPrimitive& p : g.primitives) add(o, p);
    if (with_elements) {
      for (const RvmGroup& child : g.children) {
        if (is_element(child)) add_subtree(o, child);
      }
    }
    if (!o.primitives.empty()) objects_.push_back(std::move(o));
    else --name_counts_[g.name];  // not emitted: its name stays free
  }

  void visit_pipeline(const RvmGroup& g) {
    Object pipeline = make(g, ObjectClass::pipeline);
    for (const RvmPrimitive& p : g.primitives) add(pipeline, p);
    for (const RvmGroup& child : g.children) {
      const AttributeBlock* b = block_of(child);
      const std::string* type = b ? b->find("Type") : nullptr;
      if (!type || role_of(*type) != Role::branch) {
        visit(child, ObjectClass::component);
        continue;
      }
      Branch branch;
      branch.name = child.name;
      const size_t first = objects_.size();
      // Tubes exported as primitives right under the branch: one pipe each.
      int tube = 0;
      for (const RvmPrimitive& p : child.primitives) {
        Object o = make(RvmGroup{child.name + "/TUBE " + std::to_string(++tube), {}, 0,
                                 child.transparency_percent, false, {}, {}, 0},
                        ObjectClass::pipe);
        add(o, p);
        o.pipeline_id = pipeline.id;
        derive_piping(o);
        objects_.push_back(std::move(o));
      }
      for (const RvmGroup& member : child.children) {
        const AttributeBlock* mb = block_of(member);
        const std::string* mt = mb ? mb->find("Type") : nullptr;
        const bool is_pipe = mt && role_of(*mt) == Role::pipe;
        emit_whole(member, is_pipe ? ObjectClass::pipe : ObjectClass::component, pipeline.id);
      }
      order_by_flow(first, first + size_t(tube));
      for (size_t i = first; i < objects_.size(); ++i) branch.members.push_back(objects_[i].id);
      pipeline.branches.push_back(std::move(branch));
    }
    objects_.push_back(std::move(pipeline));
  }

  // Orders a branch's members [first, end) into a chain: from the member with an end that meets
  // nobody, each next member is the one whose connection point is nearest the current exit. The
  // chain runs the way the file lists the branch's component groups (from first_group on), which
  // PDMS writes in flow order; implied tubes (before first_group) fall in where they connect.
  void order_by_flow(size_t first, size_t first_group) {
    const size_t n = objects_.size() - first;
    if (n < 2) return;
    auto ends = [&](const Object& o) {
      std::vector<glm::dvec3> out;
      for (const ConnectionPoint& c : o.connections) out.push_back(o.origin_m + glm::dvec3(c.position_m));
      return out;
    };
    std::vector<std::vector<glm::dvec3>> points;
    for (size_t i = first; i < objects_.size(); ++i) points.push_back(ends(objects_[i]));
    auto nearest_other = [&](size_t i, const glm::dvec3& p, const std::vector<bool>& used) {
      double best = INFINITY;
      size_t which = n;
      for (size_t j = 0; j < n; ++j) {
        if (j == i || used[j]) continue;
        for (const glm::dvec3& q : points[j]) {
          const double d = glm::length(q - p);
          if (d < best) { best = d; which = j; }
        }
      }
      return std::pair{which, best};
    };
    // Start: the member with the loneliest end.
    size_t start = 0;
    double loneliest = -1;
    std::vector<bool> none(n, false);
    for (size_t i = 0; i < n; ++i) {
      for (const glm::dvec3& p : points[i]) {
        const double d = nearest_other(i, p, none).second;
        if (d > loneliest && std::isfinite(d)) { loneliest = d; start = i; }
      }
    }
    std::vector<bool> used(n, false);
    std::vector<size_t> order{start};
    used[start] = true;
    while (order.size() < n) {
      const size_t cur = order.back();
      auto [next, d] = std::pair{n, double(INFINITY)};
      for (const glm::dvec3& p : points[cur]) {
        auto [j, dj] = nearest_other(cur, p, used);
        if (dj < d) { next = j; d = dj; }
      }
      if (next == n) {  // no connection points: keep file order for the rest
        for (size_t j = 0; j < n; ++j) if (!used[j]) { next = j; break; }
      }
      used[next] = true;
      order.push_back(next);
    }
    if (first_group + 1 < objects_.size()) {
      const size_t first_pos = size_t(std::find(order.begin(), order.end(), first_group - first) - order.begin());
      const size_t last_pos = size_t(std::find(order.begin(), order.end(), n - 1) - order.begin());
      if (first_pos > last_pos) std::reverse(order.begin(), order.end());
    }
    std::vector<Object> sorted;
    sorted.reserve(n);
    for (size_t i : order) sorted.push_back(std::move(objects_[first + i]));
    for (size_t i = 0; i < n; ++i) objects_[first + i] = std::move(sorted[i]);
  }

  std::string source_;
  RvmImportSummary& summary_;
  AttributeIndex index_;
  bool have_attributes_ = false;
  std::unordered_map<std::string, int> name_counts_;
  std::vector<Object> objects_;
  std::string site_, zone_;  // names of the SITE and ZONE groups being visited ("": none)
};

void count(const RvmGroup& g, const AttributeIndex* index, RvmImportSummary& s) {
  ++s.groups;
  s.primitives += g.primitives.size();
  if (index && index->count(g.name)) ++s.groups_with_attributes;
  for (const RvmGroup& c : g.children) count(c, index, s);
}

}  // namespace

std::vector<Object> rvm_to_objects(const RvmFile& file, const AttributeFile* attributes,
                                   std::string_view source, RvmImportSummary& summary) {
  summary = {};
  for (const ParseWarning& w : file.warnings) summary.warnings.push_back(w.message);
  AttributeIndex index;
  if (attributes) index = index_attribute_blocks(*attributes);
  for (const RvmGroup& g : file.roots) count(g, attributes ? &index : nullptr, summary);
  summary.primitives += file.root_primitives.size();

  Converter converter(attributes, source, summary);
  for (const RvmGroup& g : file.roots) converter.visit(g, ObjectClass::other);
  std::vector<Object> objects = converter.take();
  if (!file.root_primitives.empty()) {
    Object o;
    o.name = "(root)";
    o.source = std::string(source);
    o.id = object_id(source, o.name);
    o.colour = class_colour(ObjectClass::other, 0);
    o.origin_m = glm::dvec3(file.root_primitives.front().primitive.placement.translation_m);
    for (const RvmPrimitive& p : file.root_primitives) {
      Primitive copy = p.primitive;
      copy.placement.translation_m = glm::vec3(glm::dvec3(copy.placement.translation_m) - o.origin_m);
      o.primitives.push_back(std::move(copy));
    }
    objects.push_back(std::move(o));
  }
  summary.objects = objects.size();
  return objects;
}

}  // namespace plantview
