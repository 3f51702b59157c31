// Zip archives for BCF files through libzip: written whole at close, read an entry at a time
// with names and sizes checked first.
#include <zip.h>

#include <cstdlib>
#include <cstring>

#include "bcf_internal.h"

namespace plantview::bcf {

namespace {

std::string zip_message(::zip* archive) { return zip_strerror(archive); }

std::string open_error_message(int code) {
  zip_error_t e;
  zip_error_init_with_code(&e, code);
  std::string message = zip_error_strerror(&e);
  zip_error_fini(&e);
  return message;
}

// True if an entry name stays inside the archive's folders: no absolute path, no drive letter,
// no '..' part. `name` has '/' separators already.
bool is_contained(const std::string& name) {
  if (name.empty() || name.front() == '/') return false;
  if (name.size() >= 2 && name[1] == ':') return false;
  size_t start = 0;
  while (start <= name.size()) {
    const size_t end = std::min(name.find('/', start), name.size());
    if (name.compare(start, end - start, "..") == 0 && end - start == 2) return false;
    start = end + 1;
  }
  return true;
}

}  // namespace

ZipWriter::~ZipWriter() {
  if (archive_) zip_discard(archive_);
}

bool ZipWriter::open(const std::filesystem::path& path, std::string& error) {
  int code = 0;
  archive_ = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
  path_ = path;
  if (!archive_) {
    error = "cannot create " + path.string() + ": " + open_error_message(code);
    return false;
  }
  return true;
}

bool ZipWriter::add_bytes(const std::string& name, std::string bytes, std::string& error) {
  // libzip frees the copy (freep = 1) once written or discarded.
  void* copy = std::malloc(bytes.empty() ? 1 : bytes.size());
  if (!copy) {
    error = "out of memory for " + name;
    return false;
  }
  std::memcpy(copy, bytes.data(), bytes.size());
  zip_source_t* source = zip_source_buffer(archive_, copy, bytes.size(), 1);
  if (!source) {
    std::free(copy);
    error = "cannot add " + name + " to " + path_.string() + ": " + zip_message(archive_);
    return false;
  }
  if (zip_file_add(archive_, name.c_str(), source, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE) < 0) {
    zip_source_free(source);
    error = "cannot add " + name + " to " + path_.string() + ": " + zip_message(archive_);
    return false;
  }
  return true;
}

bool ZipWriter::add_file(const std::string& name, const std::filesystem::path& file, std::string& error) {
  zip_source_t* source = zip_source_file(archive_, file.c_str(), 0, -1);
  if (!source) {
    error = "cannot read " + file.string() + ": " + zip_message(archive_);
    return false;
  }
  const zip_int64_t index = zip_file_add(archive_, name.c_str(), source, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE);
  if (index < 0) {
    zip_source_free(source);
    error = "cannot add " + file.string() + " to " + path_.string() + ": " + zip_message(archive_);
    return false;
  }
  zip_set_file_compression(archive_, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
  return true;
}

bool ZipWriter::close(std::string& error) {
  if (zip_close(archive_) != 0) {
    error = "cannot write " + path_.string() + ": " + zip_message(archive_);
    zip_discard(archive_);
    archive_ = nullptr;
    return false;
  }
  archive_ = nullptr;
  return true;
}

ZipReader::~ZipReader() {
  if (archive_) zip_discard(archive_);
}

bool ZipReader::open(const std::filesystem::path& path, uint64_t max_entry_bytes, uint64_t max_total_bytes,
                     std::string& error) {
  max_entry_bytes_ = max_entry_bytes;
  max_total_bytes_ = max_total_bytes;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    error = path.string() + ": no such file";
    return false;
  }
  int code = 0;
  archive_ = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &code);
  if (!archive_) {
    error =
        path.string() + ": not a readable zip archive (" +
        (code == ZIP_ER_NOZIP ? std::string("not a zip archive, or truncated") : open_error_message(code)) +
        ")";
    return false;
  }
  const zip_int64_t count = zip_get_num_entries(archive_, 0);
  for (zip_int64_t i = 0; i < count; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(archive_, static_cast<zip_uint64_t>(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_NAME)) {
      error = path.string() + ": entry " + std::to_string(i) + ": " + zip_message(archive_);
      return false;
    }
    std::string name = st.name;
    for (char& c : name)
      if (c == '\\') c = '/';
    if (!is_contained(name)) {
      error = path.string() + ": entry '" + std::string(st.name) +
              "' escapes the archive's folders (an absolute path or a '..' part)";
      return false;
    }
    if ((st.valid & ZIP_STAT_SIZE) && st.size > max_entry_bytes_) {
      error = path.string() + ": entry '" + name + "' is " + std::to_string(st.size) +
              " bytes uncompressed, over the limit of " + std::to_string(max_entry_bytes_);
      return false;
    }
    if (name.back() == '/') continue;  // a directory
    names_.push_back(std::move(name));
    indices_.push_back(i);
  }
  return true;
}

bool ZipReader::has(const std::string& name) const {
  for (const std::string& n : names_)
    if (n == name) return true;
  return false;
}

bool ZipReader::read(const std::string& name, std::string& out, std::string& error) {
  int64_t index = -1;
  for (size_t i = 0; i < names_.size(); ++i)
    if (names_[i] == name) index = indices_[i];
  if (index < 0) {
    error = "no entry '" + name + "'";
    return false;
  }
  zip_stat_t st;
  zip_stat_init(&st);
  if (zip_stat_index(archive_, static_cast<zip_uint64_t>(index), 0, &st) != 0) {
    error = "entry '" + name + "': " + zip_message(archive_);
    return false;
  }
  if (total_read_ + st.size > max_total_bytes_) {
    error = "entry '" + name + "': the entries read come to over " + std::to_string(max_total_bytes_) +
            " bytes uncompressed";
    return false;
  }
  zip_file_t* file = zip_fopen_index(archive_, static_cast<zip_uint64_t>(index), 0);
  if (!file) {
    error = "entry '" + name + "': " + zip_message(archive_);
    return false;
  }
  out.assign(st.size, '\0');
  // One byte more than the header says, to catch an entry that inflates past its stated size.
  std::string extra(1, '\0');
  zip_int64_t got = 0;
  while (static_cast<uint64_t>(got) < st.size) {
    const zip_int64_t n = zip_fread(file, out.data() + got, st.size - static_cast<uint64_t>(got));
    if (n <= 0) break;
    got += n;
  }
  const bool short_read = static_cast<uint64_t>(got) != st.size;
  const bool over = !short_read && zip_fread(file, extra.data(), 1) > 0;
  std::string reason = short_read || over ? zip_error_strerror(zip_file_get_error(file)) : "";
  const int closed = zip_fclose(file);
  if (short_read || over || closed != 0) {
    error = "entry '" + name + "' cannot be read whole (" +
            (over             ? std::string("larger than its header says")
             : reason.empty() ? "truncated"
                              : reason) +
            ")";
    out.clear();
    return false;
  }
  total_read_ += st.size;
  return true;
}

}  // namespace plantview::bcf
