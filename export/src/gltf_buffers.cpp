// A glTF file's vertex and index data: each mesh's box and quantization grid, its vertices
// (float or quantized) and indices appended to their parts, and the accessors that read them
// (rules in gltf_file.h, "Data").
#include <algorithm>
#include <cmath>

#include "gltf_file_state.h"
#include "gltf_text.h"

namespace plantview::detail::gltf {

namespace {

constexpr double kQuantized = 32767.0;  // normalized int16: q / 32767
// Dequantization scales: the smallest that holds a mesh's half extent, from numbers short to
// write (a node's scale carries it); 1 (no scale at all) for meshes up to 2 m across.
constexpr double kGridScales[] = {1, 1.5, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256,
                                  384, 512, 768, 1024, 1536, 2048, 3072, 4096};

// The int8 normal nearest `n`: rounded, or where that lands more than 0.004 off unit length
// (the validator allows 0.00674; rounding can land just outside), the neighbour closest in
// direction and length.
void quantize_normal(const float n[3], int8_t out[4]) {
  int base[3];
  for (int a = 0; a < 3; ++a) base[a] = std::clamp(int(std::lround(double(n[a]) * 127.0)), -127, 127);
  auto length_of = [](const int c[3]) { return std::sqrt(double(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])) / 127.0; };
  int chosen[3] = {base[0], base[1], base[2]};
  if (std::abs(length_of(base) - 1) > 0.004) {
    double best = INFINITY;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const int c[3] = {base[0] + dx, base[1] + dy, base[2] + dz};
          if (std::abs(c[0]) > 127 || std::abs(c[1]) > 127 || std::abs(c[2]) > 127) continue;
          const double length = length_of(c);
          if (!(length > 0)) continue;
          double misfit = 0;  // distance from n after normalising, plus length off 1
          for (int a = 0; a < 3; ++a) {
            const double d = c[a] / 127.0 / length - double(n[a]);
            misfit += d * d;
          }
          misfit = std::sqrt(misfit) + 4 * std::abs(length - 1);
          if (misfit < best) {
            best = misfit;
            chosen[0] = c[0], chosen[1] = c[1], chosen[2] = c[2];
          }
        }
  }
  for (int a = 0; a < 3; ++a) out[a] = int8_t(chosen[a]);
  out[3] = 0;
}

std::string vec3_json(const float v[3]) {
  return "[" + json_number(v[0]) + "," + json_number(v[1]) + "," + json_number(v[2]) + "]";
}

}  // namespace

GltfFileState::Geometry GltfFileState::write_geometry(const MeshData& data, bool stretched) {
  Geometry g;
  MeshInfo& info = g.info;
  for (const std::vector<GltfVertex>* vs : {&data.triangle_vertices, &data.line_vertices}) {
    for (const GltfVertex& v : *vs) {
      for (int a = 0; a < 3; ++a) {
        info.min[a] = info.has_box ? std::min(info.min[a], v.position[a]) : v.position[a];
        info.max[a] = info.has_box ? std::max(info.max[a], v.position[a]) : v.position[a];
      }
      info.has_box = true;
    }
  }
  // The grid: centred on the box, the smallest short scale holding it; its worst error (half
  // a step on each axis) must be within the bound.
  if (quantization_error_m > 0 && !stretched && info.has_box) {
    double half = 0;
    for (int a = 0; a < 3; ++a) {
      info.centre[a] = (double(info.min[a]) + double(info.max[a])) / 2;
      half = std::max(half, (double(info.max[a]) - double(info.min[a])) / 2);
    }
    for (const double grid : kGridScales) {
      if (grid < half * (1 + 1e-6)) continue;
      info.grid_scale = grid;
      info.quantized = std::sqrt(3.0) * 0.5 * grid / kQuantized <= quantization_error_m;
      break;
    }
    if (!info.quantized) info.centre = glm::dvec3(0.0), info.grid_scale = 1;
  }
  if (!data.triangles.empty()) g.triangles = primitive(data.triangle_vertices, data.triangles, kTriangles, info);
  if (!data.lines.empty()) g.lines = primitive(data.line_vertices, data.lines, kLines, info);
  info.triangles = uint32_t(data.triangles.size() / 3);
  info.lines = uint32_t(data.lines.size() / 2);
  return g;
}

uint64_t GltfFileState::accessor(const std::string& json) {
  if (!accessors.append(accessor_count ? "," + json : json)) note_failure(accessors);
  return accessor_count++;
}

uint64_t GltfFileState::instance_accessor(size_t offset_floats, size_t count, const char* type) {
  return accessor("{\"bufferView\":" + std::to_string(view(instance_view)) + ",\"byteOffset\":" +
                  std::to_string(offset_floats * 4) + ",\"componentType\":" + std::to_string(kFloat) +
                  ",\"count\":" + std::to_string(count) + ",\"type\":\"" + type + "\"}");
}

