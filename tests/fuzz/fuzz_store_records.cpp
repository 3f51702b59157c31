// Fuzz harness for the store's decoders of stored bytes (storage/src: record.h, chunks.h,
// tables.h, spatial.h). A store file is input like any other: a damaged or hostile one must give
// an error, never a crash, a read out of bounds or an allocation beyond what its size allows.
//
// The first byte picks the decoder (and its parameters, where it has some); the rest is the bytes
// it decodes. For every decoder:
//   - a failure comes with a message;
//   - whatever is accepted is encoded again by the store's own encoder, and that decodes to the
//     same value, bit for bit (and, where the layout has one spelling per value, the encoding is
//     the input itself).
// Decoders that read the same layout two ways (decode_key_slots and KeySlotReader) must agree,
// and an expanded spatial block must bound what it holds.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "chunks.h"
#include "record.h"
#include "spatial.h"
#include "support/object_bits.h"
#include "tables.h"

namespace {

using namespace plantview;
using namespace plantview::detail;

void check(bool condition) {
  if (!condition) __builtin_trap();
}

bool same_bytes(std::span<const uint8_t> a, std::span<const uint8_t> b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size()) == 0);
}

// record.h's one exception to bit-exact round trips: the compact placement code of an axis-aligned
// linear part keeps no sign of its zero entries (a -0.0 there comes back as +0.0), so zeros of
// linear parts are compared without their sign; every other bit is checked.
Object without_signed_zeros(Object o) {
  for (Primitive& p : o.primitives) {
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) {
        if (p.placement.linear[c][r] == 0.0f) p.placement.linear[c][r] = 0.0f;
      }
    }
  }
  return o;
}

void same_objects(const Object& a, const Object& b) {
  check(test::object_difference(without_signed_zeros(a), without_signed_zeros(b)).empty());
  // object_difference leaves triangles out (derived data elsewhere); a record stores them.
  for (size_t i = 0; i < a.primitives.size(); ++i) {
    const auto* fa = std::get_if<FacetGroup>(&a.primitives[i].shape);
    const auto* fb = std::get_if<FacetGroup>(&b.primitives[i].shape);
    check((fa == nullptr) == (fb == nullptr));
    if (fa != nullptr) check(fa->triangles == fb->triangles);
  }
}

void object_record(const uint8_t* data, size_t size) {
  Object object;
  std::string error;
  // The key alone (ReadView::object_key): refused with a message, or the object's own.
  uint64_t id = 0, pipeline_id = 0;
  const bool key = decode_object_key(data, size, id, pipeline_id, error);
  check(key || !error.empty());
  error.clear();
  if (!decode_object(data, size, object, error)) {
    check(!error.empty());
    return;
  }
  check(key && id == object.id && pipeline_id == object.pipeline_id);
  std::vector<uint8_t> encoded;
  encode_object(object, encoded);
  Object again;
  check(decode_object(encoded.data(), encoded.size(), again, error));
  same_objects(object, again);
  std::vector<uint8_t> reencoded;
  encode_object(again, reencoded);
  check(reencoded == encoded);
}

void attribute_record(const uint8_t* data, size_t size) {
  std::vector<Attribute> attributes;
  std::string error;
  if (!decode_attributes(data, size, attributes, error)) {
    check(!error.empty());
    return;
  }
  std::vector<uint8_t> encoded;
  encode_attributes(attributes, encoded);
  check(same_bytes(encoded, {data, size}));
}

// A chunk value (chunks.h): its slot count and frame, joined again bit for bit.
void chunk_value(const uint8_t* data, size_t size) {
  uint32_t slot_count = 0;
  std::span<const uint8_t> frame;
  std::string error;
  if (!split_chunk_value(data, size, slot_count, frame, error)) {
    check(!error.empty());
    return;
  }
  check(slot_count > 0 && !frame.empty());
  check(frame.data() >= data && frame.data() + frame.size() <= data + size);
  std::vector<uint8_t> joined;
  join_chunk_value(slot_count, frame, joined);
  check(same_bytes(joined, {data, size}));
}

// A chunk's layout of `slot_count` slots: checked, its records laid out again bit for bit.
void chunk(uint32_t slot_count, const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);
  std::vector<uint32_t> ends;
  std::string error;
  if (!check_chunk(bytes, slot_count, ends, error)) {
    check(!error.empty());
    return;
  }
  std::vector<std::vector<uint8_t>> records;
  for (uint32_t i = 0; i < slot_count; ++i) {
    const std::span<const uint8_t> record = chunk_record(bytes, ends, i);
    check(record.empty() ||
          (record.data() >= bytes.data() && record.data() + record.size() <= bytes.data() + size));
    records.emplace_back(record.begin(), record.end());
  }
  std::vector<uint8_t> packed;
  pack_chunk(records, packed);
  check(packed == bytes);
}

void frame(const uint8_t* data, size_t size) {
  static const ZstdDCtx dctx{ZSTD_createDCtx()};
  static const ZstdCCtx cctx = make_compressor();
  std::vector<uint8_t> inflated;
  std::string error;
  if (!inflate_frame(dctx.get(), {data, size}, inflated, error)) {
    check(!error.empty());
    return;
  }
  check(ZSTD_getFrameContentSize(data, size) == inflated.size());
  std::vector<uint8_t> compressed, again;
  check(compress_frame(cctx.get(), inflated, compressed, error));
  check(inflate_frame(dctx.get(), compressed, again, error));
  check(again == inflated);
}

