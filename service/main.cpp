// plantview: headless, out-of-core rendering of process-plant models. The program's entry point:
// parses the command line and runs the chosen subcommand.
#include <CLI/CLI.hpp>
#include <iostream>
#include <vector>

#include "cli/commands.h"

int main(int argc, char** argv) {
  CLI::App app{
      "plantview: headless, out-of-core rendering of process-plant models from their "
      "parametric primitives"};
  app.set_version_flag("--version", std::string("plantview ") + PLANTVIEW_VERSION);
  app.require_subcommand(1);

  std::vector<plantview::cli::Action> actions;
  actions.push_back(plantview::cli::add_primitives_command(app));
  actions.push_back(plantview::cli::add_store_commands(app));
  actions.push_back(plantview::cli::add_import_command(app));
  actions.push_back(plantview::cli::add_render_commands(app));
  actions.push_back(plantview::cli::add_views_command(app));
  actions.push_back(plantview::cli::add_compare_command(app));
  actions.push_back(plantview::cli::add_serve_command(app));
  actions.push_back(plantview::cli::add_farm_command(app));
  actions.push_back(plantview::cli::add_devices_command(app));
  actions.push_back(plantview::cli::add_bcf_command(app));
  actions.push_back(plantview::cli::add_measure_command(app));
  actions.push_back(plantview::cli::add_revisions_commands(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every usage error exits 2, as the commands.h rule says.
    return app.exit(e) == 0 ? 0 : 2;
  }
  for (const auto& action : actions) {
    const int status = action();
    if (status >= 0) return status;
  }
  return 2;
}