std::string GltfFileState::primitive(const std::vector<GltfVertex>& vs, const std::vector<uint32_t>& is, int mode,
                                     const MeshInfo& info) {
  const std::string count = std::to_string(vs.size());
  std::string attributes;
  if (info.quantized) {
    std::vector<QuantizedVertex> qs(vs.size());
    int mn[3] = {32767, 32767, 32767}, mx[3] = {-32767, -32767, -32767};
    for (size_t i = 0; i < vs.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        const double q = std::round((double(vs[i].position[a]) - info.centre[a]) / info.grid_scale * kQuantized);
        qs[i].position[a] = int16_t(std::clamp(q, -kQuantized, kQuantized));
        mn[a] = std::min(mn[a], int(qs[i].position[a]));
        mx[a] = std::max(mx[a], int(qs[i].position[a]));
      }
      qs[i].position[3] = 0;
      quantize_normal(vs[i].normal, qs[i].normal);
    }
    const std::string view_json = "{\"bufferView\":" + std::to_string(view(quantized_view)) + ",\"byteOffset\":";
    const uint64_t position = accessor(view_json + std::to_string(quantized.bytes) + ",\"componentType\":" +
                                       std::to_string(kShort) + ",\"normalized\":true,\"count\":" + count +
                                       ",\"type\":\"VEC3\",\"min\":[" + std::to_string(mn[0]) + "," +
                                       std::to_string(mn[1]) + "," + std::to_string(mn[2]) + "],\"max\":[" +
                                       std::to_string(mx[0]) + "," + std::to_string(mx[1]) + "," +
                                       std::to_string(mx[2]) + "]}");
    attributes = "{\"POSITION\":" + std::to_string(position);
    if (mode == kTriangles) {
      const uint64_t normal = accessor(view_json + std::to_string(quantized.bytes + 8) + ",\"componentType\":" +
                                       std::to_string(kByte) + ",\"normalized\":true,\"count\":" + count +
                                       ",\"type\":\"VEC3\"}");
      attributes += ",\"NORMAL\":" + std::to_string(normal);
    }
    if (!quantized.append(qs.data(), qs.size() * sizeof(QuantizedVertex))) note_failure(quantized);
  } else {
    float mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const GltfVertex& v : vs) {
      for (int a = 0; a < 3; ++a) {
        mn[a] = std::min(mn[a], v.position[a]);
        mx[a] = std::max(mx[a], v.position[a]);
      }
    }
    const std::string view_json = "{\"bufferView\":" + std::to_string(view(float_view)) + ",\"byteOffset\":";
    const uint64_t position = accessor(view_json + std::to_string(vertices.bytes) + ",\"componentType\":" +
                                       std::to_string(kFloat) + ",\"count\":" + count + ",\"type\":\"VEC3\",\"min\":" +
                                       vec3_json(mn) + ",\"max\":" + vec3_json(mx) + "}");
    attributes = "{\"POSITION\":" + std::to_string(position);
    if (mode == kTriangles) {
      const uint64_t normal = accessor(view_json + std::to_string(vertices.bytes + 12) + ",\"componentType\":" +
                                       std::to_string(kFloat) + ",\"count\":" + count + ",\"type\":\"VEC3\"}");
      attributes += ",\"NORMAL\":" + std::to_string(normal);
    }
    if (!vertices.append(vs.data(), vs.size() * sizeof(GltfVertex))) note_failure(vertices);
  }
  attributes += "}";

  // 8 bits under 255 vertices, 16 under 65535 (255 and 65535 are the primitive-restart values
  // readers reject), each mesh's indices padded to 4 bytes.
  const uint64_t index_offset = indices.bytes;
  int component;
  bool ok;
  if (vs.size() < 255) {
    component = kUnsignedByte;
    std::vector<uint8_t> narrow(is.begin(), is.end());
    narrow.resize((narrow.size() + 3) & ~size_t(3), 0);
    ok = indices.append(narrow.data(), narrow.size());
  } else if (vs.size() < 65535) {
    component = kUnsignedShort;
    std::vector<uint16_t> narrow(is.begin(), is.end());
    if (narrow.size() % 2) narrow.push_back(0);
    ok = indices.append(narrow.data(), narrow.size() * 2);
  } else {
    component = kUnsignedInt;
    ok = indices.append(is.data(), is.size() * 4);
  }
  if (!ok) note_failure(indices);
  const uint64_t index = accessor("{\"bufferView\":" + std::to_string(view(index_view)) + ",\"byteOffset\":" +
                                  std::to_string(index_offset) + ",\"componentType\":" + std::to_string(component) +
                                  ",\"count\":" + std::to_string(is.size()) + ",\"type\":\"SCALAR\"}");
  return "{\"attributes\":" + attributes + ",\"indices\":" + std::to_string(index);
}

}  // namespace plantview::detail::gltf
