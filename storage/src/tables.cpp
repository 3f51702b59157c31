#include "tables.h"

#include <cassert>

namespace plantview::detail {

void encode_key_slots(const std::vector<KeySlot>& table, std::vector<uint8_t>& out) {
  out.clear();
  put_varint(out, table.size());
  uint64_t previous = 0;
  for (const KeySlot& e : table) {
    put_varint(out, e.key - previous);
    previous = e.key;
  }
  for (const KeySlot& e : table) put_varint(out, e.slot);
}

bool KeySlotReader::open(const uint8_t* data, size_t size, std::string& error) {
  VarintReader r(data, size);
  count_ = read_ = 0;
  previous_ = {};
  // Every pair takes at least two bytes: the count is checked before anything is allocated.
  if (!r.get(count_) || count_ > r.remaining() / 2) {
    count_ = 0;
    error = "table is truncated";
    return false;
  }
  // The slot column starts after the key column: walk the keys once to find it.
  keys_ = r;
  uint64_t key = 0;
  for (uint64_t i = 0; i < count_; ++i) {
    uint64_t delta;
    if (!r.get(delta)) {
      count_ = 0;
      error = "table is truncated";
      return false;
    }
    if (key + delta < key) {
      count_ = 0;
      error = "table keys overflow";
      return false;
    }
    key += delta;
  }
  slots_ = r;
  return true;
}

bool KeySlotReader::next(KeySlot& pair, std::string& error) {
  assert(read_ < count_ && "KeySlotReader::next() past the end of the table");
  uint64_t delta = 0;
  keys_.get(delta);  // checked by open()
  pair.key = previous_.key + delta;
  if (!slots_.get_u32(pair.slot)) {
    error = "table is truncated";
    return false;
  }
  if (read_ > 0 && !(previous_ < pair)) {
    error = "table is out of order at entry " + std::to_string(read_);
    return false;
  }
  previous_ = pair;
  ++read_;
  return true;
}

bool KeySlotReader::finish(std::string& error) const {
  assert(read_ == count_ && "KeySlotReader::finish() before the last pair");
  if (!slots_.at_end()) {
    error = "trailing bytes after the table";
    return false;
  }
  return true;
}

bool decode_key_slots(const uint8_t* data, size_t size, std::vector<KeySlot>& table,
                      std::string& error) {
  KeySlotReader reader;
  table.clear();
  if (!reader.open(data, size, error)) return false;
  table.resize(reader.size());
  for (KeySlot& e : table) {
    if (!reader.next(e, error)) return false;
  }
  return reader.finish(error);
}

void encode_slot_runs(const std::vector<uint32_t>& slots, std::vector<uint8_t>& out) {
  out.clear();
  std::vector<std::pair<uint32_t, uint32_t>> runs;  // (first, length)
  for (uint32_t slot : slots) {
    if (!runs.empty() && runs.back().first + runs.back().second == slot) {
      ++runs.back().second;
    } else {
      runs.push_back({slot, 1});
    }
  }
  put_varint(out, runs.size());
  uint64_t end = 0;
  for (const auto& [first, length] : runs) {
    put_varint(out, first - end);
    put_varint(out, length);
    end = uint64_t(first) + length;
  }
}

void encode_slot_runs(const std::vector<SlotRun>& runs, std::vector<uint8_t>& out) {
  out.clear();
  std::vector<SlotRun> joined;
  for (const SlotRun& r : runs) {
    if (r.length == 0) continue;
    if (!joined.empty() && joined.back().first + joined.back().length == r.first) {
      joined.back().length += r.length;
    } else {
      joined.push_back(r);
    }
  }
  put_varint(out, joined.size());
  uint64_t end = 0;
  for (const SlotRun& r : joined) {
    put_varint(out, r.first - end);
    put_varint(out, r.length);
    end = uint64_t(r.first) + r.length;
  }
}

bool decode_slot_runs(const uint8_t* data, size_t size, uint32_t slot_limit,
                      std::vector<SlotRun>& runs, std::string& error) {
  VarintReader r(data, size);
  uint64_t count = 0;
  runs.clear();
  if (!r.get(count) || count > r.remaining() / 2) {
    error = "slot list is truncated";
    return false;
  }
  uint64_t end = 0;
  for (uint64_t i = 0; i < count; ++i) {
    uint64_t gap, length;
    if (!r.get(gap) || !r.get(length)) {
      error = "slot list is truncated";
      return false;
    }
    if (length == 0 || gap > slot_limit || length > slot_limit || end + gap + length > slot_limit ||
        (i > 0 && gap == 0)) {
      error = "slot list has an impossible run";
      return false;
    }
    runs.push_back({uint32_t(end + gap), uint32_t(length)});
    end = end + gap + length;
  }
  if (!r.at_end()) {
    error = "trailing bytes after the slot list";
    return false;
  }
  return true;
}

bool decode_slot_runs(const uint8_t* data, size_t size, uint32_t slot_limit,
                      std::vector<uint32_t>& slots, std::string& error) {
  VarintReader r(data, size);
  uint64_t runs = 0;
  slots.clear();
  if (!r.get(runs) || runs > r.remaining() / 2) {
    error = "slot list is truncated";
    return false;
  }
  uint64_t end = 0;
  for (uint64_t i = 0; i < runs; ++i) {
    uint64_t gap, length;
    if (!r.get(gap) || !r.get(length)) {
      error = "slot list is truncated";
      return false;
    }
    // A run past the limit, or an empty or adjoining run (the encoder writes neither), is corrupt.
    // (Each term is checked on its own first: the sum of two corrupt varints could wrap around.)
    if (length == 0 || gap > slot_limit || length > slot_limit || end + gap + length > slot_limit ||
        (i > 0 && gap == 0)) {
      error = "slot list has an impossible run";
      return false;
    }
    const uint64_t first = end + gap;
    for (uint64_t s = first; s < first + length; ++s) slots.push_back(uint32_t(s));
    end = first + length;
  }
  if (!r.at_end()) {
    error = "trailing bytes after the slot list";
    return false;
  }
  return true;
}

}  // namespace plantview::detail
