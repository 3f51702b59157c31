// GltfFile::finish(): the nodes held back until the end, the document and the file, from what
// the parts on disk hold (rules in gltf_file.h, "Document" and "Files").
//
// Errors: a stage that fails returns false with `error` naming the file (and the system's
// reason, where a system call failed); nothing is then in place, and the temporary files stay
// until abandon() or the destructor removes them.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

#include "gltf_file.h"
#include "gltf_file_state.h"
#include "gltf_text.h"

namespace plantview::detail::gltf {

namespace {

using Record = GltfFileState::Record;

// Appends the file at `from` to `out`; false on an error (`error` set only when `from` cannot
// be opened: the caller names the file being written otherwise).
bool copy_file_into(std::FILE* out, const std::string& from, std::string& error) {
  std::FILE* in = std::fopen(from.c_str(), "rb");
  if (!in) {
    error = "cannot read back " + from + ": " + system_reason();
    return false;
  }
  std::vector<char> block(1 << 20);
  size_t n;
  bool ok = true;
  while (ok && (n = std::fread(block.data(), 1, block.size(), in)) > 0) ok = put(out, block.data(), n);
  ok = ok && !std::ferror(in);
  std::fclose(in);
  return ok;
}

// "cannot write <what>: <errno's reason>" unless an error is already set; always false.
bool write_failed(const std::string& what, std::string& error) {
  if (error.empty()) error = "cannot write " + what + ": " + system_reason();
  return false;
}

// Record `r`'s name and extras (JSON text) into `text`; false when it cannot be read back.
bool read_text(const GltfFileState& s, const Record& r, std::string& text) {
  text.resize(r.text_bytes);
  return ::pread(fileno(s.text.file), text.data(), r.text_bytes, off_t(r.text_offset)) == ssize_t(r.text_bytes);
}

// A write that failed earlier fails the file with its message; the records' text is read back
// below, so it must have reached the file.
bool ready_to_finish(const GltfFileState& s, std::string& error) {
  if (s.failed) {
    error = s.write_error;
    return false;
  }
  if (std::fflush(s.text.file) != 0) {
    error = "cannot write " + s.text.path + ": " + system_reason();
    return false;
  }
  return true;
}

// Which objects are drawn through EXT_mesh_gpu_instancing (GPU instancing only): per parent
// and mesh, when at least kGpuInstancingMin share it and have no children of their own. The
// group's node stands where its first member was.
struct Instancing {
  std::vector<int32_t> first_of_group;  // per record: the record standing for its group; -1: not instanced
  std::map<std::pair<int, int>, std::vector<uint32_t>> groups;  // (parent, mesh): member records in order
};

Instancing group_instances(const GltfFileState& s) {
  const size_t n = s.records.size();
  Instancing out;
  out.first_of_group.assign(n, -1);
  if (!s.gpu_instancing) return out;
  for (size_t i = 0; i < n; ++i) {
    const Record& r = s.records[i];
    if (r.is_object && r.mesh >= 0 && !r.has_children) out.groups[{r.parent, r.mesh}].push_back(uint32_t(i));
  }
  for (auto it = out.groups.begin(); it != out.groups.end();) {
    if (it->second.size() < kGpuInstancingMin) {
      it = out.groups.erase(it);
      continue;
    }
    for (uint32_t i : it->second) out.first_of_group[i] = int32_t(it->second.front());
    ++it;
  }
  return out;
}

// Node numbers (the streamed nodes first, then records in order, an instanced group as its
// first member) and children lists. A node with children carries no transform (its children's
// are in model space): an object that has both children and geometry (an RVM pipeline with
// primitives of its own) gets its geometry in a child node of its own, numbered right after it.
struct NodeTree {
  std::vector<int32_t> node_of;         // per record: its node; -1: drawn by its group's node
  std::vector<uint8_t> split_geometry;  // per record: 1 where its geometry is node node_of + 1
  // Record i's children (records' nodes and split geometry, not streamed nodes):
  // children[child_start[i], child_start[i + 1]).
  std::vector<uint32_t> child_start, children;
  std::vector<int> roots;  // the scene's nodes
};

NodeTree number_nodes(const GltfFileState& s, const Instancing& instancing) {
  const size_t n = s.records.size();
  NodeTree t;
  t.node_of.assign(n, -1);
  t.split_geometry.assign(n, 0);
  int32_t nodes = int32_t(s.streamed);
  for (size_t i = 0; i < n; ++i) {
    if (instancing.first_of_group[i] >= 0 && instancing.first_of_group[i] != int32_t(i)) continue;
    t.node_of[i] = nodes++;
    const Record& r = s.records[i];
    if (r.has_children && r.mesh >= 0) {
      t.split_geometry[i] = 1;
      nodes++;
    }
  }
  t.child_start.assign(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    if (t.node_of[i] < 0) continue;
    if (s.records[i].parent < 0) t.roots.push_back(t.node_of[i]);
    else t.child_start[size_t(s.records[i].parent) + 1] += 1;
    t.child_start[i + 1] += t.split_geometry[i];
  }
  for (size_t i = 0; i < n; ++i) t.child_start[i + 1] += t.child_start[i];
  t.children.resize(t.child_start[n]);
  std::vector<uint32_t> fill(t.child_start.begin(), t.child_start.end() - 1);
  for (size_t i = 0; i < n; ++i) {
    if (t.split_geometry[i]) t.children[fill[i]++] = uint32_t(t.node_of[i] + 1);
    if (t.node_of[i] >= 0 && s.records[i].parent >= 0)
      t.children[fill[size_t(s.records[i].parent)]++] = uint32_t(t.node_of[i]);
  }
  return t;
}

// The node of an instanced group standing at record `r` (without its closing brace) to
// `node`: its members' translations, rotations and (where any differs from 1) scales appended
// to `instance_data` (floats, each attribute's run in member order), their accessors, and
// their names and extras in the node's extras "objects".
bool instanced_node(GltfFileState& s, const Record& r, const std::vector<uint32_t>& members,
                    std::vector<float>& instance_data, std::string& text, std::string& node, std::string& error) {
  const size_t translations = instance_data.size();
  std::string objects;
  for (uint32_t m : members) {
    const Record& mr = s.records[m];
    if (!read_text(s, mr, text)) {
      error = "cannot read back " + s.text.path + ": " + system_reason();
      return false;
    }
    objects += (objects.empty() ? "{" : ",{") + text + "}";
    glm::vec3 scale = mr.scale;
    glm::dvec3 t;
    s.placement(r.mesh, mr.position_m, mr.rotation, scale, t);
    instance_data.insert(instance_data.end(), {float(t.x), float(t.y), float(t.z)});
  }
  const size_t rotations = instance_data.size();
  const float grid_scale = float(s.mesh_info[size_t(r.mesh)].grid_scale);
  bool scaled = false;
  for (uint32_t m : members) {
    const glm::quat& q = s.records[m].rotation;
    instance_data.insert(instance_data.end(), {q.x, q.y, q.z, q.w});
    scaled = scaled || s.records[m].scale * grid_scale != glm::vec3(1.0f);
  }
  const size_t scales = instance_data.size();
  if (scaled) {
    for (uint32_t m : members) {
      const glm::vec3 v = s.records[m].scale * grid_scale;
      instance_data.insert(instance_data.end(), {v.x, v.y, v.z});
    }
  }
  const uint64_t t = s.instance_accessor(translations, members.size(), "VEC3");
  const uint64_t q = s.instance_accessor(rotations, members.size(), "VEC4");
  std::string scale_attribute;
  if (scaled) scale_attribute = ",\"SCALE\":" + std::to_string(s.instance_accessor(scales, members.size(), "VEC3"));
  node += "\"name\":\"" + std::to_string(members.size()) + " instances\",\"mesh\":" + std::to_string(r.mesh) +
          ",\"extensions\":{\"EXT_mesh_gpu_instancing\":{\"attributes\":{\"TRANSLATION\":" + std::to_string(t) +
          ",\"ROTATION\":" + std::to_string(q) + scale_attribute + "}}},\"extras\":{\"objects\":[" + objects + "]}";
  return true;
}

// The records' nodes, in order, to the nodes part (after the streamed ones), the instances'
// transforms to `instance_data`; every node counted into `summary`. The records are then
// freed: nothing after this stage reads them.
bool write_held_nodes(GltfFileState& s, const Instancing& instancing, const NodeTree& tree,
                      std::vector<float>& instance_data, GltfFileSummary& summary, std::string& error) {
  std::string text, node;
  for (size_t i = 0; i < s.records.size(); ++i) {
    const Record& r = s.records[i];
    if (r.is_object) summary.objects += 1;
    s.count(r.mesh, r.position_m, r.rotation, r.scale, summary);
    if (tree.node_of[i] < 0) continue;  // drawn by its group's node
    node = "{";
    if (instancing.first_of_group[i] >= 0) {
      const std::vector<uint32_t>& members = instancing.groups.at({r.parent, r.mesh});
      if (!instanced_node(s, r, members, instance_data, text, node, error)) return false;
      summary.instanced_objects += members.size();
    } else {
      if (!read_text(s, r, text)) {
        error = "cannot read back " + s.text.path + ": " + system_reason();
        return false;
      }
      node += text;
      if (!r.has_children) {
        if (r.mesh >= 0) node += ",\"mesh\":" + std::to_string(r.mesh);
        if (r.placed) node += s.transform_json(r.position_m, r.rotation, r.scale, r.mesh);
      }
    }
    const auto streamed = s.streamed_children.find(int(i));
    if (tree.child_start[i + 1] > tree.child_start[i] || streamed != s.streamed_children.end()) {
      std::string list;
      for (uint32_t c = tree.child_start[i]; c < tree.child_start[i + 1]; ++c)
        list += "," + std::to_string(tree.children[c]);
      if (streamed != s.streamed_children.end())
        for (uint32_t c : streamed->second) list += "," + std::to_string(c);
      node += ",\"children\":[" + list.substr(1) + "]";
    }
    node += "}";
    if (tree.split_geometry[i]) {
      node += ",{\"name\":\"geometry\",\"mesh\":" + std::to_string(r.mesh) +
              s.transform_json(r.position_m, r.rotation, r.scale, r.mesh) + "}";
    }
    s.append_node(node);
  }
  summary.objects += s.streamed_summary.objects;
  summary.triangles += s.streamed_summary.triangles;
  summary.lines += s.streamed_summary.lines;
  summary.bounds.extend(s.streamed_summary.bounds);
  s.records.clear();
  s.records.shrink_to_fit();
  if (s.failed) {
    error = s.write_error;
    return false;
  }
  return true;
}

// The buffer views over [float vertices][quantized vertices][indices][instances], listed by
// view number (numbered as first used; an empty one is left out), and the extensions used.
void add_buffer_views(const GltfFileState& s, uint64_t instance_bytes, tinygltf::Model& m) {
  std::vector<std::pair<int, tinygltf::BufferView>> views;
  auto view = [&](int number, uint64_t offset, uint64_t length, size_t stride, int target) {
    if (number < 0 || length == 0) return;
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = size_t(offset);
    v.byteLength = size_t(length);
    v.byteStride = stride;
    v.target = target;
    views.emplace_back(number, v);
  };
  view(s.float_view, 0, s.vertices.bytes, sizeof(GltfVertex), TINYGLTF_TARGET_ARRAY_BUFFER);
  view(s.quantized_view, s.vertices.bytes, s.quantized.bytes, sizeof(QuantizedVertex), TINYGLTF_TARGET_ARRAY_BUFFER);
  view(s.index_view, s.vertices.bytes + s.quantized.bytes, s.indices.bytes, 0, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  view(s.instance_view, s.vertices.bytes + s.quantized.bytes + s.indices.bytes, instance_bytes, 0, 0);
  std::sort(views.begin(), views.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [number, v] : views) m.bufferViews.push_back(std::move(v));
  if (s.quantized.bytes > 0) {
    // Readers without it cannot read the int16 and int8 attributes.
    m.extensionsUsed.push_back("KHR_mesh_quantization");
    m.extensionsRequired.push_back("KHR_mesh_quantization");
  }
  if (instance_bytes > 0) {
    m.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
    // The extension defines no fallback: a reader without it would draw one copy.
    m.extensionsRequired.push_back("EXT_mesh_gpu_instancing");
  }
}

// The document's small parts by tinygltf (materials, made as meshes came; buffer views; the
// scene of `roots`; the asset with the origin), as JSON text without its closing brace.
bool document_head(GltfFileState& s, std::vector<int> roots, uint64_t instance_bytes, std::string& head,
                   std::string& error) {
  tinygltf::Model& m = s.model;
  add_buffer_views(s, instance_bytes, m);
  tinygltf::Scene scene;
  scene.nodes = std::move(roots);
  m.scenes.push_back(std::move(scene));
  m.defaultScene = 0;
  m.asset.version = "2.0";
  m.asset.generator = "plantview";
  m.asset.extras = tinygltf::Value(tinygltf::Value::Object{
      {"origin_m", tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(s.origin_m.x), tinygltf::Value(s.origin_m.y),
                                                           tinygltf::Value(s.origin_m.z)})}});
  {
    std::ostringstream out;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&m, out, false, false)) {
      error = "cannot serialise the glTF document of " + s.path;
      return false;
    }
    head = std::move(out).str();
  }
  while (!head.empty() && head.back() != '}') head.pop_back();
  if (head.size() < 2) {
    error = "cannot serialise the glTF document of " + s.path;
    return false;
  }
  head.pop_back();  // the arrays follow
  return true;
}

