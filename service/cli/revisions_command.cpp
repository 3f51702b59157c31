// The store's revisions (plantview/store.h, "Revisions"):
//   plantview revisions --store DIR [--json]
//   plantview changes --store DIR --from R1 [--to R2] [--json]
//   plantview upgrade --store DIR
// Exit status: 0; 1 when the store cannot be read or a revision is pruned or unknown (the
// message names it); 2 for bad arguments.
#include <unistd.h>

#include <cstdio>
#include <ctime>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "plantview/store.h"

namespace plantview::cli {

std::string revision_time_text(int64_t time_unix_ms) {
  const std::time_t t = std::time_t(time_unix_ms / 1000);
  std::tm utc{};
  char text[32] = "?";
  if (gmtime_r(&t, &utc)) std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

void add_revision_options(CLI::App& command, RevisionOptions& options) {
  command.add_option("--note", options.note, "A note recorded with the revision this commit makes");
  command.add_option("--keep-revisions", options.keep_revisions,
                     "Revisions whose changes and previous records are kept (default 10, at least 1)");
  command.add_flag("--no-wait", options.no_wait,
                   "Fail, naming it, when another import is writing the store (default: wait)");
}

int apply_revision_options(const std::string& command, const RevisionOptions& options) {
  if (options.keep_revisions < 1 || options.keep_revisions > int64_t(UINT32_MAX))
    return usage_error(command + ": --keep-revisions must be 1 or more, got " +
                       std::to_string(options.keep_revisions));
  set_import_lock_wait(!options.no_wait);
  return 0;
}

std::string newest_revision_summary(const std::string& directory) {
  std::string error;
  auto store = Store::open(directory, Store::Mode::read_only, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  std::vector<Revision> revisions;
  if (!view || !view->revisions(revisions, error) || revisions.empty()) return "";
  const Revision& r = revisions.back();
  return "revision " + std::to_string(r.number) + ": " + std::to_string(r.added) + " added, " +
         std::to_string(r.removed) + " removed, " + std::to_string(r.modified) + " modified";
}

namespace {

std::unique_ptr<ReadView> open_view(const std::string& command, const std::string& directory,
                                    std::unique_ptr<Store>& store) {
  std::string error;
  store = Store::open(directory, Store::Mode::read_only, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  if (!view) std::cerr << "plantview " << command << ": " << error << "\n";
  return view;
}

nlohmann::json revision_json(const Revision& r) {
  return {{"revision", r.number},
          {"time", revision_time_text(r.time_unix_ms)},
          {"time_unix_ms", r.time_unix_ms},
          {"added", r.added},
          {"removed", r.removed},
          {"modified", r.modified},
          {"objects", r.objects},
          {"note", r.note},
          {"sources", r.sources},
          {"changes_kept", r.changes_kept}};
}

// ---- revisions

struct RevisionsOptions {
  std::string store;
  bool json = false;
};

int run_revisions(const RevisionsOptions& o) {
  std::unique_ptr<Store> store;
  auto view = open_view("revisions", o.store, store);
  if (!view) return 1;
  std::vector<Revision> revisions;
  std::string error;
  if (!view->revisions(revisions, error)) {
    std::cerr << "plantview revisions: " << error << "\n";
    return 1;
  }
  if (o.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const Revision& r : revisions) out.push_back(revision_json(r));
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  std::printf("%8s  %-20s %8s %8s %8s %9s  %s\n", "revision", "time (UTC)", "added", "removed",
              "modified", "objects", "note; sources");
  for (const Revision& r : revisions) {
    std::string sources;
    for (const std::string& s : r.sources) sources += (sources.empty() ? "" : ", ") + s;
    std::string tail = r.note;
    if (!sources.empty()) tail += (tail.empty() ? "" : "; ") + sources;
    if (!r.changes_kept) tail += " (changes not kept)";
    std::printf("%8u  %-20s %8llu %8llu %8llu %9llu  %s\n", r.number,
                revision_time_text(r.time_unix_ms).c_str(), (unsigned long long)r.added,
                (unsigned long long)r.removed, (unsigned long long)r.modified,
                (unsigned long long)r.objects, tail.c_str());
  }
  if (revisions.empty()) std::printf("(no revisions: nothing committed yet)\n");
  return 0;
}

// ---- changes

struct ChangesOptions {
  std::string store;
  int64_t from = -1, to = -1;
  bool json = false;
};

int run_changes(const ChangesOptions& o) {
  if (o.from < 0 || o.from > int64_t(UINT32_MAX))
    return usage_error("changes: --from must be a revision number (0 or more)");
  if (o.to != -1 && (o.to < 1 || o.to > int64_t(UINT32_MAX)))
    return usage_error("changes: --to must be a revision number (1 or more)");
  if (o.to != -1 && o.to <= o.from)
    return usage_error("changes: --to (" + std::to_string(o.to) + ") must come after --from (" +
                       std::to_string(o.from) + ")");
  std::unique_ptr<Store> store;
  auto view = open_view("changes", o.store, store);
  if (!view) return 1;
  const uint32_t newest = view->info().revision;
  const uint32_t from = uint32_t(o.from), to = o.to == -1 ? newest : uint32_t(o.to);
  std::string error;
  std::vector<ObjectChange> changes;
  if (to > newest || from > newest) {
    error = "store " + o.store + ": no revision " + std::to_string(from > newest ? from : to) +
            " (the newest is " + std::to_string(newest) + ")";
  } else if (from == to) {
    // --from the newest revision: nothing changed since.
  } else if (!view->changes(from, to, changes, error)) {
    error = error.empty() ? "cannot read the changes" : error;
  } else {
    error.clear();
  }
  if (!error.empty()) {
    std::cerr << "plantview changes: " << error << "\n";
    return 1;
  }
  uint64_t counts[3] = {0, 0, 0};
  for (const ObjectChange& c : changes) ++counts[int(c.kind)];
  if (o.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const ObjectChange& c : changes) {
      list.push_back({{"id", std::to_string(c.id)},
                      {"tag", c.name},
                      {"class", class_name(c.object_class)},
                      {"kind", change_kind_name(c.kind)},
                      {"revision", c.revision}});
    }
    const nlohmann::json out = {{"store", o.store},   {"from", from},
                                {"to", to},           {"added", counts[0]},
                                {"removed", counts[1]}, {"modified", counts[2]},
                                {"changes", list}};
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  std::printf("changes from revision %u to %u: %llu added, %llu removed, %llu modified\n", from,
              to, (unsigned long long)counts[0], (unsigned long long)counts[1],
              (unsigned long long)counts[2]);
  for (const ObjectChange& c : changes) {
    std::printf("%-8s %-10s %8u  %-20llu %s\n", std::string(change_kind_name(c.kind)).c_str(),
                std::string(class_name(c.object_class)).c_str(), c.revision,
                (unsigned long long)c.id, c.name.c_str());
  }
  return 0;
}

// ---- upgrade

int run_upgrade(const std::string& directory) {
  std::string error;
  auto store = Store::open(directory, Store::Mode::read_write, error);
  std::unique_ptr<ReadView> view = store ? store->read(error) : nullptr;
  if (!view) {
    std::cerr << "plantview upgrade: " << error << "\n";
    return 1;
  }
  const StoreInfo info = view->info();
  std::fprintf(stderr, "plantview upgrade: store %s is format %u, at revision %u\n",
               directory.c_str(), info.format_version, info.revision);
  return 0;
}

}  // namespace

Action add_revisions_commands(CLI::App& app) {
  auto revisions = std::make_shared<RevisionsOptions>();
  CLI::App* revisions_cmd = app.add_subcommand(
      "revisions", "The store's revisions: number, time, changes, objects, note and sources");
  revisions_cmd->add_option("--store", revisions->store, "Store directory")->required();
  revisions_cmd->add_flag("--json", revisions->json, "Write a JSON array to stdout");

  auto changes = std::make_shared<ChangesOptions>();
  CLI::App* changes_cmd = app.add_subcommand(
      "changes", "The objects added, removed or modified between two revisions of a store");
  changes_cmd->add_option("--store", changes->store, "Store directory")->required();
  changes_cmd->add_option("--from", changes->from, "The earlier revision (0: the empty store)")
      ->required();
  changes_cmd->add_option("--to", changes->to, "The later revision (default: the newest)");
  changes_cmd->add_flag("--json", changes->json, "Write JSON to stdout");

  auto upgrade = std::make_shared<std::string>();
  CLI::App* upgrade_cmd = app.add_subcommand(
      "upgrade", "Upgrade a store of an earlier format (5) in place, in one transaction");
  upgrade_cmd->add_option("--store", *upgrade, "Store directory")->required();

  return [=]() {
    if (revisions_cmd->parsed()) return run_revisions(*revisions);
    if (changes_cmd->parsed()) return run_changes(*changes);
    if (upgrade_cmd->parsed()) return run_upgrade(*upgrade);
    return -1;
  };
}

}  // namespace plantview::cli
