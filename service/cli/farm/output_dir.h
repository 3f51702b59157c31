// The farm's output directory: checked before any work, written one whole file at a time.
//
// Rules: every file a render or a merge leaves in the directory appears complete or not at all
// (written to a temporary name in the same directory, flushed, then renamed over the final
// name), so a task killed at any moment never leaves a half image or manifest that looks done.
// Temporary names start with ".tmp-" and carry the writer's process id; a killed writer's
// leftovers are harmless and are never read.
// Errors: false with a message naming the path and the system's reason.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace plantview::cli::farm {

// Creates `dir` (and its parents) if needed and proves it writable by creating and removing a
// file in it: as root, permission bits say nothing, a read-only file system still refuses.
bool prepare_output_dir(const std::filesystem::path& dir, std::string& error);

// Writes `bytes` to `path` atomically (see above).
bool write_file_atomically(const std::filesystem::path& path, std::string_view bytes,
                           std::string& error);

// Copies the file `from` to `path` atomically (see above), streaming: never held whole.
bool copy_file_atomically(const std::filesystem::path& from, const std::filesystem::path& path,
                          std::string& error);

// Reads a whole file. False with "cannot read PATH: reason".
bool read_file(const std::filesystem::path& path, std::string& out, std::string& error);

// An exclusive advisory lock (flock) on DIR/.farm.lock, held for the object's life: the shards
// of one job take it to merge their manifests one at a time. Blocks until it is free.
class DirLock {
 public:
  DirLock(const std::filesystem::path& dir, std::string& error);
  ~DirLock();
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;
  bool locked() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

}  // namespace plantview::cli::farm