// The JSON document as pieces, in order: text, or a part's whole content.
struct Piece {
  std::string text;
  const Part* part = nullptr;  // the state's, valid until the parts are removed
};
struct Document {
  std::vector<Piece> pieces;
  uint64_t json_bytes = 0;
};

// `head`, then the accessors, meshes and nodes from their parts (an empty array left out),
// then the buffer (bin_bytes long; a .gltf's by its .bin's name).
Document splice_arrays(std::string head, const GltfFileState& s, uint64_t bin_bytes) {
  Document document;
  std::vector<Piece>& pieces = document.pieces;
  pieces.push_back({std::move(head)});
  auto array = [&](const char* name, const Part& part) {
    if (part.bytes == 0) return;
    pieces.push_back({",\"" + std::string(name) + "\":["});
    pieces.push_back({"", &part});
    pieces.push_back({"]"});
  };
  array("accessors", s.accessors);
  array("meshes", s.meshes_text);
  array("nodes", s.nodes);
  std::string tail;
  if (bin_bytes > 0) {
    tail = ",\"buffers\":[{\"byteLength\":" + std::to_string(bin_bytes);
    if (!s.binary) tail += ",\"uri\":" + json_string(utf8_text(s.bin_name));
    tail += "}]";
  }
  pieces.push_back({tail + "}"});
  for (const Piece& p : pieces) document.json_bytes += p.part ? p.part->bytes : p.text.size();
  return document;
}

