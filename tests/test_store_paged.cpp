// The store's paged spatial index and bounded-memory imports (format 3): blocks and the top,
// far-field proxies, the block cache's bound, metadata read without the index, imports whose
// runs spill to files and are killed part-way.
#include <gtest/gtest.h>
#include <lmdb.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "plantview/store.h"
// Internal knobs (run bounds, commit stages, cache bound) and encodings.
#include "chunks.h"
#include "columns.h"
#include "import_runs.h"
#include "lmdb_guard.h"
#include "spatial.h"
#include "support/temp_dir.h"

namespace plantview {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

// A box of `size_m` at `at` with a colour of its own.
Object box(const std::string& source, int i, glm::dvec3 at, float size_m = 1.0f) {
  Object o;
  o.name = "/" + source + "-" + std::to_string(i);
  o.source = source;
  o.id = object_id(source, o.name);
  o.origin_m = at;
  o.colour = {uint8_t(i), uint8_t(i >> 8), uint8_t(i >> 16), 255};
  o.primitives.push_back({{}, Box{size_m, size_m * 0.5f, size_m * 0.25f}});
  return o;
}

// `n` boxes scattered over a 2 km site, of sizes from 0.1 to 10 m.
std::vector<Object> scattered(const std::string& source, int n, unsigned seed = 5) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> at(-1000, 1000), size(0.1, 10);
  std::vector<Object> out;
  out.reserve(size_t(n));
  for (int i = 0; i < n; ++i) {
    out.push_back(box(source, i, {at(rng), at(rng), at(rng) / 20}, float(size(rng))));
  }
  return out;
}

std::unique_ptr<Store> open_store(const std::string& dir, Store::Mode mode = Store::Mode::read_write) {
  std::string error;
  auto store = Store::open(dir, mode, error);
  EXPECT_TRUE(store) << error;
  return store;
}

void import_objects(Store& store, const std::vector<Object>& objects, const std::string& source) {
  std::string error;
  auto import = store.begin_import(error);
  ASSERT_TRUE(import) << error;
  ASSERT_TRUE(import->remove_source(source, error)) << error;
  for (const Object& o : objects) ASSERT_TRUE(import->put(o, error)) << error;
  ASSERT_TRUE(import->commit(error)) << error;
}

// Every object by id (for_each_object).
std::map<uint64_t, Object> objects_by_id(const Store& store) {
  std::string error;
  auto view = store.read(error);
  EXPECT_TRUE(view) << error;
  std::map<uint64_t, Object> out;
  if (!view) return out;
  EXPECT_TRUE(view->for_each_object(
      [&](uint32_t, Object&& o) {
        out.emplace(o.id, std::move(o));
        return true;
      },
      true, error))
      << error;
  return out;
}

std::vector<fs::path> run_files(const std::string& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().extension() == ".run") out.push_back(e.path());
  }
  return out;
}

// Sets the import run bound for one test (and back).
struct SmallRuns {
  explicit SmallRuns(size_t bytes) { detail::set_import_run_bytes(bytes); }
  ~SmallRuns() { detail::set_import_run_bytes(size_t(64) << 20); }
};

// The blocks of a store, each entry with its leaf, by block.
struct WalkedBlock {
  std::shared_ptr<const SpatialBlock> block;
  std::vector<std::array<float, 6>> boxes;  // entry_bounds of each entry, by entry index
};
std::vector<WalkedBlock> all_blocks(const ReadView& view) {
  std::vector<WalkedBlock> out;
  std::string error;
  for (uint32_t b = 0; b < view.spatial_block_count(); ++b) {
    WalkedBlock w;
    w.block = view.spatial_block(b, error);
    EXPECT_TRUE(w.block) << error;
    if (!w.block) return {};
    w.boxes.resize(w.block->entries.size());
    for (const SpatialNode& n : w.block->nodes) {
      for (uint32_t k = n.first; n.count > 0 && k < n.first + n.count; ++k) {
        entry_bounds(n, w.block->entries[k], w.boxes[k].data(), w.boxes[k].data() + 3);
      }
    }
    out.push_back(std::move(w));
  }
  return out;
}

