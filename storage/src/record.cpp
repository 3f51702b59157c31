#include "record.h"

#include <cstring>
#include <type_traits>

namespace plantview::detail {

namespace {

constexpr uint8_t kLayoutVersion = 4;
constexpr uint8_t kGeneralLinear = 0xff;
constexpr uint8_t kScaled = 0x80;

class Writer {
 public:
  explicit Writer(std::vector<uint8_t>& out) : out_(out) {}
  template <typename T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const size_t at = out_.size();
    out_.resize(at + sizeof(T));
    std::memcpy(out_.data() + at, &v, sizeof(T));
  }
  void put_str(std::string_view s) {
    put(uint32_t(s.size()));
    out_.insert(out_.end(), s.begin(), s.end());
  }
  void put_vec3(const glm::vec3& v) { put(v.x); put(v.y); put(v.z); }

 private:
  std::vector<uint8_t>& out_;
};

// Bounds-checked reader: every read fails softly past the end.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : p_(data), end_(data + size) {}
  template <typename T>
  bool get(T& v) {
    if (size_t(end_ - p_) < sizeof(T)) return fail();
    std::memcpy(&v, p_, sizeof(T));
    p_ += sizeof(T);
    return true;
  }
  bool get_str(std::string& s) {
    uint32_t n;
    if (!get(n) || size_t(end_ - p_) < n) return fail();
    s.assign(reinterpret_cast<const char*>(p_), n);
    p_ += n;
    return true;
  }
  bool get_vec3(glm::vec3& v) { return get(v.x) && get(v.y) && get(v.z); }
  bool skip_str() {
    uint32_t n;
    if (!get(n) || size_t(end_ - p_) < n) return fail();
    p_ += n;
    return true;
  }
  bool skip(size_t n) {
    if (size_t(end_ - p_) < n) return fail();
    p_ += n;
    return true;
  }
  // A count of items of at least `min_item_bytes` each must fit in what is left.
  bool get_count(uint32_t& n, size_t min_item_bytes) {
    if (!get(n)) return false;
    if (min_item_bytes && size_t(end_ - p_) / min_item_bytes < n) return fail();
    return true;
  }
  size_t remaining() const { return size_t(end_ - p_); }
  bool at_end() const { return p_ == end_; }

 private:
  static bool fail() { return false; }
  const uint8_t* p_;
  const uint8_t* end_;
};

// The 48 signed permutation matrices times a scale.
bool axis_aligned_code(const glm::mat3& m, uint8_t& code, float& scale) {
  int perm_of[3];
  int signs = 0;
  scale = 0;
  for (int c = 0; c < 3; ++c) {
    int axis = -1;
    for (int r = 0; r < 3; ++r) {
      if (m[c][r] != 0.0f) {
        if (axis >= 0) return false;
        axis = r;
      }
    }
    if (axis < 0) return false;
    const float v = m[c][axis];
    if (c == 0) scale = std::abs(v);
    if (std::abs(v) != scale) return false;
    if (v < 0) signs |= 1 << c;
    perm_of[c] = axis;
  }
  static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int p = 0; p < 6; ++p) {
    if (perms[p][0] == perm_of[0] && perms[p][1] == perm_of[1] && perms[p][2] == perm_of[2]) {
      code = uint8_t(1 + p * 8 + signs);
      if (scale != 1.0f) code |= kScaled;
      return true;
    }
  }
  return false;
}

glm::mat3 axis_aligned_matrix(uint8_t code, float scale) {
  static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  const int index = (code & ~kScaled) - 1;
  const int p = index / 8, signs = index % 8;
  glm::mat3 m(0.0f);
  for (int c = 0; c < 3; ++c) m[c][perms[p][c]] = (signs & (1 << c)) ? -scale : scale;
  return m;
}

