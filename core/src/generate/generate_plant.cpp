// The generator's entry points: lays plant units out in a grid and runs the stages on each,
// streaming objects as they are built.
#include <cassert>
#include <cmath>
#include <string>

#include "presets.h"

namespace plantview {

namespace {
constexpr double kRoadGap_m = 20.0;  // between neighbouring units
}

GenerateSummary generate_plant(const GenerateOptions& options,
                               const std::function<void(Object&&)>& sink,
                               const std::function<void(double)>& progress) {
  const PresetInfo* info = preset_info(options.preset);
  assert(info != nullptr && options.scale >= 1 && options.scale <= kMaxGenerateScale);
  const gen::PresetSpec& spec = gen::preset_spec(options.preset);
  GenerateSummary summary;
  summary.units = options.scale;
  gen::Emitter out(sink, summary);
  // A grid about as wide as it is deep.
  const double pitch_x = info->plan_x_m + kRoadGap_m, pitch_y = info->plan_y_m + kRoadGap_m;
  uint32_t columns = uint32_t(std::ceil(std::sqrt(double(options.scale) * pitch_y / pitch_x)));
  columns = std::max(1u, std::min(columns, options.scale));
  const size_t width = std::max<size_t>(2, std::to_string(options.scale).size());
  const std::string preset(1, options.preset);
  for (uint32_t u = 0; u < options.scale; ++u) {
    const uint64_t seed = gen::mix_seed(gen::mix_seed(options.seed, uint64_t(options.preset)), u);
    gen::Unit unit(spec, *info, u, seed, out);
    const std::string area = std::to_string(u + 1);
    unit.area = std::string(width - std::min(width, area.size()), '0') + area;
    unit.id_source = "gen:" + preset + ":" + std::to_string(options.seed) + ":" + std::to_string(u);
    unit.source = "gen:" + preset;
    unit.origin_m = glm::dvec3(pitch_x * double(u % columns), pitch_y * double(u / columns), 0.0);
    gen::lay_out_unit(unit);
    gen::build_equipment(unit);
    gen::build_structure(unit);
    std::function<void(double)> unit_progress;
    if (progress) {
      unit_progress = [&](double f) {
        progress((double(u) + 0.1 + 0.9 * f) / double(options.scale));
      };
    }
    gen::build_piping(unit, unit_progress);
    summary.pipelines_skipped += unit.pipelines_skipped;
    if (progress) progress(double(u + 1) / double(options.scale));
  }
  return summary;
}

PlantModel generate_model(const GenerateOptions& options) {
  PlantModel model;
  generate_plant(options, [&](Object&& o) { model.objects.push_back(std::move(o)); });
  return model;
}

}  // namespace plantview