// The blocks beneath top node `t`.
void blocks_beneath(std::span<const SpatialNode> top, uint32_t t, std::vector<uint32_t>& out) {
  if (top[t].count > 0) {
    out.push_back(top[t].first);
    return;
  }
  blocks_beneath(top, top[t].first, out);
  blocks_beneath(top, top[t].first + 1, out);
}

TEST(StorePaged, EveryEntryIsInExactlyOneBlockOfAtMost2048UnderItsTopLeaf) {
  TempDir dir;
  auto store = open_store(dir.str());
  const auto objects = scattered("s", 9000);
  import_objects(*store, objects, "s");
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->spatial_objects(), 9000u);
  EXPECT_EQ(view->spatial_block_count(), 5u);  // 4 x 2048 + 808
  const auto top = view->spatial_top();
  const auto top_objects = view->spatial_top_objects();
  ASSERT_EQ(top_objects.size(), top.size());
  EXPECT_EQ(top_objects[0], 9000u);
  const auto blocks = all_blocks(*view);
  std::set<uint32_t> slots;
  std::vector<int> leaf_of_block(blocks.size(), -1);
  for (uint32_t t = 0; t < top.size(); ++t) {
    if (top[t].count == 0) {
      EXPECT_EQ(top_objects[t], top_objects[top[t].first] + top_objects[top[t].first + 1]);
      continue;
    }
    ASSERT_LT(top[t].first, blocks.size());
    EXPECT_EQ(leaf_of_block[top[t].first], -1) << "block " << top[t].first << " under two leaves";
    leaf_of_block[top[t].first] = int(t);
    const SpatialBlock& b = *blocks[top[t].first].block;
    EXPECT_EQ(top_objects[t], b.entries.size());
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(b.nodes[0].min[a], top[t].min[a]);
      EXPECT_EQ(b.nodes[0].max[a], top[t].max[a]);
    }
  }
  for (const WalkedBlock& w : blocks) {
    EXPECT_LE(w.block->entries.size(), kSpatialBlockObjects);
    for (const SpatialEntry& e : w.block->entries) EXPECT_TRUE(slots.insert(e.slot).second) << e.slot;
  }
  EXPECT_EQ(slots.size(), 9000u);
  for (int leaf : leaf_of_block) EXPECT_GE(leaf, 0);
  // for_each_spatial_entry visits the same entries in block order.
  size_t visited = 0;
  ASSERT_TRUE(view->for_each_spatial_entry(
      [&](const SpatialNode&, const SpatialEntry& e) {
        ++visited;
        return slots.count(e.slot) == 1;
      },
      error))
      << error;
  EXPECT_EQ(visited, 9000u);
}

// The proxy of every top node covers exactly what it replaces: the union of its boxes is the
// node's bounds, every object beneath lies in one of its boxes, and each box's colour is that of
// an object inside it.
TEST(StorePaged, EveryTopNodesProxyCoversExactlyTheBoundsOfWhatItReplaces) {
  TempDir dir;
  auto store = open_store(dir.str());
  const auto objects = scattered("s", 20000, 9);
  import_objects(*store, objects, "s");
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  const auto top = view->spatial_top();
  ASSERT_EQ(view->spatial_block_count(), 10u);
  const auto blocks = all_blocks(*view);
  std::map<uint32_t, Colour> colour_of;
  for (const Object& o : objects) colour_of[*view->slot_of(o.id)] = o.colour;
  for (uint32_t t = 0; t < top.size(); ++t) {
    const auto proxy = view->spatial_proxy(t);
    ASSERT_GE(proxy.size(), 1u) << t;
    ASSERT_LE(proxy.size(), kProxyBoxes) << t;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const ProxyBox& p : proxy) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p.min[a]);
        hi[a] = std::max(hi[a], p.max[a]);
      }
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(lo[a], top[t].min[a]) << "node " << t;
      EXPECT_EQ(hi[a], top[t].max[a]) << "node " << t;
    }
    std::vector<uint32_t> beneath;
    blocks_beneath(top, t, beneath);
    std::vector<bool> colour_found(proxy.size(), false);
    for (uint32_t b : beneath) {
      const WalkedBlock& w = blocks[b];
      for (size_t k = 0; k < w.boxes.size(); ++k) {
        bool inside_one = false;
        for (size_t p = 0; p < proxy.size(); ++p) {
          bool inside = true;
          for (int a = 0; a < 3; ++a) {
            inside = inside && proxy[p].min[a] <= w.boxes[k][a] && w.boxes[k][3 + a] <= proxy[p].max[a];
          }
          inside_one = inside_one || inside;
          if (inside && colour_of[w.block->entries[k].slot] == proxy[p].colour) colour_found[p] = true;
        }
        ASSERT_TRUE(inside_one) << "slot " << w.block->entries[k].slot << " of node " << t;
      }
    }
    for (size_t p = 0; p < proxy.size(); ++p) EXPECT_TRUE(colour_found[p]) << t << " box " << p;
  }
  // The root of 10 blocks is 4 levels high: its proxy has the full 8 boxes.
  EXPECT_EQ(view->spatial_proxy(0).size(), kProxyBoxes);
}