// Visits the float fields of every fixed-size shape in declaration order.
template <typename F>
void fields(Box& s, F f) { f(s.size_x_m); f(s.size_y_m); f(s.size_z_m); }
template <typename F>
void fields(Pyramid& s, F f) {
  f(s.bottom_x_m); f(s.bottom_y_m); f(s.top_x_m); f(s.top_y_m); f(s.offset_x_m); f(s.offset_y_m); f(s.height_m);
}
template <typename F>
void fields(Cylinder& s, F f) { f(s.radius_m); f(s.height_m); }
template <typename F>
void fields(Snout& s, F f) {
  f(s.radius_bottom_m); f(s.radius_top_m); f(s.height_m); f(s.offset_x_m); f(s.offset_y_m);
  f(s.bottom_shear_x_rad); f(s.bottom_shear_y_rad); f(s.top_shear_x_rad); f(s.top_shear_y_rad);
}
template <typename F>
void fields(SquareToRound& s, F f) {
  f(s.bottom_x_m); f(s.bottom_y_m); f(s.top_radius_m); f(s.height_m); f(s.offset_x_m); f(s.offset_y_m);
}
template <typename F>
void fields(CircularTorus& s, F f) { f(s.bend_radius_m); f(s.tube_radius_m); f(s.angle_rad); }
template <typename F>
void fields(RectangularTorus& s, F f) { f(s.inner_radius_m); f(s.outer_radius_m); f(s.height_m); f(s.angle_rad); }
template <typename F>
void fields(Sphere& s, F f) { f(s.radius_m); }
template <typename F>
void fields(EllipticalDish& s, F f) { f(s.base_radius_m); f(s.height_m); }
template <typename F>
void fields(SphericalDish& s, F f) { f(s.base_radius_m); f(s.height_m); }
template <typename F>
void fields(Saddle& s, F f) { f(s.length_m); f(s.width_m); f(s.height_m); f(s.cradle_radius_m); }
template <typename F>
void fields(Line& s, F f) { f(s.start_x_m); f(s.end_x_m); }
template <typename F>
void fields(Prism& s, F f) { f(s.sides); f(s.radius_m); f(s.height_m); }

void encode_primitive(const Primitive& p, Writer& w) {
  w.put(uint8_t(p.kind()));
  uint8_t code;
  float scale;
  if (axis_aligned_code(p.placement.linear, code, scale)) {
    w.put(code);
    if (code & kScaled) w.put(scale);
    w.put_vec3(p.placement.translation_m);
  } else {
    w.put(kGeneralLinear);
    w.put_vec3(p.placement.translation_m);
    for (int c = 0; c < 3; ++c) w.put_vec3(p.placement.linear[c]);
  }
  std::visit(
      [&](const auto& shape) {
        using S = std::decay_t<decltype(shape)>;
        if constexpr (std::is_same_v<S, FacetGroup>) {
          w.put(uint32_t(shape.polygon_ends.size()));
          w.put(uint32_t(shape.contour_ends.size()));
          w.put(uint32_t(shape.vertices.size()));
          w.put(uint32_t(shape.triangles.size()));
          for (uint32_t e : shape.polygon_ends) w.put(e);
          for (uint32_t e : shape.contour_ends) w.put(e);
          for (const FacetVertex& v : shape.vertices) { w.put_vec3(v.position_m); w.put_vec3(v.normal); }
          for (uint32_t t : shape.triangles) w.put(t);
        } else {
          S copy = shape;
          fields(copy, [&](auto v) { w.put(v); });
        }
      },
      p.shape);
}