void key_slot_table(const uint8_t* data, size_t size) {
  std::vector<KeySlot> table;
  std::string error;
  const bool ok = decode_key_slots(data, size, table, error);

  // The reader alone, pair by pair, must come to the same verdict and pairs.
  KeySlotReader reader;
  std::string reader_error;
  bool reader_ok = reader.open(data, size, reader_error);
  std::vector<KeySlot> pairs;
  for (uint64_t i = 0; reader_ok && i < reader.size(); ++i) {
    KeySlot pair;
    reader_ok = reader.next(pair, reader_error);
    if (reader_ok) pairs.push_back(pair);
  }
  reader_ok = reader_ok && reader.finish(reader_error);
  check(ok == reader_ok && error == reader_error);
  if (!ok) {
    check(!error.empty());
    return;
  }
  check(pairs.size() == table.size());
  for (size_t i = 0; i < table.size(); ++i) {
    check(pairs[i].key == table[i].key && pairs[i].slot == table[i].slot);
    if (i > 0) check(table[i - 1] < table[i]);
  }
  std::vector<uint8_t> encoded;
  encode_key_slots(table, encoded);
  std::vector<KeySlot> again;
  check(decode_key_slots(encoded.data(), encoded.size(), again, error));
  check(again.size() == table.size());
  for (size_t i = 0; i < table.size(); ++i) {
    check(again[i].key == table[i].key && again[i].slot == table[i].slot);
  }
}

void slot_runs(const uint8_t* data, size_t size) {
  // The limit (the store's next slot) comes first, as four bytes.
  if (size < 4) return;
  uint32_t limit;
  std::memcpy(&limit, data, 4);
  limit %= 1u << 20;  // bounds the list's memory as a store of a million objects would
  std::vector<uint32_t> slots;
  std::string error;
  if (!decode_slot_runs(data + 4, size - 4, limit, slots, error)) {
    check(!error.empty());
    return;
  }
  for (size_t i = 0; i < slots.size(); ++i) {
    check(slots[i] < limit);
    if (i > 0) check(slots[i - 1] < slots[i]);
  }
  std::vector<uint8_t> encoded;
  encode_slot_runs(slots, encoded);
  std::vector<uint32_t> again;
  check(decode_slot_runs(encoded.data(), encoded.size(), limit, again, error));
  check(again == slots);
}

// A spatial block: decoded, written again bit for bit, and expanded into a hierarchy that bounds
// what it holds.
void spatial_block(const uint8_t* data, size_t size) {
  std::vector<BlockEntry> entries;
  std::string error;
  if (!decode_block(data, size, entries, error)) {
    check(!error.empty());
    return;
  }
  std::vector<uint8_t> encoded;
  encode_block(entries.data(), uint32_t(entries.size()), encoded);
  check(encoded.size() == size && std::memcmp(encoded.data(), data, size) == 0);
  SpatialBlock expanded;
  expand_block(entries, expanded);
  check(expanded.entries.size() == entries.size());
  for (const SpatialNode& node : expanded.nodes) {
    if (node.count == 0) {
      for (uint32_t c = node.first; c < node.first + 2; ++c) {
        check(c < expanded.nodes.size());
        for (int a = 0; a < 3; ++a) {
          check(node.min[a] <= expanded.nodes[c].min[a] && expanded.nodes[c].max[a] <= node.max[a]);
        }
      }
      continue;
    }
    check(uint64_t(node.first) + node.count <= entries.size());
    for (uint32_t k = node.first; k < node.first + node.count; ++k) {
      check(expanded.entries[k].slot == entries[k].grid.slot);
      float lo[3], hi[3];
      entry_bounds(node, expanded.entries[k], lo, hi);
      for (int a = 0; a < 3; ++a) {
        check(double(lo[a]) <= double(entries[k].grid.min[a]) * kSpatialCellM);
        check(double(hi[a]) >= double(entries[k].grid.max[a]) * kSpatialCellM);
      }
    }
  }
}

// The spatial top: decoded (proxies checked against their nodes by the decoder); whatever it
// accepts has proxies inside their nodes, one box at least per node.
void spatial_top(const uint8_t* data, size_t size) {
  DecodedTop top;
  std::string error;
  if (!decode_top(data, size, top, error)) {
    check(!error.empty());
    return;
  }
  check(top.proxy_first.size() == top.nodes.size() + 1 || top.nodes.empty());
  for (size_t i = 0; i < top.nodes.size(); ++i) {
    check(top.proxy_first[i] < top.proxy_first[i + 1]);
    for (uint32_t p = top.proxy_first[i]; p < top.proxy_first[i + 1]; ++p) {
      for (int a = 0; a < 3; ++a) {
        check(top.nodes[i].min[a] <= top.proxies[p].min[a]);
        check(top.proxies[p].max[a] <= top.nodes[i].max[a]);
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t* bytes = data + 1;
  const size_t n = size - 1;
  switch (data[0] % 11) {
    case 0: object_record(bytes, n); break;
    case 1: attribute_record(bytes, n); break;
    case 2: chunk_value(bytes, n); break;
    case 3: chunk(1, bytes, n); break;
    case 4: chunk(64, bytes, n); break;
    case 5: chunk(256, bytes, n); break;
    case 6: frame(bytes, n); break;
    case 7: key_slot_table(bytes, n); break;
    case 8: slot_runs(bytes, n); break;
    case 9: spatial_block(bytes, n); break;
    case 10: spatial_top(bytes, n); break;
  }
  return 0;
}
