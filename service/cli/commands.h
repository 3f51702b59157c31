// The subcommands of the plantview program. Each registers its options on the CLI11 app and
// returns the process exit status when run: 0 on success, 1 on a runtime failure (message on
// stderr), 2 on a usage error (CLI11 reports those).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace plantview::cli {

// A subcommand's action, run after parsing when its subcommand was chosen.
using Action = std::function<int()>;

// `plantview primitives`: the tessellation of every primitive kind at every level.
Action add_primitives_command(CLI::App& app);

// `plantview gen`, `info` and `export`: generating plants into, and reading, the store.
Action add_store_commands(CLI::App& app);

// `plantview import FILE... --store DIR`: RVM and XML files into the store.
Action add_import_command(CLI::App& app);

// `plantview render`, `compare` and `path`: review images, comparing them, camera paths.
Action add_render_commands(CLI::App& app);

// `plantview serve`: the HTTP service (plantview/server.h).
Action add_serve_command(CLI::App& app);

}  // namespace plantview::cli
