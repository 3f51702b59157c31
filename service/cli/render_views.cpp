// `plantview render --views`: the farm's shard (farm/scheduler.h states the contract): named,
// captioned review images, a manifest part, and the job's merged manifest and contact sheet.
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "cli/bcf_export.h"
#include "cli/farm/incremental.h"
#include "cli/farm/job_inputs.h"
#include "cli/farm/manifest.h"
#include "cli/farm/output_dir.h"
#include "cli/progress.h"
#include "cli/render_run.h"
#include "plantview/review.h"

namespace plantview::cli::rendering {

namespace {

// The options one view renders with: its subject highlighted, the rest ghosted (an overview's
// empty subject highlights nothing); its section where it has one, else the command line's; its
// style (view_filters.h), where the command line's --colour-by, --hide and --only replace each
// part they give.
RenderOptions review_render_options(const RenderOptions& base, const ReviewView& view) {
  RenderOptions options = base;
  options.record_drawn = true;  // what each image was drawn from (farm/incremental.h)
  options.highlight_ids = view.subject;
  options.style = view.style;
  if (!base.style.colour_by.empty()) options.style.colour_by = base.style.colour_by;
  if (!base.style.hide.empty()) options.style.hide = base.style.hide;
  if (!base.style.only.empty()) options.style.only = base.style.only;
  if (!view.section.empty()) options.section = view.section;
  if (view.changes && !base.changes) options.changes = view.changes;  // (--changes replaces it)
  // A clash view's two colours (--colour-by replaces them, as it replaces the view's own).
  if (base.style.colour_by.empty()) options.subject_colours = view.colours;
  return options;
}

// Draws the view's caption strip (review.h: caption_lines) into the image, with the frame's
// legend when it is coloured by an attribute.
bool add_review_caption(Image& image, const ReviewView& view, const FrameStats& stats,
                        std::string& error) {
  std::vector<CaptionColumn> columns(1);
  columns[0].lines = caption_lines(view);
  // A change image says what it shows: the range and its counts.
  if (stats.changes.shown) columns[0].lines.insert(columns[0].lines.begin(), change_caption(stats.changes));
  // The legend in columns beside the view's lines, as many rows as they have (at least 4).
  // (A change image's legend needs no heading: the first line says what it is.)
  add_legend_columns(stats.legend, std::max<size_t>(4, columns[0].lines.size()), columns,
                     !stats.changes.shown && stats.legend.key != "subjects");
  return add_caption_columns(image, view.title, columns, error);
}

// What, besides the view, the objects it drew and its global inputs, an image depends on (the
// settings hash; farm/incremental.h says when a view is rendered again).
std::string render_settings_text(const RenderArgs& a, const RenderPlan& plan) {
  nlohmann::json settings = {
      {"program", PLANTVIEW_VERSION},
      {"size", std::to_string(plan.width) + "x" + std::to_string(plan.height)},
      {"format", plan.format == ImageFormat::png ? "png" : "jpeg"},
      {"quality", plan.format == ImageFormat::jpeg ? a.quality : 0},
      {"lod_policy", std::string(lod_policy_name(plan.options.lod_policy))},
      {"pixel_error", plan.options.pixel_error},
      {"vertex_budget_bytes", plan.options.vertex_budget_bytes},
      {"centrelines", plan.options.centrelines},
      {"hlod", plan.options.hlod},
      {"subpixel_culling", plan.options.subpixel_culling},
      {"samples", plan.options.samples},
      {"antialias", plan.options.antialias},
      {"antialias_method", std::string(antialias_method_name(plan.options.antialias_method))},
      {"ground", plan.options.ground},
      {"ambient_occlusion", plan.options.ambient_occlusion},
      {"caption", true}};
  if (plan.options.changes)  // --changes (absent otherwise, as the style)
    settings["changes"] = change_range_text(*plan.options.changes);
  if (!plan.options.style.empty())  // (absent otherwise: earlier runs' hashes hold)
    settings["style"] = {{"colour_by", plan.options.style.colour_by},
                         {"hide", plan.options.style.hide},
                         {"only", plan.options.style.only}};
  if (plan.options.section.empty()) return settings.dump();
  // The command line's section (each view's own is in the view's text, hashed with it).
  nlohmann::json planes = nlohmann::json::array();
  for (const ClipPlane& p : plan.options.section.planes)
    planes.push_back({p.point_m.x, p.point_m.y, p.point_m.z, p.normal.x, p.normal.y, p.normal.z});
  settings["section"] = {{"planes", planes}, {"capped", plan.options.section.capped}};
  if (plan.options.section.has_box) {
    const DAabb& b = plan.options.section.box;
    settings["section"]["box"] = {b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z};
  }
  return settings.dump();
}

nlohmann::json vec3_json(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

nlohmann::json view_record(const ReviewView& view, const std::string& file, const std::string& hash,
                           const RenderPlan& plan) {
  return {{"name", view.name},
          {"title", view.title},
          {"kind", view.kind},
          {"file", file},
          {"camera",
           {{"eye", vec3_json(view.camera.eye_m)},
            {"target", vec3_json(view.camera.target_m)},
            {"up", vec3_json(view.camera.up)},
            {"fov_deg", view.camera.fov_deg}}},
          {"aspect", view.aspect},
          {"subject", view.subject},
          {"settings_hash", hash},
          {"shard", std::to_string(plan.shard_index) + "/" + std::to_string(plan.shard_count)}};
}

}  // namespace

int render_views(const RenderArgs& a, const RenderPlan& plan) {
  std::string error, text;
  const fs::path out = a.out;
  std::vector<ReviewView> views;
  // Everything that can be refused is checked before the first image.
  if (!farm::read_views_file(a.views, views, text, error)) return fail(error);
  if (!farm::prepare_output_dir(out, error)) return fail(error);
  const auto t_open = std::chrono::steady_clock::now();
  auto store = Store::open(a.store, Store::Mode::read_only, error);
  if (!store) return fail(error);
  auto read = store->read(error);
  if (!read) return fail(error);
  const double store_open_ms = ms_since(t_open);
  if (!farm::check_subjects(views, *read, error)) return fail(a.views + ": " + error);
  std::error_code ec;
  if (!fs::equivalent(a.views, out / farm::kViewsCopyName, ec) &&
      !farm::write_file_atomically(out / farm::kViewsCopyName, text, error))
    return fail(error);

  // Which of this shard's views are done already with the same settings, and of those drawn
  // at an earlier state of the store, which that state's changes cannot reach
  // (farm/incremental.h).
  std::map<std::string, nlohmann::json> previous;
  if (!farm::read_newest_records(out, previous, error)) return fail(error);
  const std::string store_identity = farm::store_identity(*read);
  const DAabb model_bounds = read->info().statistics.bounds;
  const uint32_t revision = read->info().revision;  // (shown; the state is store_identity)
  if (!farm::ensure_objects_file(out, store_identity, *read, error)) return fail(error);
  std::vector<farm::ObjectState> store_objects;
  if (!farm::read_objects_file(farm::objects_file(out, store_identity), store_objects, error)) return fail(error);
  read.reset();
  const std::string settings = render_settings_text(a, plan) + "\n";
  const char* extension = plan.format == ImageFormat::png ? ".png" : ".jpg";
  std::vector<nlohmann::json> records;
  std::vector<size_t> to_render;
  std::vector<std::string> hashes(views.size()), globals(views.size()), stale_because(views.size());
  farm::StalenessJudge judge(out, store_identity);
  size_t kept_after_change = 0;
  for (size_t i = plan.shard_index; i < views.size(); i += plan.shard_count) {
    hashes[i] = farm::hash_hex(settings + review_views_json({views[i]}, views[i].kind));
    globals[i] = farm::global_inputs_hash(
        model_bounds, farm::uses_model_bounds(review_render_options(plan.options, views[i])));
    const auto found = previous.find(views[i].name);
    farm::Staleness staleness;
    if (a.force) {
      staleness.reason = farm::Staleness::Reason::settings;
      staleness.detail = "--force";
    } else if (found == previous.end() || found->second.value("status", "") != "done" ||
               !fs::is_regular_file(out / found->second.value("file", ""), ec)) {
      staleness.reason = farm::Staleness::Reason::no_record;
      staleness.detail = "not done";
    } else if (!judge.judge(found->second, hashes[i], globals[i], staleness, error)) {
      return fail(error);
    }
    if (staleness.reason == farm::Staleness::Reason::fresh) {
      nlohmann::json record = found->second;  // kept in this shard's part when it is written again
      if (record.value("store", "") != store_identity) {
        // Drawn at an earlier state whose changes cannot reach it: its image is this state's.
        record["store"] = store_identity;
        record["revision"] = revision;
        record["checked_unix_ms"] = farm::unix_ms_now();
        ++kept_after_change;
      }
      records.push_back(std::move(record));
    } else {
      stale_because[i] = std::string(farm::staleness_name(staleness.reason)) + ": " + staleness.detail;
      to_render.push_back(i);
    }
  }
  const size_t skipped = records.size();

  size_t failed = 0;
  if (!to_render.empty()) {
    const auto t_context = std::chrono::steady_clock::now();
    RenderSession session;
    if (!start_rendering(a.device, *store, plan.options, session, error)) return fail(error);
    if (farm::store_identity(session.renderer->read_view()) != store_identity)
      return fail(a.store + ": the store changed (an import committed) while this shard started; run it again");
    const double context_ms = ms_since(t_context);
    Progress progress("render");
    // Each view's image is encoded and written while the next renders; its record follows in
    // the shard's order once written.
    std::string manifest_error;
    ImageWriter writer(plan.format, a.quality);
    for (size_t n = 0; n < to_render.size() && manifest_error.empty(); ++n) {
      const ReviewView& view = views[to_render[n]];
      const auto t_view = std::chrono::steady_clock::now();
      const std::string file = view.name + extension;
      auto record = std::make_shared<nlohmann::json>(view_record(view, file, hashes[to_render[n]], plan));
      const RenderOptions view_options = review_render_options(plan.options, view);
      (*record)["store"] = store_identity;
      (*record)["revision"] = revision;
      (*record)["global"] = globals[to_render[n]];
      (*record)["global_uses_bounds"] = farm::uses_model_bounds(view_options);
      (*record)["size"] = {{"width", plan.width}, {"height", plan.height}};
      (*record)["section"] = farm::section_json(view_options.section);
      if (!stale_because[to_render[n]].empty()) (*record)["rendered_because"] = stale_because[to_render[n]];
      FrameStats stats;
      Image image = writer.take_buffer();
      session.renderer->set_options(view_options);
      if (n + 1 < to_render.size()) session.renderer->expect(views[to_render[n + 1]].camera);
      bool ok = session.renderer->render(view.camera, plan.width, plan.height, false, image, stats, error);
      const auto t_caption = std::chrono::steady_clock::now();
      ok = ok && add_review_caption(image, view, stats, error);
      if (ok) {
        // What the image was drawn from, beside it (read before the next view's frame).
        farm::DrawnSet drawn;
        const fs::path drawn_path = farm::drawn_file(out, view.name);
        ok = farm::drawn_set(session.renderer->read_view(), stats, store_objects, drawn, error) &&
             farm::write_drawn_file(drawn_path, drawn, error);
        (*record)["drawn"] = {{"file", fs::relative(drawn_path, out).string()},
                              {"objects", drawn.objects.size()},
                              {"regions", drawn.regions.size()},
                              {"pipelines", drawn.pipelines.size()},
                              {"digest", farm::drawn_digest(drawn)}};
        stats.drawn_slots = {};
        stats.drawn_regions = {};
      }
      const double caption_ms = ms_since(t_caption);
      // Recorded once written (or at once, failed).
      const auto finish_view = [&, n, t_view, caption_ms, record](bool written, const std::string& why,
                                                                 const FrameStats& frame) {
        (*record)["status"] = written ? "done" : "failed";
        if (!written) {
          (*record)["error"] = why;
          std::cerr << "plantview: view '" << views[to_render[n]].name << "': " << why << "\n";
          ++failed;
        }
        (*record)["stats"] = nlohmann::json::parse(frame.to_json());
        (*record)["ms"] = {{"store_open", store_open_ms},  {"context", context_ms},
                           {"first_in_process", n == 0}, {"frame", frame.ms.total},
                           {"caption", caption_ms},       {"encode", frame.ms.encode},
                           {"total", ms_since(t_view)}};
        (*record)["finished_unix_ms"] = farm::unix_ms_now();
        records.push_back(std::move(*record));
        // The part lists every view this shard finished, so a killed task loses only the
        // views it was rendering and writing.
        if (manifest_error.empty() &&
            !farm::write_manifest_part(out, plan.shard_index, plan.shard_count, records, manifest_error) &&
            manifest_error.empty())
          manifest_error = "cannot write the manifest part";
        progress.update(double(n + 1) / double(to_render.size()),
                        std::to_string(n + 1) + "/" + std::to_string(to_render.size()) + " " +
                            views[to_render[n]].name);
      };
      if (!ok) {
        writer.finish();  // the views before it first, in order
        finish_view(false, error, stats);
        continue;
      }
      writer.write(out / file, std::move(image), stats, [finish_view](ImageToWrite& written) {
        finish_view(written.ok, written.error, written.stats);
      });
    }
    writer.finish();
    progress.finish();
    if (!manifest_error.empty()) return fail(manifest_error);
  } else if (!farm::write_manifest_part(out, plan.shard_index, plan.shard_count, records, error)) {
    return fail(error);
  }
  farm::FarmSummary summary;
  if (!farm::merge_manifests(out, summary, error)) return fail(error);
  // The job's BCF file, by whichever shard finds every view done (each writes it whole under a
  // temporary name, so two that finish together leave one complete file).
  std::string bcf_status;
  if (!a.bcf.empty()) {
    if (summary.done.size() == summary.views) {
      read = store->read(error);
      if (!read) return fail(error);
      if (!export_views_bcf(views, out, farm::store_identity(*read), read.get(), a.bcf, error))
        return fail("--bcf: " + error);
      read.reset();
      bcf_status = "written";
    } else {
      bcf_status = "waiting: " + std::to_string(summary.views - summary.done.size()) + " view(s) not done";
    }
  }
  nlohmann::json result{{"shard", std::to_string(plan.shard_index) + "/" + std::to_string(plan.shard_count)},
                        {"views", to_render.size() + skipped},
                        {"rendered", to_render.size() - failed},
                        {"skipped", skipped},
                        {"kept_after_store_change", kept_after_change},
                        {"failed", failed},
                        {"job", farm::summary_json(summary)}};
  if (!bcf_status.empty()) result["bcf"] = bcf_status;
  std::cout << result.dump() << "\n";
  return failed == 0 ? 0 : 1;
}

}  // namespace plantview::cli::rendering
