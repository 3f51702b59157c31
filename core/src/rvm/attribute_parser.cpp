// The attribute-file parser: the header line declares the keywords, then one pass over the lines
// with an explicit stack of open blocks. Contract and grammar: plantview/rvm.h.
#include <algorithm>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "plantview/rvm.h"

namespace plantview {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim_left(std::string_view s) {
  size_t i = 0;
  while (i < s.size() && is_blank(s[i])) ++i;
  return s.substr(i);
}

std::string_view trim(std::string_view s) {
  s = trim_left(s);
  size_t n = s.size();
  while (n > 0 && is_blank(s[n - 1])) --n;
  return s.substr(0, n);
}

// Finds a keyword the file's header declared (name_end, sep) in time linear in the text searched
// plus the keyword (Knuth-Morris-Pratt). The header may declare keywords megabytes long, and a
// naive search (std::string_view::find) costs their length at every position it tries.
class KeywordSearch {
 public:
  // O(keyword.size()) time and memory.
  void assign(std::string_view keyword) {
    keyword_ = keyword;
    border_.assign(keyword_.size(), 0);
    for (size_t i = 1, k = 0; i < keyword_.size(); ++i) {
      while (k > 0 && keyword_[i] != keyword_[k]) k = border_[k - 1];
      if (keyword_[i] == keyword_[k]) ++k;
      border_[i] = k;
    }
  }
  size_t size() const { return keyword_.size(); }
  // The length of the longest prefix of the keyword ending with `c` after a match of `state`
  // characters.
  size_t advance(size_t state, char c) const {
    if (state == keyword_.size()) state = border_[state - 1];
    while (state > 0 && keyword_[state] != c) state = border_[state - 1];
    return keyword_[state] == c ? state + 1 : 0;
  }
  // The first occurrence at or after `from`, npos when none (nor for an empty keyword). Reads
  // text only up to the end of the occurrence found.
  size_t find(std::string_view text, size_t from = 0) const {
    if (keyword_.empty()) return std::string_view::npos;
    for (size_t i = from, state = 0; i < text.size(); ++i) {
      state = advance(state, text[i]);
      if (state == keyword_.size()) return i + 1 - keyword_.size();
    }
    return std::string_view::npos;
  }
  std::string_view keyword() const { return keyword_; }

 private:
  std::string keyword_;
  std::vector<size_t> border_;  // border_[i]: longest proper border of keyword_[0, i]
};

// Whether the keyword starts at given positions of one text, asked in nondecreasing order: one
// pass over the text for all the questions together.
class KeywordStarts {
 public:
  KeywordStarts(const KeywordSearch& search, std::string_view text)
      : search_(search), text_(text) {}
  bool at(size_t p) {
    const size_t m = search_.size();
    if (m == 0 || p + m > text_.size()) return false;
    if (read_ > p + m) return text_.substr(p, m) == search_.keyword();  // asked out of order
    for (; read_ < p + m; ++read_) state_ = search_.advance(state_, text_[read_]);
    return state_ == m;
  }

 private:
  const KeywordSearch& search_;
  std::string_view text_;
  size_t read_ = 0;   // characters of text_ read
  size_t state_ = 0;  // matched prefix of the keyword ending at read_
};

class AttributeParser {
 public:
  AttributeParser(std::string_view text, std::string_view source) : text_(text), source_(source) {}
  ParseResult<AttributeFile> run();

 private:
  // Stages. Each returns false after recording the error.
  bool next_line(std::string_view& line);
  bool parse_header(std::string_view line);
  bool open_block(std::string_view name);
  bool close_block();
  bool parse_attribute_line(std::string_view line);

  bool fail(uint32_t line, uint64_t offset, const std::string& what);
  size_t find_next(char c, size_t& cached) const;

  static constexpr size_t kUnknown = ~size_t{0};