bool decode_primitive(Reader& r, Primitive& p, std::string& error) {
  uint8_t kind = 0, code = 0;
  if (!r.get(kind) || !r.get(code)) return false;
  if (kind >= kPrimitiveKindCount) {
    error = "unknown primitive kind " + std::to_string(kind);
    return false;
  }
  if (code == kGeneralLinear) {
    if (!r.get_vec3(p.placement.translation_m)) return false;
    for (int c = 0; c < 3; ++c) {
      if (!r.get_vec3(p.placement.linear[c])) return false;
    }
  } else {
    const int index = (code & ~kScaled) - 1;
    if (index < 0 || index >= 48) {
      error = "bad placement code " + std::to_string(code);
      return false;
    }
    float scale = 1.0f;
    if ((code & kScaled) && !r.get(scale)) return false;
    p.placement.linear = axis_aligned_matrix(code, scale);
    if (!r.get_vec3(p.placement.translation_m)) return false;
  }
  bool ok = true;
  auto read_shape = [&](auto shape) {
    using S = decltype(shape);
    if constexpr (std::is_same_v<S, FacetGroup>) {
      uint32_t np, nc, nv, nt;
      if (!r.get(np) || !r.get(nc) || !r.get(nv) || !r.get(nt)) return void(ok = false);
      // Counts are checked against the bytes left before anything is allocated.
      const uint64_t need = uint64_t(np) * 4 + uint64_t(nc) * 4 + uint64_t(nv) * 24 + uint64_t(nt) * 4;
      if (need > r.remaining()) return void(ok = false);
      shape.polygon_ends.reserve(np);
      shape.contour_ends.reserve(nc);
      shape.vertices.reserve(nv);
      shape.triangles.reserve(nt);
      for (uint32_t i = 0; i < np && ok; ++i) { uint32_t e = 0; ok = r.get(e); shape.polygon_ends.push_back(e); }
      for (uint32_t i = 0; i < nc && ok; ++i) { uint32_t e = 0; ok = r.get(e); shape.contour_ends.push_back(e); }
      for (uint32_t i = 0; i < nv && ok; ++i) {
        FacetVertex v;
        ok = r.get_vec3(v.position_m) && r.get_vec3(v.normal);
        shape.vertices.push_back(v);
      }
      for (uint32_t i = 0; i < nt && ok; ++i) {
        uint32_t t = 0;
        ok = r.get(t) && t < nv;
        shape.triangles.push_back(t);
      }
    } else {
      fields(shape, [&](auto& v) { ok = ok && r.get(v); });
    }
    p.shape = std::move(shape);
  };
  switch (PrimitiveKind(kind)) {
    case PrimitiveKind::box: read_shape(Box{}); break;
    case PrimitiveKind::pyramid: read_shape(Pyramid{}); break;
    case PrimitiveKind::prism: read_shape(Prism{}); break;
    case PrimitiveKind::cylinder: read_shape(Cylinder{}); break;
    case PrimitiveKind::snout: read_shape(Snout{}); break;
    case PrimitiveKind::square_to_round: read_shape(SquareToRound{}); break;
    case PrimitiveKind::circular_torus: read_shape(CircularTorus{}); break;
    case PrimitiveKind::rectangular_torus: read_shape(RectangularTorus{}); break;
    case PrimitiveKind::sphere: read_shape(Sphere{}); break;
    case PrimitiveKind::elliptical_dish: read_shape(EllipticalDish{}); break;
    case PrimitiveKind::spherical_dish: read_shape(SphericalDish{}); break;
    case PrimitiveKind::saddle: read_shape(Saddle{}); break;
    case PrimitiveKind::line: read_shape(Line{}); break;
    case PrimitiveKind::facet_group: read_shape(FacetGroup{}); break;
  }
  return ok;
}

}  // namespace

void encode_object(const Object& o, std::vector<uint8_t>& out) {
  out.clear();
  Writer w(out);
  w.put(kLayoutVersion);
  w.put(uint8_t(o.object_class));
  w.put(o.colour);
  w.put(o.id);
  for (int i = 0; i < 3; ++i) w.put(o.origin_m[i]);
  w.put_str(o.name);
  w.put_str(o.source);
  w.put(o.pipeline_id);
  w.put(uint32_t(o.primitives.size()));
  for (const Primitive& p : o.primitives) encode_primitive(p, w);
  w.put(uint32_t(o.connections.size()));
  for (const ConnectionPoint& c : o.connections) {
    w.put_vec3(c.position_m);
    w.put_vec3(c.direction);
    w.put(c.diameter_m);
  }
  w.put(uint32_t(o.centreline.size()));
  for (const CentrelineSegment& s : o.centreline) {
    w.put_vec3(s.start_m);
    w.put_vec3(s.end_m);
    w.put(s.diameter_m);
  }
  w.put(uint32_t(o.branches.size()));
  for (const Branch& br : o.branches) {
    w.put_str(br.name);
    w.put(uint32_t(br.members.size()));
    for (uint64_t id : br.members) w.put(id);
  }
}

