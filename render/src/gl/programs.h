// GL helpers of the backend's passes: programs linked from their sources (program_sources.h),
// uniform lookup, and the stream buffers a frame refills.
// Threads: the backend's (its GL context current). Errors: 0 with "renderer: ..." in `error`.
#pragma once

#include <epoxy/gl.h>

#include <cstddef>
#include <initializer_list>
#include <string>
#include <utility>

#include "gl/program_sources.h"

namespace plantview::detail {

// Compiles the shaders of `source` and links them into a program: 0 with the compiler's or the
// linker's log in `error`, naming the program ("renderer: the <name> shaders do not link: ...").
GLuint link(const ProgramSource& source, std::string& error);

// A uniform's location in `program` (-1 where the program has none by that name: setting it
// does nothing).
inline GLint at(GLuint program, const char* name) { return glGetUniformLocation(program, name); }

// Fills a stream buffer from `parts`, one after the other, growing it (`capacity`, bytes) by half
// again when it is too small. No invalidation: the buffer is idle (the last frame was read back),
// and new storage would be zeroed every frame.
void upload_stream(GLuint buffer, size_t& capacity, size_t bytes,
                   std::initializer_list<std::pair<const void*, size_t>> parts);

}  // namespace plantview::detail