// Every part's buffered writes to its file, so that it can be copied from there.
bool flush_parts(const GltfFileState& s, std::string& error) {
  for (const Part* p : s.parts) {
    if (p->file && std::fflush(p->file) != 0) {
      error = "cannot write " + p->path + ": " + system_reason();
      return false;
    }
  }
  return true;
}

bool put_document(std::FILE* out, const Document& document, std::string& error) {
  for (const Piece& p : document.pieces)
    if (!(p.part ? copy_file_into(out, p.part->path, error) : put(out, p.text))) return false;
  return true;
}

// The binary buffer: [float vertices][quantized vertices][indices][instance transforms].
bool put_binary(std::FILE* out, const GltfFileState& s, const std::vector<float>& instance_data, std::string& error) {
  return copy_file_into(out, s.vertices.path, error) && copy_file_into(out, s.quantized.path, error) &&
         copy_file_into(out, s.indices.path, error) && put(out, instance_data.data(), instance_data.size() * 4);
}

// A .glb at temp_out: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros)
// where there is binary data. Fails beyond 4 GiB, the most a .glb can say.
bool write_glb(const GltfFileState& s, const Document& document, const std::vector<float>& instance_data,
               uint64_t bin_bytes, std::string& error) {
  std::FILE* out = std::fopen(s.temp_out.c_str(), "wb");
  if (!out) return write_failed(s.path, error);
  const uint64_t json_padded = (document.json_bytes + 3) & ~uint64_t(3);
  const uint64_t bin_padded = (bin_bytes + 3) & ~uint64_t(3);
  const uint64_t total = 12 + 8 + json_padded + (bin_bytes ? 8 + bin_padded : 0);
  if (total > UINT32_MAX) {
    std::fclose(out);
    error = "cannot write " + s.path + ": " + std::to_string(total) +
            " bytes, more than a .glb can hold (4 GiB); select less, raise the tolerance or write .gltf";
    return false;
  }
  const uint32_t header[5] = {0x46546C67u, 2u, uint32_t(total), uint32_t(json_padded), 0x4E4F534Au};
  bool ok = put(out, header, sizeof header) && put_document(out, document, error) &&
            put(out, "   ", size_t(json_padded - document.json_bytes));
  if (bin_bytes) {
    const uint32_t chunk[2] = {uint32_t(bin_padded), 0x004E4942u};
    const char zeros[4] = {};
    ok = ok && put(out, chunk, sizeof chunk) && put_binary(out, s, instance_data, error) &&
         put(out, zeros, size_t(bin_padded - bin_bytes));
  }
  ok = std::fclose(out) == 0 && ok;
  return ok || write_failed(s.path, error);
}

