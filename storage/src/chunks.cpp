#include "chunks.h"

#include <algorithm>
#include <cstring>

namespace plantview::detail {

namespace {

// Spatial blocks and the top (make_compressor()): preset c's 20 blocks take 96 pages at 6, 111
// at 3, and gen --scale 100 spends about 1 s more of CPU on them (of 28).
constexpr int kCompressionLevel = 6;
constexpr size_t kMaxInflatedBytes = size_t(1) << 30;

uint32_t read_le32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
void write_le32(uint8_t* p, uint32_t v) { std::memcpy(p, &v, 4); }

}  // namespace

bool split_chunk_value(const uint8_t* data, size_t size, uint32_t& slot_count,
                       std::span<const uint8_t>& frame, std::string& error) {
  if (size <= 4) {
    error = size < 4 ? "chunk value is truncated" : "chunk value holds no frame";
    return false;
  }
  slot_count = read_le32(data);
  if (slot_count == 0) {
    error = "chunk value holds no slots";
    return false;
  }
  frame = {data + 4, size - 4};
  return true;
}

void join_chunk_value(uint32_t slot_count, std::span<const uint8_t> frame,
                      std::vector<uint8_t>& out) {
  out.resize(4 + frame.size());
  write_le32(out.data(), slot_count);
  if (!frame.empty()) std::memcpy(out.data() + 4, frame.data(), frame.size());
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

void pack_chunk(std::span<const uint32_t> sizes, std::span<const uint8_t> bytes,
                std::vector<uint8_t>& out) {
  out.resize(sizes.size() * 4 + bytes.size());
  for (size_t i = 0; i < sizes.size(); ++i) write_le32(out.data() + 4 * i, sizes[i]);
  if (!bytes.empty()) std::memcpy(out.data() + sizes.size() * 4, bytes.data(), bytes.size());
}

bool check_chunk(const std::vector<uint8_t>& chunk, uint32_t slot_count,
                 std::vector<uint32_t>& ends, std::string& error) {
  const size_t header = size_t(slot_count) * 4;
  if (chunk.size() < header) {
    error = "chunk is truncated";
    return false;
  }
  const size_t body = chunk.size() - header;
  ends.resize(slot_count);
  size_t end = 0;
  for (uint32_t i = 0; i < slot_count; ++i) {
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

bool cut_chunks(ZSTD_CCtx* cctx, uint32_t first_slot, std::span<const uint32_t> sizes,
                std::span<const uint8_t> bytes, size_t frame_budget, std::vector<ChunkValue>& out,
                std::string& error) {
  const size_t n = sizes.size();
  std::vector<size_t> offset(n + 1, 0);  // of each slot's record in `bytes`
  for (size_t s = 0; s < n; ++s) offset[s + 1] = offset[s] + sizes[s];
  const auto layout_bytes = [&](size_t begin, size_t end) {
    return 4 * (end - begin) + offset[end] - offset[begin];
  };
  const size_t slack = frame_budget / 32;
  double ratio = 0.25;  // frame bytes per layout byte, as the last trial found
  std::vector<uint8_t> layout, frame, fit_frame;
  size_t begin = 0;
  for (;;) {
    while (begin < n && sizes[begin] == 0) ++begin;
    if (begin == n) return true;
    // The chunk's end (exclusive) is searched between what is known to fit and what is known
    // not to, each trial at the end whose layout compresses, at the last ratio, to just under
    // the budget: two or three trials a chunk.
    size_t fit_end = 0;        // the longest chunk known to fit (0: none yet)
    size_t over_end = n + 1;   // the shortest known not to
    for (;;) {
      const double want = double(frame_budget - slack / 2) / ratio;
      size_t lo = begin + 1, hi = n;  // the first end whose layout reaches `want`
      while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (double(layout_bytes(begin, mid)) >= want) {
          hi = mid;
        } else {
          lo = mid + 1;
        }
      }
      const size_t end = std::clamp(lo, std::max(begin + 1, fit_end + 1), over_end - 1);
      pack_chunk(sizes.subspan(begin, end - begin),
                 bytes.subspan(offset[begin], offset[end] - offset[begin]), layout);
      if (!compress_frame(cctx, layout, frame, error)) return false;
      ratio = double(std::max<size_t>(frame.size(), 1)) / double(layout.size());
      if (frame.size() <= frame_budget || end == begin + 1) {
        // Fits (or one record, a chunk of its own whatever its size).
        fit_end = end;
        fit_frame.swap(frame);
        if (end == n || fit_end + 1 >= over_end || fit_frame.size() + slack >= frame_budget ||
            fit_frame.size() > frame_budget) {
          break;
        }
      } else {
        over_end = end;
        if (fit_end + 1 >= over_end) break;
      }
    }
    out.push_back({first_slot + uint32_t(begin), {}});
    join_chunk_value(uint32_t(fit_end - begin), fit_frame, out.back().value);
    begin = fit_end;
  }
}

}  // namespace plantview::detail
