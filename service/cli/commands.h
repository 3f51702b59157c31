// The subcommands of the plantview program. Each registers its options on the CLI11 app and
// returns the process exit status when run: 0 on success, 1 on a runtime failure (message on
// stderr), 2 on a usage error (CLI11 reports those).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace plantview {
class ReadView;
struct ClashReport;
struct PreviousClashes;
}  // namespace plantview

namespace plantview::cli {

// A subcommand's action, run after parsing when its subcommand was chosen.
using Action = std::function<int()>;

// A usage error found after parsing (a value out of range, options that do not go together):
// the message on stderr, exit status 2.
inline int usage_error(const std::string& message) {
  std::cerr << "plantview: " << message << "\n";
  return 2;
}

// `plantview primitives`: the tessellation of every primitive kind at every level.
Action add_primitives_command(CLI::App& app);

// `plantview gen`, `info` and `export`: generating plants into, and reading, the store.
Action add_store_commands(CLI::App& app);

// `plantview import FILE... --store DIR`: RVM and XML files into the store.
Action add_import_command(CLI::App& app);

// `plantview render` and `path`: review images and camera paths.
Action add_render_commands(CLI::App& app);

// Render options as `farm submit` passes them on to its shards (each name followed by its
// value, or a flag alone), checked as `render --views VIEWS --out OUT` checks them, before
// anything is read or written: 0, or 2 with the usage error on stderr.
int check_render_options(const std::vector<std::string>& passed, const std::string& views,
                         const std::string& out);

// `plantview views --store DIR --per KIND --out VIEWS.json`: named, fitted review views.
Action add_views_command(CLI::App& app);

// `plantview compare A B`: how far apart two images are.
Action add_compare_command(CLI::App& app);

// `plantview farm submit` and `farm status`: views files rendered by a scheduler (Slurm).
Action add_farm_command(CLI::App& app);

// `plantview serve`: the HTTP service (plantview/server.h).
Action add_serve_command(CLI::App& app);

// `plantview bcf export` and `bcf import`: review views as BCF 2.1 files and back.
Action add_bcf_command(CLI::App& app);

// `plantview devices [--json]`: the EGL devices (the --device indices) and the default one.
Action add_devices_command(CLI::App& app);

// `plantview measure --store DIR --a TAG|ID --b TAG|ID [--json]`: clearance between two objects.
Action add_measure_command(CLI::App& app);

// `plantview revisions`, `changes` and `upgrade`: a store's revisions (plantview/store.h).
Action add_revisions_commands(CLI::App& app);
// A revision's time as text, "2026-12-06T10:02:11Z" (UTC).
std::string revision_time_text(int64_t time_unix_ms);
// What import and gen share about revisions: --note, --keep-revisions, --no-wait.
struct RevisionOptions {
  std::string note;
  int64_t keep_revisions = 10;  // kDefaultKeepRevisions
  bool no_wait = false;
};
void add_revision_options(CLI::App& command, RevisionOptions& options);
// Checks them (2 with the message on stderr for a bad --keep-revisions, else 0), and applies
// --no-wait (set_import_lock_wait).
int apply_revision_options(const std::string& command, const RevisionOptions& options);
// "revision 14: 3 added, 0 removed, 37 modified" for the store's newest revision ("" when it
// cannot be read).
std::string newest_revision_summary(const std::string& directory);
// `plantview clash --store DIR [...]` and `clash merge`: clash detection (plantview/clash.h).
Action add_clash_command(CLI::App& app);
// The options `clash` and `farm submit --clash` share, as given (millimetres).
struct ClashOptions {
  double tolerance_mm = 1.0, clearance_mm = 0.0;
  std::string between, with;
  bool include_connected = false;
  std::string since;  // a previous clashes.json; "" for none
};
// What `clash --store STORE` refuses, checked before anything runs or is written, in this order:
// the tolerance and clearance in range, --between with --and (usage: 2); the store opened and
// read (1); a store without piping topology unless --include-connected, a set that matches no
// object, naming it (2); the --since file read whole and made by a run on this store with these
// settings (1). 0 with the store's view in `view` and, with --since, the file's header and keys
// in `previous` (clash.h: read_previous_clashes); else the exit status, the message on
// stderr naming `command` ("clash", "farm submit --clash"), the option and the path.
int check_clash_options(const std::string& command, const ClashOptions& options, const std::string& store,
                        std::unique_ptr<ReadView>& view, PreviousClashes& previous);

}  // namespace plantview::cli