// The largest object's colour wins its box: one big red box among small grey ones.
TEST(StorePaged, AProxyBoxTakesTheColourOfTheLargestObjectInIt) {
  TempDir dir;
  auto store = open_store(dir.str());
  std::vector<Object> objects;
  for (int i = 0; i < 100; ++i) {
    Object o = box("s", i, {i * 2.0, 0, 0}, 0.5f);
    o.colour = {100, 100, 100, 255};
    objects.push_back(o);
  }
  objects[37].primitives[0] = {{}, Box{1.9f, 3, 3}};
  objects[37].colour = {255, 0, 0, 255};
  import_objects(*store, objects, "s");
  std::string error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  const glm::dvec3 origin = view->spatial_origin();
  int red = 0;
  for (const ProxyBox& p : view->spatial_proxy(0)) {
    const bool holds_big = origin.x + p.min[0] <= 37 * 2.0 - 0.9 && origin.x + p.max[0] >= 37 * 2.0 + 0.9;
    EXPECT_EQ(p.colour == Colour({255, 0, 0, 255}), holds_big);
    red += holds_big;
  }
  EXPECT_EQ(red, 1);
}

TEST(StorePaged, TheBlockCacheStaysUnderItsBoundAfterWalkingEveryBlock) {
  TempDir dir;
  constexpr size_t kBound = size_t(1) << 20;
  detail::set_spatial_cache_bytes(kBound);
  {
    auto store = open_store(dir.str());
    import_objects(*store, scattered("s", 61440), "s");  // 30 blocks, about 60 KB each decoded
    std::string error;
    auto view = store->read(error);
    ASSERT_TRUE(view) << error;
    ASSERT_EQ(view->spatial_block_count(), 30u);
    size_t most = 0;
    for (uint32_t b = 0; b < view->spatial_block_count(); ++b) {
      ASSERT_TRUE(view->spatial_block(b, error)) << error;
      most = std::max(most, view->spatial_cache_bytes());
      EXPECT_LE(view->spatial_cache_bytes(), kBound) << "after block " << b;
    }
    EXPECT_GT(most, kBound / 2);  // it does cache
    // Held blocks stay whatever the bound; once let go, the next block brings it back under.
    std::vector<std::shared_ptr<const SpatialBlock>> held;
    for (uint32_t b = 0; b < view->spatial_block_count(); ++b) held.push_back(view->spatial_block(b, error));
    EXPECT_GT(view->spatial_cache_bytes(), kBound);
    const auto first = held[0];
    EXPECT_EQ(view->spatial_block(0, error), first);  // held: the same block, not decoded again
    held.clear();
    ASSERT_TRUE(view->spatial_block(0, error));
    ASSERT_TRUE(view->spatial_block(29, error));
    EXPECT_LE(view->spatial_cache_bytes(), kBound);
  }
  detail::set_spatial_cache_bytes(kSpatialCacheBytes);
}