  std::string_view text_;
  std::string_view source_;
  size_t pos_ = 0;          // start of the next line
  size_t line_start_ = 0;   // byte offset of the current line
  uint32_t line_ = 0;       // 1-based number of the current line
  size_t next_lf_ = kUnknown, next_cr_ = kUnknown;  // cached line-end searches, see find_next
  std::optional<ParseError> error_;
  AttributeFile file_;
  std::vector<AttributeBlock> open_;  // blocks opened and not yet closed, outermost first
  KeywordSearch name_end_, separator_;  // the header's keywords
};

bool AttributeParser::fail(uint32_t line, uint64_t offset, const std::string& what) {
  error_ = ParseError{std::string(source_) + ":" + std::to_string(line) + ": " + what, offset, line};
  return false;
}

// The offset of the next `c` at or after pos_ (text size when none). Each search resumes where the
// last one found its character, so finding every line end costs one pass over the text.
size_t AttributeParser::find_next(char c, size_t& cached) const {
  if (cached == kUnknown || cached < pos_) {
    const void* hit = std::memchr(text_.data() + pos_, c, text_.size() - pos_);
    cached = hit ? static_cast<size_t>(static_cast<const char*>(hit) - text_.data()) : text_.size();
  }
  return cached;
}

// The next line without its terminator (LF, CR LF or CR); false at the end of the text.
bool AttributeParser::next_line(std::string_view& line) {
  if (pos_ >= text_.size()) return false;
  const char* begin = text_.data() + pos_;
  const char* end = text_.data() + text_.size();
  const char* p = text_.data() + std::min(find_next('\n', next_lf_), find_next('\r', next_cr_));
  line = std::string_view(begin, static_cast<size_t>(p - begin));
  if (p < end && *p == '\r') ++p;
  if (p < end && *p == '\n') ++p;
  line_start_ = pos_;
  pos_ = static_cast<size_t>(p - text_.data());
  ++line_;
  return true;
}

// "CADC_Attributes_File v1.0 , start: NEW , end: END , name_end: := , sep: &end&"
bool AttributeParser::parse_header(std::string_view line) {
  bool has_start = false, has_end = false, has_name_end = false;
  AttributeKeywords& k = file_.keywords;
  k.separator.clear();
  for (size_t field = 0; !line.empty() || field == 0; ++field) {
    const size_t comma = line.find(',');
    const std::string_view part = trim(line.substr(0, comma));
    line = comma == std::string_view::npos ? std::string_view() : line.substr(comma + 1);
    const size_t colon = part.find(':');
    if (colon == std::string_view::npos) {
      if (field == 0) file_.format = std::string(part);
      continue;
    }
    const std::string_view key = trim(part.substr(0, colon));
    const std::string_view value = trim(part.substr(colon + 1));
    if (value.empty()) continue;
    if (key == "start") {
      k.start = value;
      has_start = true;
    } else if (key == "end") {
      k.end = value;
      has_end = true;
    } else if (key == "name_end") {
      k.name_end = value;
      has_name_end = true;
    } else if (key == "sep") {
      k.separator = value;
    }
  }
  if (!has_start || !has_end || !has_name_end) {
    return fail(1, 0, std::string("expected the attribute file header declaring start, end and "
                                  "name_end keywords; missing ") +
                          (!has_start ? "start" : !has_end ? "end" : "name_end"));
  }
  name_end_.assign(k.name_end);
  separator_.assign(k.separator);
  return true;
}

bool AttributeParser::open_block(std::string_view name) {
  if (name.empty()) return fail(line_, line_start_, "'" + file_.keywords.start + "' without a name");
  if (open_.size() >= kMaxAttributeDepth) {
    return fail(line_, line_start_,
                "blocks nest deeper than " + std::to_string(kMaxAttributeDepth));
  }
  AttributeBlock& block = open_.emplace_back();
  block.name = name;
  block.line = line_;
  return true;
}

bool AttributeParser::close_block() {
  if (open_.empty()) {
    return fail(line_, line_start_, "'" + file_.keywords.end + "' without an open block");
  }
  AttributeBlock block = std::move(open_.back());
  open_.pop_back();
  (open_.empty() ? file_.blocks : open_.back().children).push_back(std::move(block));
  return true;
}

// The first quote at or after `from` that can close a quoted value: one followed, after blanks,
// by the separator or the end of the line; npos when there is none. The answer for a later `from`
// is never earlier, which lets a caller reuse it along the line. `separator_at` answers for the
// line: the quotes tried move forward, over one line and across calls.
size_t closing_quote(std::string_view line, size_t from, KeywordStarts& separator_at) {
  for (size_t q = line.find('\'', from); q != std::string_view::npos; q = line.find('\'', q + 1)) {
    const std::string_view after = trim_left(line.substr(q + 1));
    if (after.empty() || separator_at.at(line.size() - after.size())) return q;
  }
  return std::string_view::npos;
}

// key := value [sep key := value]...
bool AttributeParser::parse_attribute_line(std::string_view line) {
  if (open_.empty()) return fail(line_, line_start_, "attribute line outside a block");
  const AttributeKeywords& k = file_.keywords;
  // closing_quote's last answer, reused while it lies ahead, so that a line costs one pass.
  size_t close = std::string_view::npos;
  bool close_known = false;
  KeywordStarts separator_at(separator_, line);
  std::string_view rest = line;
  while (!rest.empty()) {
    const size_t assign = name_end_.find(rest);
    const uint64_t at = static_cast<uint64_t>(rest.data() - text_.data());
    if (assign == std::string_view::npos) {
      return fail(line_, at, "expected '" + k.name_end + "' after an attribute name");
    }
    const std::string_view key = trim(rest.substr(0, assign));
    if (key.empty()) return fail(line_, at, "attribute without a name");
    rest = trim_left(rest.substr(assign + k.name_end.size()));

    // A quoted value ends at the first quote followed by the separator or the end of the line.
    std::string_view value;
    bool quoted = false;
    if (!rest.empty() && rest[0] == '\'') {
      const size_t open = static_cast<size_t>(rest.data() - line.data());
      if (!close_known || (close != std::string_view::npos && close <= open)) {
        close = closing_quote(line, open + 1, separator_at);
        close_known = true;
      }
      if (close != std::string_view::npos) {
        value = line.substr(open + 1, close - open - 1);
        rest = trim_left(line.substr(close + 1));
        quoted = true;
      }
    }
    if (!quoted) {
      const size_t sep = separator_.find(rest);
      value = trim(rest.substr(0, sep));
      rest = sep == std::string_view::npos ? std::string_view() : rest.substr(sep);
    }
    open_.back().attributes.emplace_back(key, value);
    if (!rest.empty()) rest = trim_left(rest.substr(k.separator.size()));  // past the separator
  }
  return true;
}

ParseResult<AttributeFile> AttributeParser::run() {
  // Stage 1: an optional byte order mark, then the header that declares the keywords.
  if (text_.starts_with("\xEF\xBB\xBF")) pos_ = 3;
  std::string_view line;
  if (!next_line(line)) {
    fail(1, 0, "empty text: expected the attribute file header");
    return *error_;
  }
  if (!parse_header(line)) return *error_;
  const AttributeKeywords& k = file_.keywords;

  // Stage 2: blocks and their attribute lines.
  while (next_line(line)) {
    line = trim(line);
    if (line.empty()) continue;
    bool ok = true;
    if (line == k.end) {
      ok = close_block();
    } else if (line.starts_with(k.start) &&
               (line.size() == k.start.size() || is_blank(line[k.start.size()]))) {
      ok = open_block(trim(line.substr(k.start.size())));
    } else {
      ok = parse_attribute_line(line);
    }
    if (!ok) return *error_;
  }

  // Stage 3: every block must be closed.
  if (!open_.empty()) {
    const AttributeBlock& block = open_.back();
    fail(block.line, text_.size(),
         "block \"" + block.name + "\" is not closed: the text ends (at line " +
             std::to_string(line_) + ") before its '" + k.end + "'");
    return *error_;
  }
  return std::move(file_);
}

}  // namespace

const std::string* AttributeBlock::find(std::string_view key) const {
  for (const auto& [attribute, value] : attributes) {
    if (attribute == key) return &value;
  }
  return nullptr;
}

ParseResult<AttributeFile> parse_attributes(std::string_view text, std::string_view source_name) {
  return AttributeParser(text, source_name).run();
}

AttributeIndex index_attribute_blocks(const AttributeFile& file) {
  AttributeIndex index;
  std::vector<const AttributeBlock*> pending;
  for (auto it = file.blocks.rbegin(); it != file.blocks.rend(); ++it) pending.push_back(&*it);
  while (!pending.empty()) {  // depth first, in file order
    const AttributeBlock* block = pending.back();
    pending.pop_back();
    index.try_emplace(block->name, block);
    for (auto it = block->children.rbegin(); it != block->children.rend(); ++it) {
      pending.push_back(&*it);
    }
  }
  return index;
}

}  // namespace plantview
