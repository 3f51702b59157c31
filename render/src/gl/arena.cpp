// GL backend: the vertex arena's buffers (grown or mapped client memory) and the index buffers
// (rules in gl/backend.h).
#include "gl/backend.h"

#include <epoxy/gl.h>
#include <sys/mman.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cstring>
#include <string>

namespace plantview::detail {

GlBackend::Mapping::~Mapping() { reset(); }

void GlBackend::Mapping::reset() {
  if (data_) munmap(data_, bytes_);
  data_ = nullptr;
  bytes_ = 0;
  committed_ = 0;
}

void GlBackend::Mapping::commit_to(size_t end_bytes) {
  if (end_bytes <= committed_ || !can_commit_) return;
  const size_t target = std::min(bytes_, (end_bytes + kCommitStep - 1) / kCommitStep * kCommitStep);
  if (madvise(static_cast<char*>(data_) + committed_, target - committed_, MADV_POPULATE_WRITE) != 0) {
    can_commit_ = false;  // (before Linux 5.14, or refused: the writes fault the pages in)
    return;
  }
  committed_ = target;
}

bool GlBackend::Mapping::map(size_t bytes) {
  assert(!data_ && bytes > 0);
  // Anonymous pages read as zero and take memory only once written; no swap is reserved for
  // the untouched rest.
  void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) return false;
  data_ = p;
  bytes_ = bytes;
  return true;
}

bool GlBackend::map_arena() {
  if (!epoxy_has_gl_extension("GL_AMD_pinned_memory")) return false;
  const auto give_up = [&] {
    mapped_vertices_.reset();
    mapped_objects_.reset();
    return false;
  };
  if (!mapped_vertices_.map(budget_vertices_ * sizeof(PackedVertex)) ||
      !mapped_objects_.map(budget_vertices_ * sizeof(uint32_t)))
    return give_up();
  GLuint buffers[2];
  glCreateBuffers(2, buffers);
  const Mapping* memory[2] = {&mapped_vertices_, &mapped_objects_};
  const size_t sizes[2] = {sizeof(PackedVertex), sizeof(uint32_t)};
  for (int b = 0; b < 2; ++b) {
    glBindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, buffers[b]);
    glBufferData(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, GLsizeiptr(budget_vertices_ * sizes[b]),
                 memory[b]->data(), GL_STREAM_DRAW);
  }
  glBindBuffer(GL_EXTERNAL_VIRTUAL_MEMORY_BUFFER_AMD, 0);
  if (glGetError() != GL_NO_ERROR) {  // (llvmpipe: a buffer over 4 GB)
    glDeleteBuffers(2, buffers);
    return give_up();
  }
  arena_ = buffers[0];
  arena_objects_ = buffers[1];
  arena_vertices_ = budget_vertices_;
  bind_arena();
  return true;
}

void GlBackend::bind_arena() {
  glVertexArrayVertexBuffer(vao_, 0, arena_, 0, sizeof(PackedVertex));
  glVertexArrayVertexBuffer(vao_, 1, arena_objects_, 0, sizeof(uint32_t));
}

bool GlBackend::grow_arena(uint64_t vertices, std::string& error) {
  vertices = std::min(vertices, budget_vertices_);  // (a full arena evicts instead)
  if (vertices <= arena_vertices_) return true;
  const uint64_t size = std::min(budget_vertices_, std::max(vertices + vertices / 2, arena_vertices_ * 2));
  const auto start = std::chrono::steady_clock::now();
  GLuint buffers[2];
  glCreateBuffers(2, buffers);
  glNamedBufferStorage(buffers[0], GLsizeiptr(size * sizeof(PackedVertex)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  glNamedBufferStorage(buffers[1], GLsizeiptr(size * sizeof(uint32_t)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  if (glGetError() != GL_NO_ERROR) {
    glDeleteBuffers(2, buffers);
    error = "renderer: cannot allocate " + std::to_string((size * kBytesPerVertex) >> 20) +
            " MB of the vertex arena";
    return false;
  }
  if (arena_vertices_) {
    glCopyNamedBufferSubData(arena_, buffers[0], 0, 0, GLsizeiptr(arena_vertices_ * sizeof(PackedVertex)));
    glCopyNamedBufferSubData(arena_objects_, buffers[1], 0, 0, GLsizeiptr(arena_vertices_ * sizeof(uint32_t)));
    GLuint old[2] = {arena_, arena_objects_};
    glDeleteBuffers(2, old);
  }
  arena_ = buffers[0];
  arena_objects_ = buffers[1];
  arena_vertices_ = size;
  bind_arena();
  growth_ms_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return true;
}

void GlBackend::upload(uint64_t first, std::span<const PackedVertex> vertices,
                       std::span<const uint32_t> objects) {
  if (arena_mapped()) {
    mapped_vertices_.commit_to((first + vertices.size()) * sizeof(PackedVertex));
    if (!objects.empty()) mapped_objects_.commit_to((first + objects.size()) * sizeof(uint32_t));
    std::memcpy(static_cast<PackedVertex*>(mapped_vertices_.data()) + first, vertices.data(), vertices.size_bytes());
    if (!objects.empty())
      std::memcpy(static_cast<uint32_t*>(mapped_objects_.data()) + first, objects.data(), objects.size_bytes());
    return;
  }
  glNamedBufferSubData(arena_, GLintptr(first * sizeof(PackedVertex)),
                       GLsizeiptr(vertices.size_bytes()), vertices.data());
  if (!objects.empty())
    glNamedBufferSubData(arena_objects_, GLintptr(first * sizeof(uint32_t)),
                         GLsizeiptr(objects.size_bytes()), objects.data());
}

uint32_t* GlBackend::map_indices(size_t count, std::string& error, bool next) {
  const unsigned which = next ? 1 - drawn_indices_ : drawn_indices_;
  const GLuint buffer = index_buffers_[which];
  size_t& capacity = index_capacities_[which];
  const size_t bytes = std::max<size_t>(count, 1) * sizeof(uint32_t);
  if (bytes > capacity) {
    capacity = std::max(bytes, capacity * 3 / 2);
    glNamedBufferData(buffer, GLsizeiptr(capacity), nullptr, GL_STREAM_DRAW);
  }
  // Unsynchronised: nothing the GPU may still draw reads it (the drawn one: the previous frame
  // was finished, read back, before this one began, and a frame's phases wait for each other;
  // the next one: drawn only from the next frame on), and invalidating would make the driver
  // allocate (and zero) new storage every frame.
  auto* indices = static_cast<uint32_t*>(glMapNamedBufferRange(
      buffer, 0, GLsizeiptr(bytes), GL_MAP_WRITE_BIT | GL_MAP_UNSYNCHRONIZED_BIT));
  if (!indices) error = "renderer: cannot map " + std::to_string(bytes >> 20) + " MB of index buffer";
  return indices;
}

void GlBackend::unmap_indices(bool next) {
  glUnmapNamedBuffer(index_buffers_[next ? 1 - drawn_indices_ : drawn_indices_]);
}

void GlBackend::use_next_indices() {
  drawn_indices_ = 1 - drawn_indices_;
  glVertexArrayElementBuffer(vao_, index_buffers_[drawn_indices_]);
}

}  // namespace plantview::detail