// Overwrites <database>/<key> with `bytes`, as a damaged disk might (no Store open on `dir`).
void put_raw(const std::string& dir, const char* database, MDB_val key, std::span<const uint8_t> bytes) {
  MDB_env* env = nullptr;
  ASSERT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  ASSERT_EQ(mdb_env_open(env, dir.c_str(), 0, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  MDB_dbi dbi;
  ASSERT_EQ(mdb_txn_begin(env, nullptr, 0, &txn), MDB_SUCCESS);
  ASSERT_EQ(mdb_dbi_open(txn, database, 0, &dbi), MDB_SUCCESS);
  MDB_val v{bytes.size(), const_cast<uint8_t*>(bytes.data())};
  ASSERT_EQ(mdb_put(txn, dbi, &key, &v, 0), MDB_SUCCESS);
  ASSERT_EQ(mdb_txn_commit(txn), MDB_SUCCESS);
  mdb_env_close(env);
}

std::vector<uint8_t> zstd_frame(const std::vector<uint8_t>& raw) {
  std::vector<uint8_t> frame;
  std::string error;
  EXPECT_TRUE(detail::compress_frame(detail::make_compressor().get(), raw, frame, error)) << error;
  return frame;
}

// read() and info() read metadata only: with a block damaged they still answer, and so do the
// other blocks; the damaged block fails with a message naming the store and the block. With the
// top damaged, read(), info() and objects still answer; the spatial calls that can fail name it.
// The first slot of every object chunk (objects/ keys), read with the store closed.
std::vector<uint32_t> object_chunk_firsts(const std::string& dir) {
  std::vector<uint32_t> firsts;
  MDB_env* env = nullptr;
  EXPECT_EQ(mdb_env_create(&env), MDB_SUCCESS);
  mdb_env_set_maxdbs(env, 12);
  EXPECT_EQ(mdb_env_open(env, dir.c_str(), MDB_RDONLY, 0644), MDB_SUCCESS);
  MDB_txn* txn = nullptr;
  MDB_dbi dbi;
  EXPECT_EQ(mdb_txn_begin(env, nullptr, MDB_RDONLY, &txn), MDB_SUCCESS);
  EXPECT_EQ(mdb_dbi_open(txn, "objects", 0, &dbi), MDB_SUCCESS);
  MDB_cursor* cursor = nullptr;
  EXPECT_EQ(mdb_cursor_open(txn, dbi, &cursor), MDB_SUCCESS);
  MDB_val k, v;
  for (int rc = mdb_cursor_get(cursor, &k, &v, MDB_FIRST); rc == MDB_SUCCESS;
       rc = mdb_cursor_get(cursor, &k, &v, MDB_NEXT)) {
    firsts.push_back(detail::read_be32(k.mv_data));
  }
  mdb_cursor_close(cursor);
  mdb_txn_abort(txn);
  mdb_env_close(env);
  return firsts;
}

// Which of `firsts` (ascending) holds `slot`.
size_t chunk_index(const std::vector<uint32_t>& firsts, uint32_t slot) {
  return size_t(std::upper_bound(firsts.begin(), firsts.end(), slot) - firsts.begin()) - 1;
}

TEST(StorePaged, ViewsOfOneStateDecompressAChunkOnceWithinTheSharedBound) {
  TempDir dir;
  constexpr uint32_t kObjects = 64 * 64;
  auto store = open_store(dir.str());
  import_objects(*store, scattered("s", kObjects), "s");
  store.reset();
  const std::vector<uint32_t> chunks = object_chunk_firsts(dir.str());
  ASSERT_GT(chunks.size(), 12u);
  store = open_store(dir.str());
  std::string error;
  auto first = store->read(error);
  ASSERT_TRUE(first) << error;
  std::vector<Object> read(kObjects);
  for (uint32_t slot = 0; slot < read.size(); ++slot)
    ASSERT_TRUE(first->object(slot, read[slot], false, error)) << error;
  EXPECT_EQ(first->chunks_decompressed(), chunks.size());
  // Another view of the state, a sibling on another thread or a later read, finds every chunk
  // decompressed, and the same objects in it.
  auto sibling = first->sibling(error);
  ASSERT_TRUE(sibling) << error;
  auto later = store->read(error);
  ASSERT_TRUE(later) << error;
  std::thread reader([&] {
    Object o;
    for (uint32_t slot = 0; slot < read.size(); slot += 7) {
      ASSERT_TRUE(sibling->object(slot, o, false, error)) << error;
      EXPECT_EQ(o.id, read[slot].id);
    }
  });
  reader.join();
  Object o;
  for (uint32_t slot = 3; slot < read.size(); slot += 64) {
    ASSERT_TRUE(later->object(slot, o, false, error)) << error;
    EXPECT_EQ(o.name, read[slot].name);
  }
  EXPECT_EQ(sibling->chunks_decompressed(), 0u);
  EXPECT_EQ(later->chunks_decompressed(), 0u);
  EXPECT_GT(first->chunk_cache_bytes(), 0u);
  EXPECT_LE(first->chunk_cache_bytes(), kChunkCacheBytes);

  // A state read under a small bound keeps at most that much: what fell out is decompressed
  // again, correctly.
  const size_t chunk_bytes = first->chunk_cache_bytes() / chunks.size();
  const size_t bound = chunk_bytes * 4;
  first.reset();
  sibling.reset();
  later.reset();
  import_objects(*store, scattered("s", kObjects, 6), "s");  // a new state, new slots
  store.reset();
  const std::vector<uint32_t> new_chunks = object_chunk_firsts(dir.str());
  store = open_store(dir.str());
  detail::set_chunk_cache_bytes(bound);
  auto small = store->read(error);
  ASSERT_TRUE(small) << error;
  auto other = small->sibling(error);
  ASSERT_TRUE(other) << error;
  const std::vector<Object> expected = scattered("s", kObjects, 6);
  std::map<uint64_t, const Object*> by_id;
  for (const Object& e : expected) by_id[e.id] = &e;
  const uint32_t base = small->slot_count() - kObjects;  // slots only grow: the new objects'
  ASSERT_EQ(new_chunks[chunk_index(new_chunks, base)], base);
  const size_t new_count = new_chunks.size() - chunk_index(new_chunks, base);
  ASSERT_GT(new_count, 12u);
  for (int pass = 0; pass < 2; ++pass) {
    for (uint32_t slot = base; slot < base + kObjects; ++slot) {
      // The views take turns chunk by chunk, swapping turns in the second pass.
      ReadView& view = (chunk_index(new_chunks, slot) + pass) % 2 ? *other : *small;
      ASSERT_TRUE(view.object(slot, o, false, error)) << error;
      ASSERT_TRUE(by_id.count(o.id)) << "slot " << slot;
      EXPECT_EQ(o.origin_m, by_id[o.id]->origin_m);
      EXPECT_LE(small->chunk_cache_bytes(), bound) << "after slot " << slot;
    }
  }
  // In the second pass each view meets the chunks the other read, which the shared bound has
  // long let go.
  EXPECT_EQ(small->chunks_decompressed() + other->chunks_decompressed(), 2u * new_count);
  detail::set_chunk_cache_bytes(kChunkCacheBytes);
}

TEST(StorePaged, InfoDoesNotDecodeTheSpatialIndex) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, scattered("s", 5000), "s");  // 3 blocks, in spatial_a
  }
  const std::vector<uint8_t> not_a_block = zstd_frame({0x00, 0x01});
  const detail::Key32 block_1(1);
  put_raw(dir.str(), "spatial_a", block_1.val(), not_a_block);
  {
    auto store = open_store(dir.str(), Store::Mode::read_only);
    std::string error;
    auto view = store->read(error);
    ASSERT_TRUE(view) << error;
    EXPECT_EQ(view->info().objects, 5000u);
    EXPECT_EQ(view->info().format_version, kStoreFormatVersion);
    EXPECT_TRUE(view->spatial_block(0, error)) << error;
    EXPECT_TRUE(view->spatial_block(2, error)) << error;
    EXPECT_FALSE(view->spatial_block(1, error));
    EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
    EXPECT_NE(error.find("spatial block 1: block holds 0 entries"), std::string::npos) << error;
    error.clear();
    EXPECT_FALSE(view->for_each_spatial_entry([](const SpatialNode&, const SpatialEntry&) { return true; }, error));
    EXPECT_NE(error.find("spatial block 1"), std::string::npos) << error;
  }
  const std::vector<uint8_t> not_a_top = zstd_frame({1, 2, 3});
  put_raw(dir.str(), "meta", MDB_val{11, const_cast<char*>("spatial_top")}, not_a_top);
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_only, error);
  ASSERT_TRUE(store) << error;
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;  // metadata only
  EXPECT_EQ(view->info().objects, 5000u);
  Object o;
  EXPECT_TRUE(view->object(7, o, true, error)) << error;
  EXPECT_FALSE(view->spatial_ready(error));
  EXPECT_NE(error.find(dir.str()), std::string::npos) << error;
  EXPECT_NE(error.find("spatial top"), std::string::npos) << error;
  EXPECT_TRUE(view->spatial_top().empty());
  EXPECT_EQ(view->spatial_block_count(), 0u);
  error.clear();
  EXPECT_FALSE(view->spatial_block(0, error));
  EXPECT_NE(error.find("spatial top"), std::string::npos) << error;
  error.clear();
  EXPECT_FALSE(view->for_each_spatial_entry([](const SpatialNode&, const SpatialEntry&) { return true; }, error));
  EXPECT_NE(error.find("spatial top"), std::string::npos) << error;
}

