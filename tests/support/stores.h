// Stores for tests: one made of given objects (make_object: one of a single primitive), or a
// generated plant, in a temporary directory the caller keeps alive. A store that cannot be made fails the test (GoogleTest) and is null.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/model.h"
#include "plantview/store.h"
#include "support/temp_dir.h"

namespace plantview::test {

// An object of one primitive, placed at `origin_m`, from the source "test" (its id follows
// from its name, as an import's would).
inline Object make_object(const std::string& name, ObjectClass cls, glm::dvec3 origin_m, Colour colour,
                          Primitive primitive) {
  Object o;
  o.name = name;
  o.source = "test";
  o.id = object_id(o.source, name);
  o.object_class = cls;
  o.origin_m = origin_m;
  o.colour = colour;
  o.primitives.push_back(std::move(primitive));
  return o;
}

inline std::unique_ptr<Store> make_store(const TempDir& dir, const std::vector<Object>& objects) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  if (!store) return nullptr;
  const IngestResult result = ingest_objects(*store, objects);
  EXPECT_TRUE(result) << result.error().message;
  return store;
}

// A generated plant of `preset` ('a' .. 'c', generate.h).
inline std::unique_ptr<Store> generated_store(const TempDir& dir, char preset) {
  std::string error;
  auto store = Store::open(dir.str(), Store::Mode::read_write, error);
  EXPECT_TRUE(store) << error;
  if (!store) return nullptr;
  GenerateOptions options;
  options.preset = preset;
  const IngestResult result = ingest_generated(*store, options);
  EXPECT_TRUE(result) << result.error().message;
  return result ? std::move(store) : nullptr;
}

}  // namespace plantview::test