// A .gltf at temp_out (the document and a newline) and, where there is binary data, its .bin
// at temp_bin.
bool write_gltf(const GltfFileState& s, const Document& document, const std::vector<float>& instance_data,
                uint64_t bin_bytes, std::string& error) {
  std::FILE* out = std::fopen(s.temp_out.c_str(), "wb");
  if (!out) return write_failed(s.path, error);
  bool ok = put_document(out, document, error) && put(out, "\n", 1);
  if (ok && bin_bytes) {
    std::FILE* bin = std::fopen(s.temp_bin.c_str(), "wb");
    if (!bin) {
      std::fclose(out);
      return write_failed((std::filesystem::path(s.path).parent_path() / s.bin_name).string(), error);
    }
    ok = put_binary(bin, s, instance_data, error);
    ok = std::fclose(bin) == 0 && ok;
  }
  ok = std::fclose(out) == 0 && ok;
  return ok || write_failed(s.path, error);
}

// The .bin before the .gltf that refers to it, so that a reader never finds the file without
// its data.
bool rename_into_place(const GltfFileState& s, uint64_t bin_bytes, std::string& error) {
  std::error_code ec;
  const std::filesystem::path final_path(s.path);
  if (!s.binary && bin_bytes) {
    std::filesystem::rename(s.temp_bin, final_path.parent_path() / s.bin_name, ec);
    if (ec) {
      error = "cannot write " + (final_path.parent_path() / s.bin_name).string() + ": " + ec.message();
      return false;
    }
  }
  std::filesystem::rename(s.temp_out, final_path, ec);
  if (ec) {
    error = "cannot write " + s.path + ": " + ec.message();
    return false;
  }
  return true;
}