// An id put twice in one import, the two puts in different spilled runs: the later wins, the
// earlier is gone from every index, the statistics and its source.
TEST(StorePaged, AnIdPutTwiceAcrossARunBoundaryKeepsTheLaterObject) {
  SmallRuns runs(64 * 16);  // 64 ids a run
  TempDir dir;
  auto store = open_store(dir.str());
  import_objects(*store, scattered("keep", 10, 3), "keep");
  std::vector<Object> objects = scattered("s", 300);
  Object again = objects[10];
  again.name = "/s-10-AGAIN";  // the same id (from the first name), another name and place
  again.origin_m = {5000, 0, 0};
  again.colour = {1, 2, 3, 4};
  // And an id committed before, put twice: the committed one and the first put both go.
  Object kept_again = scattered("keep", 10, 3)[4];
  std::string error;
  {
    auto import = store->begin_import(error);
    ASSERT_TRUE(import) << error;
    for (const Object& o : objects) ASSERT_TRUE(import->put(o, error)) << error;
    ASSERT_TRUE(import->put(kept_again, error)) << error;
    ASSERT_TRUE(import->put(again, error)) << error;
    kept_again.colour = {9, 9, 9, 9};
    ASSERT_TRUE(import->put(kept_again, error)) << error;
    EXPECT_FALSE(run_files(dir.str()).empty());  // the ids did spill
    ASSERT_TRUE(import->commit(error)) << error;
  }
  EXPECT_TRUE(run_files(dir.str()).empty());
  auto view = store->read(error);
  ASSERT_TRUE(view) << error;
  EXPECT_EQ(view->info().objects, 310u);
  EXPECT_EQ(view->spatial_objects(), 310u);
  const auto slot = view->slot_of(again.id);
  ASSERT_TRUE(slot.has_value());
  Object o;
  ASSERT_TRUE(view->object(*slot, o, true, error)) << error;
  EXPECT_TRUE(o == again);
  EXPECT_TRUE(view->slots_named(objects[10].name).empty());
  EXPECT_EQ(view->slots_named(again.name), std::vector<uint32_t>{*slot});
  const auto kept_slot = view->slot_of(kept_again.id);
  ASSERT_TRUE(kept_slot.has_value());
  ASSERT_TRUE(view->object(*kept_slot, o, true, error)) << error;
  EXPECT_TRUE(o == kept_again);
  EXPECT_EQ(view->slots_named(kept_again.name), std::vector<uint32_t>{*kept_slot});
  std::set<uint32_t> spatial_slots;
  ASSERT_TRUE(view->for_each_spatial_entry(
      [&](const SpatialNode&, const SpatialEntry& e) { return spatial_slots.insert(e.slot).second; }, error));
  EXPECT_EQ(spatial_slots.size(), 310u);
  EXPECT_TRUE(spatial_slots.count(*slot));
  // Removing the source removes exactly what it holds now.
  view.reset();
  {
    auto import = store->begin_import(error);
    ASSERT_TRUE(import->remove_source("s", error)) << error;
    ASSERT_TRUE(import->commit(error)) << error;
  }
  const auto left = objects_by_id(*store);
  EXPECT_EQ(left.size(), 10u);
  EXPECT_TRUE(left.at(kept_again.id) == kept_again);
}

