// `plantview devices [--json]`: the EGL devices this machine offers, with the index that
// `render`, `serve` and `farm` take as --device, and which one they take without it. Each is
// opened and closed once. Text on stdout, or one JSON document with --json:
//   {"devices": [{"index", "name", "software", "usable", "description"}...],
//    "default": INDEX, or null where no device is usable and Mesa's surfaceless platform is tried}
// Exit 1 when no device is usable and the surfaceless platform makes no context either.
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "plantview/render.h"

namespace plantview::cli {

namespace {

int run_devices(bool json) {
  const std::vector<GpuDeviceInfo> devices = GpuContext::list_devices();
  // GpuContext::create(-1)'s rule: the first usable hardware device, else the first usable one.
  int chosen = -1;
  for (const bool software : {false, true}) {
    for (const auto& d : devices) {
      if (chosen < 0 && d.usable && d.software == software) chosen = d.index;
    }
  }
  std::string surfaceless;  // what create(-1) opens where no device is usable
  std::string error;
  if (chosen < 0) {
    if (auto context = GpuContext::create(-1, error)) surfaceless = context->description();
  }
  if (json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& d : devices)
      list.push_back({{"index", d.index}, {"name", d.name}, {"software", d.software},
                      {"usable", d.usable}, {"description", d.description}});
    nlohmann::json out = {{"devices", list}, {"default", nullptr}};
    if (chosen >= 0) out["default"] = chosen;
    if (!surfaceless.empty()) out["surfaceless"] = surfaceless;
    std::cout << out.dump() << "\n";
  } else {
    if (devices.empty()) std::cout << "EGL lists no devices (no EGL_EXT_platform_device)\n";
    for (const auto& d : devices) {
      std::cout << (d.index == chosen ? "* " : "  ") << d.index << "  "
                << (d.software ? "software" : "hardware") << "  "
                << (d.usable ? d.description : "not usable: " + d.description) << "\n";
    }
    if (chosen >= 0) {
      std::cout << "(* the default; --device N picks another)\n";
    } else if (!surfaceless.empty()) {
      std::cout << "default: " << surfaceless << "\n";
    }
  }
  if (chosen < 0 && surfaceless.empty()) {
    std::cerr << "plantview: " << error << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

Action add_devices_command(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  auto* devices = app.add_subcommand(
      "devices", "List the EGL devices (the --device indices) and which one is used by default");
  devices->add_flag("--json", *json, "One JSON document on stdout");
  return [=]() -> int { return devices->parsed() ? run_devices(*json) : -1; };
}

}  // namespace plantview::cli
