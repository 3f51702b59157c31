// Internal: the store's writer lock (store.h, "Two writers at once"): an advisory flock on
// <store>/import.lock held beside LMDB's own writer lock, and <store>/import.writer saying who
// holds it, so that a second writer can name the first instead of blocking in silence.
#pragma once

#include <string>

namespace plantview::detail {

class WriterLock {
 public:
  WriterLock() = default;
  ~WriterLock() { release(); }
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;
  // Takes the lock (waiting, with a message on stderr, or failing per set_import_lock_wait())
  // and writes import.writer. False with a message naming the store and the other writer.
  bool acquire(const std::string& directory, std::string& error);
  // Removes import.writer and drops the lock (nothing when not held).
  void release();
  bool held() const { return fd_ >= 0; }

 private:
  std::string directory_;
  int fd_ = -1;
};

// "the import by pid N (COMMAND, started HH:MM:SS)" from <directory>/import.writer, or "another
// import" when the file is missing or names a process that is gone.
std::string describe_writer(const std::string& directory);

}  // namespace plantview::detail