// Imports that spill runs replace sources as imports that do not.
TEST(StorePaged, ReimportingWithSpilledRunsReplacesExactlyAsBefore) {
  SmallRuns runs(1000);
  TempDir dir;
  auto store = open_store(dir.str());
  auto a = scattered("a", 3000, 1), b = scattered("b", 2500, 2);
  import_objects(*store, a, "a");
  import_objects(*store, b, "b");
  a.resize(1200);
  for (Object& o : a) o.origin_m += glm::dvec3(3, 0, 0);
  import_objects(*store, a, "a");
  std::map<uint64_t, Object> expected;
  for (const Object& o : a) expected[o.id] = o;
  for (const Object& o : b) expected[o.id] = o;
  const auto back = objects_by_id(*store);
  ASSERT_EQ(back.size(), expected.size());
  for (const auto& [id, o] : expected) EXPECT_TRUE(back.at(id) == o) << o.name;
  std::string error;
  auto view = store->read(error);
  EXPECT_EQ(view->spatial_objects(), expected.size());
  for (const auto& [id, o] : expected) {
    const auto slot = view->slot_of(id);
    ASSERT_TRUE(slot.has_value());
    EXPECT_EQ(view->slots_named(o.name).size(), 1u) << o.name;
  }
  EXPECT_TRUE(run_files(dir.str()).empty());
}

