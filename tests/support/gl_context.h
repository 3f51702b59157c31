// The GL context of a render test program: one for the whole program (contexts are per thread,
// and a test program's tests run on one), made on first use, its device said once on stderr.
// Without one the test asking fails and the program aborts: every render test needs it.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "plantview/render.h"

namespace plantview::test {

inline GpuContext& gl_context() {
  static std::unique_ptr<GpuContext> ctx = [] {
    std::string error;
    auto c = GpuContext::create(-1, error);
    if (!c) ADD_FAILURE() << error;
    else std::fprintf(stderr, "render tests on: %s\n", c->description().c_str());
    return c;
  }();
  if (!ctx) std::abort();
  return *ctx;
}

}  // namespace plantview::test
