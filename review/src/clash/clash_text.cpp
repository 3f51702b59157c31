// ClashText (plantview/clash.h): one allocation holding the count, the size and the characters.
#include <atomic>
#include <cstring>
#include <new>
#include <ostream>

#include "plantview/clash.h"

namespace plantview {

// The characters (size + 1 with the terminator) follow the block in its allocation.
struct ClashText::Block {
  std::atomic<uint32_t> references{1};
  uint32_t size = 0;
  char* text() { return reinterpret_cast<char*>(this + 1); }
};

ClashText::ClashText(std::string_view text) {
  if (text.empty()) return;
  void* memory = ::operator new(sizeof(Block) + text.size() + 1);
  block_ = new (memory) Block;
  block_->size = uint32_t(text.size());
  std::memcpy(block_->text(), text.data(), text.size());
  block_->text()[text.size()] = '\0';
}

ClashText::ClashText(const ClashText& other) noexcept : block_(other.block_) {
  if (block_) block_->references.fetch_add(1, std::memory_order_relaxed);
}

ClashText::~ClashText() {
  if (block_ && block_->references.fetch_sub(1, std::memory_order_acq_rel) == 1) {
    block_->~Block();
    ::operator delete(block_);
  }
}

std::string_view ClashText::view() const {
  return block_ ? std::string_view(block_->text(), block_->size) : std::string_view();
}

const char* ClashText::c_str() const { return block_ ? block_->text() : ""; }

std::ostream& operator<<(std::ostream& out, const ClashText& text) { return out << text.view(); }

}  // namespace plantview