// Where the child importing 4000 objects (runs of 100) is killed.
enum class KillAt { after_puts, runs_written, ids_merged, blocks_written };

void kill_self(const char*) { raise(SIGKILL); }

void import_and_die(const std::string& dir, KillAt at) {
  detail::set_import_run_bytes(100 * sizeof(uint64_t) * 2);
  if (at == KillAt::ids_merged || at == KillAt::blocks_written) {
    static KillAt where;
    where = at;
    detail::set_import_stage_hook([](const char* stage) {
      if ((where == KillAt::ids_merged && std::string(stage) == "ids merged") ||
          (where == KillAt::blocks_written && std::string(stage) == "blocks written")) {
        kill_self(stage);
      }
    });
  }
  std::string error;
  auto store = Store::open(dir, Store::Mode::read_write, error);
  if (!store) _exit(3);
  auto import = store->begin_import(error);
  if (!import || !import->remove_source("a", error)) _exit(4);
  const auto objects = scattered("a", 4000, 77);
  for (size_t i = 0; i < objects.size(); ++i) {
    if (at == KillAt::after_puts && i == 1500) kill_self("puts");
    if (!import->put(objects[i], error)) _exit(5);
  }
  if (at == KillAt::runs_written) kill_self("runs");
  import->commit(error);
  _exit(6);  // not reached: the hook kills the process first
}

TEST(StorePaged, AnImportKilledAtAnyPointLeavesTheStoreAsItWasAndTheNextCleansUp) {
  TempDir dir;
  {
    auto store = open_store(dir.str());
    import_objects(*store, scattered("a", 3000, 1), "a");
    import_objects(*store, scattered("b", 100, 2), "b");
  }
  const auto before = [&] {
    auto store = open_store(dir.str(), Store::Mode::read_only);
    return objects_by_id(*store);
  }();
  ASSERT_EQ(before.size(), 3100u);
  for (KillAt at : {KillAt::after_puts, KillAt::runs_written, KillAt::ids_merged, KillAt::blocks_written}) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) import_and_die(dir.str(), at);
    int status = 0;
    waitpid(child, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "stage " << int(at) << ": the child stopped by itself: " << WEXITSTATUS(status);
    EXPECT_FALSE(run_files(dir.str()).empty()) << "stage " << int(at);
    auto store = open_store(dir.str());
    const auto now = objects_by_id(*store);
    ASSERT_EQ(now.size(), before.size()) << "stage " << int(at);
    for (const auto& [id, o] : before) EXPECT_TRUE(now.at(id) == o) << o.name;
    std::string error;
    auto view = store->read(error);
    ASSERT_TRUE(view) << error;
    EXPECT_EQ(view->spatial_objects(), 3100u);
    EXPECT_EQ(view->info().objects, 3100u);
    view.reset();
    // The next import removes what the killed one left.
    auto import = store->begin_import(error);
    ASSERT_TRUE(import) << error;
    EXPECT_TRUE(run_files(dir.str()).empty()) << "stage " << int(at);
  }
  // And the store takes imports afterwards.
  auto store = open_store(dir.str());
  import_objects(*store, scattered("a", 4000, 77), "a");
  EXPECT_EQ(objects_by_id(*store).size(), 4100u);
}

}  // namespace
}  // namespace plantview