// Frees all but the finished files' names: a split keeps each finished file (to remove it if a
// later one fails) while it writes the next.
void release_finished(GltfFileState& s) {
  for (Part* p : s.parts) p->remove();
  s.finished = true;
  s.model = tinygltf::Model();
  s.meshes = {};
  s.mesh_info = {};
  s.geometries = {};
  s.streamed_children = {};
  s.sites = {};
  s.zones = {};
  s.pipelines = {};
}

}  // namespace

bool GltfFile::finish(GltfFileSummary& summary, std::string& error) {
  GltfFileState& s = *state_;
  summary.path = s.path;
  summary.meshes = s.mesh_info.size();
  // Nothing more is written after a failed write: its message is the file's error.
  if (!ready_to_finish(s, error)) return false;
  // Instanced nodes are chosen only now, when every parent's members are known.
  const Instancing instancing = group_instances(s);
  // Group nodes learnt their children as objects came: now each node gets its number.
  NodeTree tree = number_nodes(s, instancing);
  // The nodes held back (groups; with GPU instancing, every object's) follow the streamed ones.
  std::vector<float> instance_data;
  if (!write_held_nodes(s, instancing, tree, instance_data, summary, error)) return false;
  // tinygltf writes the small parts; the arrays that grow with the plant are spliced in from disk.
  const uint64_t instance_bytes = instance_data.size() * 4;
  const uint64_t bin_bytes = s.vertices.bytes + s.quantized.bytes + s.indices.bytes + instance_bytes;
  std::string head;
  if (!document_head(s, std::move(tree.roots), instance_bytes, head, error)) return false;
  const Document document = splice_arrays(std::move(head), s, bin_bytes);
  // The parts are copied from their files: what is buffered must reach them first.
  if (!flush_parts(s, error)) return false;
  // Under temporary names, so that a failure leaves nothing half-written at the destination.
  const bool written = s.binary ? write_glb(s, document, instance_data, bin_bytes, error)
                                : write_gltf(s, document, instance_data, bin_bytes, error);
  if (!written) return false;
  // The .bin before the .gltf that refers to it: a reader never finds the file without its data.
  if (!rename_into_place(s, bin_bytes, error)) return false;
  // A split keeps its finished files while it writes the next: only their names stay.
  release_finished(s);
  std::error_code ec;
  summary.bytes = std::filesystem::file_size(s.path, ec);
  if (!s.binary) summary.bytes += bin_bytes;
  return true;
}

}  // namespace plantview::detail::gltf
