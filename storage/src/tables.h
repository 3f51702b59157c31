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

// `slots` sorted ascending, without duplicates.
void encode_slot_runs(const std::vector<uint32_t>& slots, std::vector<uint8_t>& out);
// Every slot must be below `slot_limit` (the store's next slot), which also bounds the memory a
// corrupt list can ask for.
bool decode_slot_runs(const uint8_t* data, size_t size, uint32_t slot_limit,
                      std::vector<uint32_t>& slots, std::string& error);

}  // namespace plantview::detail