bool decode_object(const uint8_t* data, size_t size, Object& o, std::string& error) {
  Reader r(data, size);
  o = Object{};
  uint8_t version = 0, object_class = 0;
  bool ok = r.get(version) && r.get(object_class) && r.get(o.colour);
  ok = ok && r.get(o.id);
  if (ok && version != kLayoutVersion) {
    error = "record layout " + std::to_string(version) + " is not " + std::to_string(kLayoutVersion);
    return false;
  }
  if (ok && object_class >= kObjectClassCount) {
    error = "unknown object class " + std::to_string(object_class);
    return false;
  }
  o.object_class = ObjectClass(object_class);
  for (int i = 0; ok && i < 3; ++i) ok = r.get(o.origin_m[i]);
  ok = ok && r.get_str(o.name) && r.get_str(o.source) && r.get(o.pipeline_id);
  uint32_t n = 0;
  // Each count is checked against the bytes left before anything is reserved for it.
  ok = ok && r.get_count(n, 14);  // kind, code, translation at least
  if (ok) o.primitives.reserve(n);
  for (uint32_t i = 0; ok && i < n; ++i) {
    Primitive p;
    ok = decode_primitive(r, p, error);
    if (!error.empty()) return false;
    o.primitives.push_back(std::move(p));
  }
  ok = ok && r.get_count(n, 28);
  if (ok) o.connections.reserve(n);
  for (uint32_t i = 0; ok && i < n; ++i) {
    ConnectionPoint c;
    ok = r.get_vec3(c.position_m) && r.get_vec3(c.direction) && r.get(c.diameter_m);
    o.connections.push_back(c);
  }
  ok = ok && r.get_count(n, 28);
  if (ok) o.centreline.reserve(n);
  for (uint32_t i = 0; ok && i < n; ++i) {
    CentrelineSegment s;
    ok = r.get_vec3(s.start_m) && r.get_vec3(s.end_m) && r.get(s.diameter_m);
    o.centreline.push_back(s);
  }
  ok = ok && r.get_count(n, 8);
  if (ok) o.branches.reserve(n);
  for (uint32_t i = 0; ok && i < n; ++i) {
    Branch br;
    uint32_t m = 0;
    ok = r.get_str(br.name) && r.get_count(m, 8);
    if (ok) br.members.reserve(m);
    for (uint32_t k = 0; ok && k < m; ++k) {
      uint64_t id = 0;
      ok = r.get(id);
      br.members.push_back(id);
    }
    o.branches.push_back(std::move(br));
  }
  if (!ok || !r.at_end()) {
    error = ok ? "trailing bytes in object record" : "object record is truncated";
    return false;
  }
  return true;
}

bool decode_object_key(const uint8_t* data, size_t size, uint64_t& id, uint64_t& pipeline_id,
                       std::string& error) {
  Reader r(data, size);
  uint8_t version = 0, object_class = 0;
  Colour colour;
  glm::dvec3 origin_m;
  const bool ok = r.get(version) && r.get(object_class) && r.get(colour) && r.get(id) &&
                  r.skip(sizeof origin_m) && r.skip_str() && r.skip_str() && r.get(pipeline_id);
  if (ok && version != kLayoutVersion) {
    error = "record layout " + std::to_string(version) + " is not " + std::to_string(kLayoutVersion);
    return false;
  }
  if (!ok) error = "object record is truncated";
  return ok;
}

void encode_attributes(const std::vector<Attribute>& attributes, std::vector<uint8_t>& out) {
  out.clear();
  Writer w(out);
  w.put(uint32_t(attributes.size()));
  for (const Attribute& a : attributes) {
    w.put_str(a.key);
    w.put_str(a.value);
  }
}

bool decode_attributes(const uint8_t* data, size_t size, std::vector<Attribute>& out,
                       std::string& error) {
  Reader r(data, size);
  uint32_t n = 0;
  bool ok = r.get_count(n, 8);
  out.clear();
  for (uint32_t i = 0; ok && i < n; ++i) {
    Attribute a;
    ok = r.get_str(a.key) && r.get_str(a.value);
    out.push_back(std::move(a));
  }
  if (!ok || !r.at_end()) {
    error = ok ? "trailing bytes in attribute record" : "attribute record is truncated";
    return false;
  }
  return true;
}

}  // namespace plantview::detail
