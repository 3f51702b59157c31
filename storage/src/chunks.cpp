#include "chunks.h"

#include <cstring>

namespace plantview::detail {

namespace {

constexpr int kCompressionLevel = 3;  // level 6 halves ingest speed for 5% fewer bytes
constexpr size_t kMaxInflatedBytes = size_t(1) << 30;

uint32_t read_le32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
void write_le32(uint8_t* p, uint32_t v) { std::memcpy(p, &v, 4); }

}  // namespace

bool split_block(const uint8_t* data, size_t size, uint32_t chunks,
                 std::vector<std::span<const uint8_t>>& frames, std::string& error) {
  frames.clear();
  const size_t header = size_t(chunks) * 4;
  if (size < header) {
    error = "block is truncated";
    return false;
  }
  uint32_t begin = 0;
  for (uint32_t i = 0; i < chunks; ++i) {
    const uint32_t end = read_le32(data + 4 * i);
    if (end < begin || end > size - header) {
      error = "block header is corrupt";
      return false;
    }
    frames.emplace_back(data + header + begin, end - begin);
    begin = end;
  }
  if (begin != size - header) {
    error = "block has trailing bytes";
    return false;
  }
  return true;
}

void join_block(const std::vector<std::vector<uint8_t>>& frames, std::vector<uint8_t>& out) {
  size_t total = 0;
  for (const auto& f : frames) total += f.size();
  out.resize(frames.size() * 4 + total);
  uint32_t end = 0;
  uint8_t* at = out.data() + frames.size() * 4;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!frames[i].empty()) std::memcpy(at, frames[i].data(), frames[i].size());
    at += frames[i].size();
    end += uint32_t(frames[i].size());
    write_le32(out.data() + 4 * i, end);
  }
}

void pack_chunk(const std::vector<std::vector<uint8_t>>& records, std::vector<uint8_t>& out) {
  size_t total = 0;
  for (const auto& r : records) total += r.size();
  out.resize(records.size() * 4 + total);
  uint8_t* at = out.data() + records.size() * 4;
  for (size_t i = 0; i < records.size(); ++i) {
    if (!records[i].empty()) std::memcpy(at, records[i].data(), records[i].size());
    at += records[i].size();
    write_le32(out.data() + 4 * i, uint32_t(records[i].size()));
  }
}

bool check_chunk(const std::vector<uint8_t>& chunk, uint32_t chunk_slots,
                 std::vector<uint32_t>& ends, std::string& error) {
  const size_t header = size_t(chunk_slots) * 4;
  if (chunk.size() < header) {
    error = "chunk is truncated";
    return false;
  }
  const size_t body = chunk.size() - header;
  ends.resize(chunk_slots);
  size_t end = 0;
  for (uint32_t i = 0; i < chunk_slots; ++i) {
    end += read_le32(chunk.data() + 4 * i);
    if (end > body) {
      error = "chunk header is corrupt";
      return false;
    }
    ends[i] = uint32_t(end);
  }
  if (end != body) {
    error = "chunk has trailing bytes";
    return false;
  }
  return true;
}

std::span<const uint8_t> chunk_record(const std::vector<uint8_t>& chunk,
                                      const std::vector<uint32_t>& ends, uint32_t index) {
  const uint32_t begin = index == 0 ? 0 : ends[index - 1];
  return {chunk.data() + ends.size() * 4 + begin, ends[index] - begin};
}

ZstdCCtx make_compressor() {
  ZstdCCtx c(ZSTD_createCCtx());
  ZSTD_CCtx_setParameter(c.get(), ZSTD_c_compressionLevel, kCompressionLevel);
  ZSTD_CCtx_setParameter(c.get(), ZSTD_c_contentSizeFlag, 1);
  ZSTD_CCtx_setParameter(c.get(), ZSTD_c_checksumFlag, 0);
  return c;
}

bool compress_frame(ZSTD_CCtx* cctx, std::span<const uint8_t> in, std::vector<uint8_t>& out,
                    std::string& error) {
  out.resize(ZSTD_compressBound(in.size()));
  const size_t n = ZSTD_compress2(cctx, out.data(), out.size(), in.data(), in.size());
  if (ZSTD_isError(n)) {
    error = std::string("compressing: ") + ZSTD_getErrorName(n);
    return false;
  }
  out.resize(n);
  return true;
}

bool inflate_frame(ZSTD_DCtx* dctx, std::span<const uint8_t> frame, std::vector<uint8_t>& out,
                   std::string& error) {
  const unsigned long long size = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN ||
      size > kMaxInflatedBytes) {
    error = "not a valid zstd frame";
    return false;
  }
  out.resize(size);
  const size_t got = ZSTD_decompressDCtx(dctx, out.data(), out.size(), frame.data(), frame.size());
  if (ZSTD_isError(got) || got != size) {
    error = std::string("does not decompress: ") +
            (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short");
    return false;
  }
  return true;
}

}  // namespace plantview::detail
