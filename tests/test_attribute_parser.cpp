// Attribute-file parser (plantview/rvm.h): the Huldra sample and its match with the RVM groups, a
// small file with every rule, every truncation of it, and errors that name their line.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>

#include "plantview/rvm.h"
#include "support/rvm_writer.h"

namespace plantview::testing {
namespace {

constexpr const char* kSource = "test.txt";

bool contains(const std::string& text, std::string_view part) {
  return text.find(part) != std::string::npos;
}

// Every rule at least once: BOM, CR LF, a blank line, tabs, quoted and bare values, a separator
// inside quotes, a quote inside a value, non-UTF-8 bytes, an empty value, keys with blanks,
// nesting, and no newline at the end.
const std::string kHeader =
    "\xEF\xBB\xBF" "CADC_Attributes_File v1.0 , start: NEW , end: END , name_end: := , sep: &end&\n";
const std::string kSmall = kHeader +
    "NEW Header Information\n"
    "  Source:= PDMS Data &end& Date:= 28 Dec 2020  &end& Time:= 4:55 PM\n"
    "END\n"
    "NEW /PIPE-100\r\n"
    "  Name:= '/PIPE-100' &end& Type:= 'PIPE'\r\n"
    "\n"
    "  Description:= 'Caf\xE9 \xFF line'\n"
    "  Note:= 'a &end& b'  &end& Quote:= 'it's'\n"
    "\tNEW /PIPE-100/B1\n"
    "\t  Type:= 'BRAN'\n"
    "\t  Empty:=\n"
    "\t  Derived length (mm):= 390\n"
    "\tEND\n"
    "END\n"
    "NEW /EQUI-1\n"
    "  Type:= EQUI\n"
    "END";

using Attributes = std::vector<std::pair<std::string, std::string>>;

TEST(AttributeParser, SmallFileParsesEveryRule) {
  maybe_write_fuzz_seed("small.txt", std::as_bytes(std::span(kSmall)));
  const auto parsed = parse_attributes(kSmall, kSource);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const AttributeFile& file = parsed.value();
  EXPECT_EQ(file.format, "CADC_Attributes_File v1.0");
  EXPECT_EQ(file.keywords.start, "NEW");
  EXPECT_EQ(file.keywords.end, "END");
  EXPECT_EQ(file.keywords.name_end, ":=");
  EXPECT_EQ(file.keywords.separator, "&end&");
  ASSERT_EQ(file.blocks.size(), 3u);

  const AttributeBlock& header = file.blocks[0];
  EXPECT_EQ(header.name, "Header Information");
  EXPECT_EQ(header.line, 2u);
  EXPECT_EQ(header.attributes,
            (Attributes{{"Source", "PDMS Data"}, {"Date", "28 Dec 2020"}, {"Time", "4:55 PM"}}));

  const AttributeBlock& pipe = file.blocks[1];
  EXPECT_EQ(pipe.name, "/PIPE-100");
  EXPECT_EQ(pipe.line, 5u);
  EXPECT_EQ(pipe.attributes, (Attributes{{"Name", "/PIPE-100"},
                                         {"Type", "PIPE"},
                                         {"Description", "Caf\xE9 \xFF line"},
                                         {"Note", "a &end& b"},
                                         {"Quote", "it's"}}));
  ASSERT_EQ(pipe.children.size(), 1u);
  const AttributeBlock& branch = pipe.children[0];
  EXPECT_EQ(branch.name, "/PIPE-100/B1");
  EXPECT_EQ(branch.line, 10u);
  EXPECT_EQ(branch.attributes,
            (Attributes{{"Type", "BRAN"}, {"Empty", ""}, {"Derived length (mm)", "390"}}));
  ASSERT_NE(branch.find("Derived length (mm)"), nullptr);
  EXPECT_EQ(*branch.find("Derived length (mm)"), "390");
  EXPECT_EQ(branch.find("Name"), nullptr);

  EXPECT_EQ(file.blocks[2].name, "/EQUI-1");
  EXPECT_EQ(file.blocks[2].line, 16u);
  EXPECT_EQ(file.blocks[2].attributes, (Attributes{{"Type", "EQUI"}}));

  const AttributeIndex index = index_attribute_blocks(file);
  EXPECT_EQ(index.size(), 4u);
  ASSERT_TRUE(index.contains("/PIPE-100/B1"));
  EXPECT_EQ(index.at("/PIPE-100/B1"), &branch);
}

// A prefix is a valid file exactly when it ends (blanks aside) after the header or after a
// top-level END; any other cut leaves a block open (or a partial line) and must name a line.
TEST(AttributeParser, EveryTruncationParsesOrFailsNamingALine) {
  const std::string_view full = kSmall;
  for (size_t n = 0; n < full.size(); ++n) {
    const std::string_view prefix = full.substr(0, n);
    const auto parsed = parse_attributes(prefix, kSource);
    if (n < kHeader.size() - 1) {  // inside the header: incomplete keywords must fail on line 1
      if (!parsed) {
        EXPECT_EQ(parsed.error().line, 1u) << parsed.error().message;
      }
      continue;
    }
    std::string_view trimmed = prefix;
    while (!trimmed.empty() && std::string_view(" \t\r\n").find(trimmed.back()) != std::string_view::npos) {
      trimmed.remove_suffix(1);
    }
    const bool complete = trimmed.size() == kHeader.size() - 1 || trimmed.ends_with("\nEND");
    ASSERT_EQ(parsed.ok(), complete) << "prefix of " << n << " bytes: "
                                     << (parsed ? "parsed" : parsed.error().message);
    if (parsed) {
      size_t top_level_ends = 0;
      for (size_t at = trimmed.find("\nEND"); at != std::string_view::npos;
           at = trimmed.find("\nEND", at + 1)) {
        ++top_level_ends;
      }
      EXPECT_EQ(parsed.value().blocks.size(), top_level_ends) << n;
    } else {
      const ParseError& e = parsed.error();
      EXPECT_GE(e.line, 2u) << e.message;
      EXPECT_TRUE(e.message.starts_with("test.txt:" + std::to_string(e.line) + ": ")) << e.message;
      EXPECT_LE(e.offset, n);
    }
  }
}

TEST(AttributeParser, ErrorsNameTheirLine) {
  struct Case {
    std::string body;      // after the header (line 1)
    uint32_t line;
    const char* expected;
  };
  const std::vector<Case> cases = {
      {"END\n", 2, "'END' without an open block"},
      {"Type:= 'PIPE'\n", 2, "attribute line outside a block"},
      {"NEW /A\n  Type 'PIPE'\nEND\n", 3, "expected ':=' after an attribute name"},
      {"NEW /A\n  Type:= 'PIPE' &end& Bad\nEND\n", 3, "expected ':='"},
      {"NEW /A\n  := 'PIPE'\nEND\n", 3, "attribute without a name"},
      {"NEW /A\nNEW\nEND\nEND\n", 3, "'NEW' without a name"},
      {"NEW /A\n  NEW /A/B\n    X:= 1\n  END\n", 2, "block \"/A\" is not closed"},
      {"NEW /A\n  NEW /A/B\n    X:= 1\n", 3, "block \"/A/B\" is not closed: the text ends (at line 4)"},
      {"NEW /A\nEND\nEND\n", 4, "'END' without an open block"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.body);
    const auto parsed = parse_attributes(kHeader + c.body, kSource);
    ASSERT_FALSE(parsed);
    EXPECT_EQ(parsed.error().line, c.line) << parsed.error().message;
    EXPECT_TRUE(parsed.error().message.starts_with("test.txt:" + std::to_string(c.line) + ": "))
        << parsed.error().message;
    EXPECT_TRUE(contains(parsed.error().message, c.expected)) << parsed.error().message;
  }
}

TEST(AttributeParser, HeaderMustDeclareTheKeywords) {
  for (const std::string& text :
       {std::string(), std::string("\xEF\xBB\xBF"), std::string("NEW /A\nEND\n"),
        std::string("CADC_Attributes_File v1.0 , start: NEW , end: END\nNEW /A\nEND\n"),
        std::string("CADC_Attributes_File v1.0 , start: NEW , end: , name_end: :=\n")}) {
    const auto parsed = parse_attributes(text, kSource);
    ASSERT_FALSE(parsed) << text;
    EXPECT_EQ(parsed.error().line, 1u);
    EXPECT_TRUE(parsed.error().message.starts_with("test.txt:1: ")) << parsed.error().message;
  }
}

TEST(AttributeParser, DeclaredKeywordsAreUsed) {
  const std::string text =
      "MyFormat 2 , start: BEGIN , end: FINISH , name_end: = , sep: ;;\r"  // CR-only lines
      "BEGIN one\r"
      "  a = 1 ;; b = '2;;3' ;; c=4\r"
      "  NEW = not a block\r"
      "FINISH\r";
  const auto parsed = parse_attributes(text, kSource);
  ASSERT_TRUE(parsed) << parsed.error().message;
  ASSERT_EQ(parsed.value().blocks.size(), 1u);
  EXPECT_EQ(parsed.value().format, "MyFormat 2");
  EXPECT_EQ(parsed.value().blocks[0].attributes,
            (Attributes{{"a", "1"}, {"b", "2;;3"}, {"c", "4"}, {"NEW", "not a block"}}));

  const std::string no_separator =
      "F , start: NEW , end: END , name_end: :=\nNEW x\n  k:= a &end& b\nEND\n";
  const auto plain = parse_attributes(no_separator, kSource);
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_EQ(plain.value().keywords.separator, "");
  EXPECT_EQ(plain.value().blocks[0].attributes, (Attributes{{"k", "a &end& b"}}));
}

TEST(AttributeParser, NestingIsLimited) {
  for (const uint32_t depth : {kMaxAttributeDepth, kMaxAttributeDepth + 1}) {
    std::string text = kHeader;
    for (uint32_t i = 0; i < depth; ++i) text += "NEW b" + std::to_string(i) + "\n";
    for (uint32_t i = 0; i < depth; ++i) text += "END\n";
    const auto parsed = parse_attributes(text, kSource);
    if (depth == kMaxAttributeDepth) {
      ASSERT_TRUE(parsed) << parsed.error().message;
      EXPECT_EQ(index_attribute_blocks(parsed.value()).size(), depth);
    } else {
      ASSERT_FALSE(parsed);
      EXPECT_EQ(parsed.error().line, depth + 1);
      EXPECT_TRUE(contains(parsed.error().message, "nest deeper than"));
    }
  }
}

TEST(AttributeParser, IndexKeepsTheFirstOfRepeatedNames) {
  const auto parsed = parse_attributes(
      kHeader + "NEW A\n  n:= 1\n  NEW A\n    n:= 2\n  END\nEND\nNEW A\n  n:= 3\nEND\n", kSource);
  ASSERT_TRUE(parsed) << parsed.error().message;
  const AttributeIndex index = index_attribute_blocks(parsed.value());
  ASSERT_EQ(index.size(), 1u);
  EXPECT_EQ(*index.at("A")->find("n"), "1");
}

// The header may declare keywords megabytes long; finding them stays linear in the text (a
// naive search took 4 minutes here for one 4 MB keyword over an 8 MB line: at every position it
// compared most of the keyword).
TEST(AttributeParser, MultiMegabyteKeywordsParseInLinearTime) {
  const size_t m = size_t(4) << 20;
  const std::string a(m, 'a');
  std::string pairs;  // "a'" m / 2 times: every quote in it followed by most of the separator
  for (size_t i = 0; i < m / 2; ++i) pairs += "a'";
  struct Case {
    std::string name, text;
    Attributes expected;
  } cases[] = {
      // name_end = a..ab: at every 'a' of the line a near match.
      {"name_end", "F , start: NEW , end: END , name_end: " + a + "b\nNEW x\n" + a + a + "b v\nEND\n",
       {{a, "v"}}},
      // sep = a..ab, an unquoted value of a's before it.
      {"sep", "F , start: NEW , end: END , name_end: := , sep: " + a + "b\nNEW x\nk := " + a + a +
                  "b j := 2\nEND\n",
       {{"k", a}, {"j", "2"}}},
      // sep = a'a'..a'b, a quoted value of a'a'..: every quote a candidate for closing it.
      {"sep after quotes", "F , start: NEW , end: END , name_end: := , sep: " + pairs.substr(0, m / 2) +
                               "b\nNEW x\nk := '" + pairs + pairs.substr(0, m / 2) + "b x := 1\nEND\n",
       // The separator's only occurrence follows the last quote of the first `pairs`.
       {{"k", pairs.substr(0, pairs.size() - 1)}, {"x", "1"}}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const auto start = std::chrono::steady_clock::now();
    const auto parsed = parse_attributes(c.text, kSource);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(parsed) << parsed.error().message;
    ASSERT_EQ(parsed.value().blocks.size(), 1u);
    EXPECT_TRUE(parsed.value().blocks[0].attributes == c.expected);
    EXPECT_LT(seconds, 5.0) << c.text.size() << " bytes";
  }
}

// ---------------------------------------------------------------------------------------------
// The Huldra sample (../shared/data/huldra): the attribute file of WD1-PSUP.RVM.

const std::filesystem::path kHuldra = std::filesystem::path(PLANTVIEW_SHARED_DIR) / "data/huldra";

TEST(AttributeParserHuldra, SampleParsesAndItsBlocksMatchTheRvmGroups) {
  if (!std::filesystem::exists(kHuldra / "WD1-PSUP.txt")) GTEST_SKIP() << "no sample in " << kHuldra;
  const auto bytes = load_file(kHuldra / "WD1-PSUP.txt");
  ASSERT_TRUE(bytes) << bytes.error().message;
  const std::string_view text(reinterpret_cast<const char*>(bytes.value().data()),
                              bytes.value().size());
  const auto start = std::chrono::steady_clock::now();
  const auto parsed = parse_attributes(text, "WD1-PSUP.txt");
  const auto stop = std::chrono::steady_clock::now();
  ASSERT_TRUE(parsed) << parsed.error().message;
  std::printf("WD1-PSUP.txt (%zu bytes): parsed in %.2f ms\n", text.size(),
              std::chrono::duration<double, std::milli>(stop - start).count());
  const AttributeFile& file = parsed.value();
  ASSERT_EQ(file.blocks.size(), 2u);
  EXPECT_EQ(file.blocks[0].name, "Header Information");
  EXPECT_EQ(file.blocks[0].attributes,
            (Attributes{{"Source", "PDMS Data"}, {"Date", "28 Dec 2020"}, {"Time", "4:55 PM"},
                        {"Project", "ABC"}, {"MDB", "/XYZ"}, {"Element", "/WD1-PSUP"}}));
  const AttributeIndex index = index_attribute_blocks(file);
  EXPECT_EQ(index.size(), 8150u);

  const auto attribute = [&](std::string_view block, std::string_view key) -> std::string {
    const auto it = index.find(block);
    if (it == index.end()) return "<no block>";
    const std::string* value = it->second->find(key);
    return value ? *value : "<no attribute>";
  };
  EXPECT_EQ(attribute("/WD1-PSUP", "Type"), "SITE");
  EXPECT_EQ(attribute("/WD1-PSUP", "RefNo"), "=16821/2");
  EXPECT_EQ(attribute("/WD1-PSUP", "NumbDb"), "437");
  EXPECT_EQ(attribute("/PS/WD1/0001", "Type"), "ZONE");
  EXPECT_EQ(attribute("/PS/WD1/0001", "Position"), "E 90000mm N 290000mm U 0mm");
  EXPECT_EQ(attribute("/PS/WD1/0001/F1", "Description"), "HO-WF-712011");
  EXPECT_EQ(attribute("DRAWING 1 of STRUCTURE /PS/WD1/0001/F1", "Type"), "DRAW");
  EXPECT_EQ(attribute("DRAWING 1 of STRUCTURE /PS/WD1/0001/F1", "LevelTo"), "10");

  // Every RVM group has a block of its name, and its child groups are among the block's children.
  const auto rvm_bytes = load_file(kHuldra / "WD1-PSUP.RVM");
  ASSERT_TRUE(rvm_bytes) << rvm_bytes.error().message;
  RvmParseOptions options;
  options.triangulate_facet_groups = false;
  const auto rvm = parse_rvm(rvm_bytes.value(), "WD1-PSUP.RVM", options);
  ASSERT_TRUE(rvm) << rvm.error().message;
  size_t groups = 0, found = 0, children_matched = 0;
  std::function<void(const RvmGroup&)> walk = [&](const RvmGroup& group) {
    ++groups;
    const auto it = index.find(group.name);
    if (it != index.end()) {
      ++found;
      for (const RvmGroup& child : group.children) {
        for (const AttributeBlock& block_child : it->second->children) {
          if (block_child.name == child.name) {
            ++children_matched;
            break;
          }
        }
      }
    }
    for (const RvmGroup& child : group.children) walk(child);
  };
  for (const RvmGroup& root : rvm.value().roots) walk(root);
  EXPECT_EQ(groups, 4084u);
  EXPECT_EQ(found, groups);
  EXPECT_EQ(children_matched, groups - rvm.value().roots.size());
}

}  // namespace
}  // namespace plantview::testing
