// Internal: the id and name tables and the per-source slot lists, before compression.
//
// Key/slot table (indexes/"ids", indexes/"names"): pairs sorted by key, then slot:
//   varint count | varint key - previous key (first: the key) ... | varint slot ...
// Keys first, then slots, so that each kind of number sits with its own kind (zstd does better).
// Slot runs (sources/<path>): the sorted slots as runs of consecutive numbers:
//   varint runs | (varint first - end of the previous run, varint length)...
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "varint.h"

namespace plantview::detail {

struct KeySlot {
  uint64_t key;
  uint32_t slot;
  friend bool operator<(const KeySlot& a, const KeySlot& b) {
    return a.key != b.key ? a.key < b.key : a.slot < b.slot;
  }
};

// `table` sorted (operator<).
void encode_key_slots(const std::vector<KeySlot>& table, std::vector<uint8_t>& out);
// False with a message if the bytes are malformed or out of order.
bool decode_key_slots(const uint8_t* data, size_t size, std::vector<KeySlot>& table,
                      std::string& error);

// Reads a key/slot table where it lies, pair by pair, so that a reader keeps only what it needs
// of it (never the 16-byte pairs). Messages are those of decode_key_slots. Allocates nothing.
class KeySlotReader {
 public:
  // Checks the count and the key column; `data` must outlive the reader. False with a message.
  bool open(const uint8_t* data, size_t size, std::string& error);
  uint64_t size() const { return count_; }
  // The next pair in table order. Call it size() times, then finish(). False with a message if
  // the slot column is malformed or the pair is out of order.
  bool next(KeySlot& pair, std::string& error);
  // False with a message unless the table ended exactly at the end of the bytes.
  bool finish(std::string& error) const;

 private:
  VarintReader keys_{nullptr, 0}, slots_{nullptr, 0};
  uint64_t count_ = 0, read_ = 0;
  KeySlot previous_{};
};

// A run of consecutive slots [first, first + length).
struct SlotRun {
  uint32_t first, length;
};
// `runs` ascending, not overlapping (adjoining runs are joined).
void encode_slot_runs(const std::vector<SlotRun>& runs, std::vector<uint8_t>& out);
// The list as runs: memory follows the runs, not the slots (an import keeps a source's slots so).
bool decode_slot_runs(const uint8_t* data, size_t size, uint32_t slot_limit,
                      std::vector<SlotRun>& runs, std::string& error);

// `slots` sorted ascending, without duplicates.
void encode_slot_runs(const std::vector<uint32_t>& slots, std::vector<uint8_t>& out);
// Every slot must be below `slot_limit` (the store's next slot), which also bounds the memory a
// corrupt list can ask for.
bool decode_slot_runs(const uint8_t* data, size_t size, uint32_t slot_limit,
                      std::vector<uint32_t>& slots, std::string& error);

}  // namespace plantview::detail
