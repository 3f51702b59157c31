// Internal: LEB128 varints (7 bits a byte, low bits first) and zigzag for signed values, the
// building block of the index encodings (tables.cpp, spatial.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace plantview::detail {

inline void put_varint(std::vector<uint8_t>& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(uint8_t(v | 0x80));
    v >>= 7;
  }
  out.push_back(uint8_t(v));
}

inline uint64_t zigzag(int64_t v) { return (uint64_t(v) << 1) ^ uint64_t(v >> 63); }
inline int64_t unzigzag(uint64_t v) { return int64_t(v >> 1) ^ -int64_t(v & 1); }

// Reads varints from a byte range; every read fails softly (false) past the end or on a varint
// longer than 10 bytes.
class VarintReader {
 public:
  VarintReader(const uint8_t* data, size_t size) : p_(data), end_(data + size) {}
  bool get(uint64_t& v) {
    v = 0;
    for (int shift = 0; shift < 64 && p_ != end_; shift += 7) {
      const uint8_t b = *p_++;
      v |= uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) return true;
    }
    return false;
  }
  bool get_u32(uint32_t& v) {
    uint64_t w;
    if (!get(w) || w > UINT32_MAX) return false;
    v = uint32_t(w);
    return true;
  }
  bool get_signed(int64_t& v) {
    uint64_t w;
    if (!get(w)) return false;
    v = unzigzag(w);
    return true;
  }
  size_t remaining() const { return size_t(end_ - p_); }
  bool at_end() const { return p_ == end_; }
  const uint8_t* position() const { return p_; }
  void skip(size_t n) { p_ += n; }  // n <= remaining()

 private:
  const uint8_t* p_;
  const uint8_t* end_;
};

}  // namespace plantview::detail
