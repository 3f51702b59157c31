// plantview/ingest.h: putting plant models into a store. The one import and generate pipeline that
// the plantview program, the benchmarks and the tests share.
//
// What goes in
//   - Files (ingest_files): RVM review models (.rvm) with their attribute files (.txt/.att), and
//     plantview XML (.xml). An RVM's attribute file is the one given among the files with the
//     same stem, else a .txt, .TXT, .att or .ATT beside the RVM under the same name, else none
//     (every group then becomes an object of class other; rvm_import.h). plan_import() sorts the
//     names first, without touching the disk, so that a caller can refuse bad arguments before
//     it opens a store.
//   - A generated plant (ingest_generated): generate_plant()'s preset, scale and seed
//     (generate.h); the objects' source is "gen:<preset>".
//   - Objects already in memory (ingest_objects): tests and tools that build their own; their
//     sources are their `source` fields.
//
// Transactions and sources
//   - Every call is one store transaction (store.h, Import): nothing is visible until it
//     commits, and a bad file, an error, a cancellation or a killed process leaves the store
//     exactly as it was. One call per store at a time (store.h: one Import per store; LMDB
//     serialises writers, across processes too).
//   - Every input is a source: a file's is its canonical path (as weakly_canonical gives it; the
//     path as given if that fails), a generated plant's "gen:<preset>". What a source brought
//     before is removed in the same transaction before its objects go in, so importing a file
//     (or generating a preset) again replaces it rather than adding to it.
//
// Progress and cancellation (IngestControl)
//   - `progress` is called on the calling thread, between pieces of work, never after the call
//     returns. Reports come in order: file_index never decreases, within a file the stages
//     come in the order of IngestStage, and within a stage `done` never decreases. Units of
//     done/total per stage are listed at IngestStage. It may be called often (every object
//     stored): keep it cheap, or throttle. An exception it throws abandons the transaction (the
//     store stays as it was) and propagates.
//   - `stop`: a stop may be requested from any thread. The call checks it before it starts,
//     between files and stages, before each object it stores, between 1 MB blocks of XML and
//     at each of the generator's progress steps (at least one per 64 pipelines routed); then it
//     abandons the transaction and returns the error "cancelled" (kind cancelled). A single
//     stage that is one call into core (parsing one RVM file) is not interrupted. Once the
//     commit has started the token is no longer checked: the call commits or fails as a whole.
//
// Errors
//   A failed call returns an IngestError; the store is unchanged. Input errors name the file and
//   where in it (byte offset for RVM, line for attribute and XML files), as the parsers
//   (rvm.h, xml.h) word them, e.g.
//     "WD1-PSUP.RVM: offset 652 (0x28c): PRIM chunk at offset 524 (0x20c): unknown primitive kind 12"
//   Store errors are the store's messages (they name the store directory and the operation).
//   Arguments that break a rule stated here (a scale out of range, an unknown preset) are caller
//   bugs and assert; check them with parse_preset() and kMaxGenerateScale.
//
// Memory, besides the transaction's own (the store's):
//   - An RVM file is held whole while it is converted: its bytes until parsed, then its parse,
//     its attribute file (parsed and indexed by name) and the objects made of them (a few times
//     the files' size: Huldra's 3.6 MB take 15 MB at peak). The conversion needs the whole
//     parse (an object is a group's subtree, its attributes are looked up by name, a pipeline is
//     its PIPE group's subtree), so this grows with the largest file, not with the plant. The
//     parse and the attributes are dropped before the objects are stored, and each object once
//     it is stored.
//   - XML is read in 1 MB blocks and stored object by object.
//   - A generated plant holds one plant unit's layout at a time (generate.h) and batches of
//     1024 objects between the generator and the store: 4 waiting at most, one being filled,
//     one being stored (a few MB).
//   Nothing is kept per object of the plant: the summary holds counts.
//
// Threads: any thread may call; the progress and file_done callbacks run on the calling thread.
// A generated plant is generated on a thread of its own, one batch ahead of the calling thread,
// which stores it (unless import_threads() is 1, store.h); the store's compression threads work
// beside them. The objects are stored in the order generated: the store is the same, byte for
// byte, whatever the thread count.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <stop_token>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "plantview/generate.h"
#include "plantview/model.h"
#include "plantview/store.h"

