// Internal: an import's index data in bounded memory: fixed-size records appended to a buffer,
// which, when full, is sorted and written to a run file in the store directory
// (import-<pid>-<kind>-<n>.run, opened O_CLOEXEC); at commit a k-way merge reads every run and
// the buffer's rest in sorted order. Files are removed when the SpilledRuns is destroyed
// (commit or abort); a killed process leaves them, and the next import removes them
// (remove_stale_runs, called while it holds LMDB's writer lock, so no other import is running).
// Single-threaded, like the import.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <queue>
#include <string>
#include <type_traits>
#include <vector>

namespace plantview::detail {

// Bytes of each of an import's buffers (ids, names, spatial) before it spills a run; tests set
// it small to make runs spill. Read by begin_import.
size_t import_run_bytes();
void set_import_run_bytes(size_t bytes);
// Called by commit() at named stages ("ids merged", "blocks written"); tests kill themselves
// there. Null (the default): nothing.
using ImportStageHook = void (*)(const char* stage);
void set_import_stage_hook(ImportStageHook hook);
void import_stage(const char* stage);
// Removes import-*.run files in `directory` (left by killed imports).
void remove_stale_runs(const std::string& directory);

template <typename T, typename Less>
class SpilledRuns {
  static_assert(std::is_trivially_copyable_v<T>);
  struct Run {
    std::string path;
    int fd;
    uint64_t count;
  };

 public:
  SpilledRuns(std::string directory, std::string kind, size_t capacity)
      : directory_(std::move(directory)), kind_(std::move(kind)),
        capacity_(std::max<size_t>(capacity, 1)) {}
  ~SpilledRuns() {
    for (Run& r : runs_) {
      ::close(r.fd);
      std::error_code ec;
      std::filesystem::remove(r.path, ec);
    }
  }
  SpilledRuns(const SpilledRuns&) = delete;
  SpilledRuns& operator=(const SpilledRuns&) = delete;

  // False with a message naming the run file on a write error.
  bool add(const T& value, std::string& error) {
    if (buffer_.capacity() == 0) buffer_.reserve(capacity_);
    buffer_.push_back(value);
    return buffer_.size() < capacity_ || spill(error);
  }
  size_t runs() const { return runs_.size(); }
  uint64_t size() const { return spilled_ + buffer_.size(); }

  // Reads every value in sorted order (runs and the buffer's rest). Start it once, after the
  // last add(). Reads runs in pieces of kReadValues values each.
  class Merger {
   public:
    explicit Merger(SpilledRuns& owner) : owner_(owner) {}
    bool start(std::string& error) {
      std::sort(owner_.buffer_.begin(), owner_.buffer_.end(), Less{});
      sources_.resize(owner_.runs_.size() + 1);
      for (size_t i = 0; i < owner_.runs_.size(); ++i) {
        sources_[i].run = &owner_.runs_[i];
        if (!fill(sources_[i], error)) return false;
        if (sources_[i].at < sources_[i].values.size()) heap_.push(i);
      }
      Source& memory = sources_.back();
      memory.memory = &owner_.buffer_;
      if (!owner_.buffer_.empty()) heap_.push(sources_.size() - 1);
      return true;
    }
    // False at the end (`done` true) or on a read error (`done` false, message set).
    bool next(T& out, bool& done, std::string& error) {
      done = false;
      if (heap_.empty()) {
        done = true;
        return false;
      }
      const size_t i = heap_.top();
      heap_.pop();
      Source& s = sources_[i];
      out = s.current();
      ++s.at;
      if (s.run && s.at == s.values.size() && !fill(s, error)) return false;
      if (s.at < s.size()) heap_.push(i);
      return true;
    }

   private:
    static constexpr size_t kReadValues = size_t(1) << 14;
    struct Source {
      Run* run = nullptr;
      std::vector<T>* memory = nullptr;
      std::vector<T> values;
      size_t at = 0;
      uint64_t read = 0;  // values read from the run so far
      const T& current() const { return memory ? (*memory)[at] : values[at]; }
      size_t size() const { return memory ? memory->size() : values.size(); }
    };
    bool fill(Source& s, std::string& error) {
      const uint64_t left = s.run->count - s.read;
      const size_t n = size_t(std::min<uint64_t>(left, kReadValues));
      s.values.resize(n);
      s.at = 0;
      size_t done = 0;
      const size_t bytes = n * sizeof(T);
      while (done < bytes) {
        const ssize_t got = ::pread(s.run->fd, reinterpret_cast<char*>(s.values.data()) + done,
                                    bytes - done, off_t(s.read * sizeof(T) + done));
        if (got <= 0) {
          error = "reading " + s.run->path + ": " +
                  (got < 0 ? std::string(std::strerror(errno)) : std::string("cut short"));
          return false;
        }
        done += size_t(got);
      }
      s.read += n;
      return true;
    }
    struct Greater {
      const std::vector<Source>* sources;
      bool operator()(size_t a, size_t b) const {
        return Less{}((*sources)[b].current(), (*sources)[a].current());
      }
    };
    SpilledRuns& owner_;
    std::vector<Source> sources_;
    std::priority_queue<size_t, std::vector<size_t>, Greater> heap_{Greater{&sources_}};
  };

 private:
  bool spill(std::string& error) {
    std::sort(buffer_.begin(), buffer_.end(), Less{});
    const std::string path = directory_ + "/import-" + std::to_string(::getpid()) + "-" + kind_ +
                             "-" + std::to_string(runs_.size()) + ".run";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) {
      error = "creating " + path + ": " + std::strerror(errno);
      return false;
    }
    runs_.push_back({path, fd, buffer_.size()});
    const char* p = reinterpret_cast<const char*>(buffer_.data());
    size_t left = buffer_.size() * sizeof(T);
    while (left > 0) {
      const ssize_t wrote = ::write(fd, p, left);
      if (wrote < 0 && errno == EINTR) continue;
      if (wrote <= 0) {
        error = "writing " + path + ": " + std::strerror(errno);
        return false;
      }
      p += wrote;
      left -= size_t(wrote);
    }
    spilled_ += buffer_.size();
    buffer_.clear();
    return true;
  }

  std::string directory_, kind_;
  size_t capacity_;
  std::vector<T> buffer_;
  std::vector<Run> runs_;
  uint64_t spilled_ = 0;
};

}  // namespace plantview::detail
