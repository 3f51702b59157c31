// Stores for tests: one made of given objects, or a generated plant, in a temporary directory
// the caller keeps alive. A store that cannot be made fails the test (GoogleTest) and is null.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "plantview/generate.h"
#include "plantview/ingest.h"
#include "plantview/model.h"
#include "plantview/store.h"
#include "support/temp_dir.h"

namespace plantview::test {

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