namespace plantview {

// ---------------------------------------------------------------------------------------------
// Progress, cancellation, results.

// The stages of a call, in the order they are reported, with the unit of done/total.
enum class IngestStage : uint8_t {
  parsing,      // RVM: loading and parsing the file and then its attribute file; bytes of both
                // together (0 before, the RVM's size after it, the total after the attributes)
  classifying,  // RVM: turning groups into objects; the file's groups (0 before, all after)
  storing,      // RVM, objects in memory: putting objects into the transaction; objects
  reading,      // XML: reading the file and storing its objects as they come; bytes of the file
  generating,   // generated plant: thousandths of a plant unit (total = 1000 x scale)
  committing,   // every call, last: rebuilding the indexes and committing; 0 of 1, then 1 of 1
};
// "parsing", "classifying", ... as spelt above.
std::string_view stage_name(IngestStage stage);

struct IngestProgress {
  IngestStage stage = IngestStage::parsing;
  std::string_view path;      // the file at hand as given; empty while generating, storing
                              // objects from memory, or committing
  uint32_t file_index = 0;    // 0-based index among the model files (plan order); file_count
                              // while committing
  uint32_t file_count = 0;    // model files in the call; 0 for generated or in-memory objects
  uint64_t done = 0, total = 1;  // in the stage's unit; done <= total, total >= 1
};

struct IngestControl {
  // May be empty. A report (and the text its `path` views) is valid only during the callback.
  std::function<void(const IngestProgress&)> progress;
  // Default: never stops.
  std::stop_token stop;
  // Recorded with the revision this call commits (Import::set_note, set_keep_revisions).
  std::string note;
  uint32_t keep_revisions = kDefaultKeepRevisions;
};

struct IngestError {
  enum class Kind : uint8_t {
    input,      // a file is missing, unreadable or malformed (message names it and where)
    store,      // the store refused (message names the store and the operation)
    cancelled,  // the stop token was triggered; message "cancelled"
  };
  Kind kind = Kind::input;
  std::string message;  // complete on its own, as described above
  std::string path;     // input errors: the file at fault, as given; otherwise empty
};

// What one model file brought.
struct IngestedFile {
  std::string path;             // as given
  std::string source;           // the store's source: the canonical path
  std::string attributes_path;  // RVM: the attribute file read (as given or found); empty if none
  bool xml = false;             // true for plantview XML, false for RVM
  // RVM: groups and primitives in the file and objects made of them (RvmImportSummary).
  // XML: groups 0; primitives of its objects and objects read.
  uint64_t groups = 0, primitives = 0, objects = 0;
  std::vector<std::string> warnings;  // RVM: the parser's and the conversion's
};

// What a successful call put into the store.
struct IngestSummary {
  // Counts of the objects this call put (objects, primitives and full-resolution triangles by
  // class and kind, model-space bounds). Objects of other sources are not included.
  ModelStatistics added;
  std::vector<IngestedFile> files;  // ingest_files: one per model file, in plan order
  GenerateSummary generated;        // ingest_generated: the generator's own counts
  double seconds = 0;               // wall time of the whole call, commit included
};

// Either a summary (the transaction committed) or the error that stopped the call.
class IngestResult {
 public:
  IngestResult(IngestSummary summary) : state_(std::move(summary)) {}  // NOLINT: implicit by design
  IngestResult(IngestError error) : state_(std::move(error)) {}        // NOLINT: implicit by design

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }
  // Assert that the result holds what is asked for.
  const IngestSummary& summary() const;
  const IngestError& error() const;

 private:
  std::variant<IngestSummary, IngestError> state_;
};

// ---------------------------------------------------------------------------------------------
// Files.

struct ImportPlan {
  struct Model {
    std::filesystem::path path;        // .rvm or .xml, as given
    bool xml = false;
    std::filesystem::path attributes;  // RVM: the attribute file given for it; empty: look beside
  };
  std::vector<Model> models;  // in the order given
};

// Sorts file names by extension (either case): .rvm and .xml are models, .txt and .att the
// attribute files of the RVM of the same stem. Touches no file. Returns the plan, or nullopt with
// `error` set to one of (FILE as given):
//   "FILE: not an .rvm, .xml, .txt or .att file"
//   "FILE: attribute file without an RVM file of the same name"
//   "no .rvm or .xml file given"
std::optional<ImportPlan> plan_import(std::span<const std::string> files, std::string& error);

// Imports the plan's files into `store` in one transaction (see the opening block). `file_done`,
// if given, is called on the calling thread after each file's objects are in the transaction
// (not yet committed: a later failure still leaves the store as it was).
IngestResult ingest_files(Store& store, const ImportPlan& plan, const IngestControl& control = {},
                          const std::function<void(const IngestedFile&)>& file_done = {});

// ---------------------------------------------------------------------------------------------
// Generated plants and objects in memory.

// Generates the plant `options` describes into `store` (source "gen:<preset>"), replacing what
// that preset brought before, in one transaction.
IngestResult ingest_generated(Store& store, const GenerateOptions& options,
                              const IngestControl& control = {});

// Puts `objects` into `store` in one transaction, after removing what their sources (the
// distinct values of their `source` fields) brought before.
IngestResult ingest_objects(Store& store, std::span<const Object> objects,
                            const IngestControl& control = {});

}  // namespace plantview
