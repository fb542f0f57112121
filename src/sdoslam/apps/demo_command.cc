#include "sdoslam/apps/demo_command.h"

#include <fmt/format.h>

#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <system_error>

#include "sdoslam/core/error.h"
#include "sdoslam/eval/html_report.h"
#include "sdoslam/eval/plot.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/objects/object_eval.h"
#include "sdoslam/runner/run_on_dataset.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sequence.h"

namespace sdoslam {
namespace {

struct DemoArgs {
  std::string out = "sdoslam_demo";
  unsigned seed = 1;
  int frames = 150;
};

// One SLAM run of the demo, kept for the report.
struct DemoRun {
  std::string label;  // "<scenario> <mode>", as in the evaluation table
  RunMode mode;
  std::filesystem::path sequence;  // the rendered input
  std::filesystem::path out;       // the run's result set
  RunSummary summary;
  // sdo run: the frames of the report's strip (index) with their features as thumbnail marks.
  std::map<size_t, std::vector<ThumbnailMark>> strip;
  // sdo run: its moving objects (run --save-objects) scored against the rendered bodies.
  std::optional<ObjectEvaluation> objects;
};

// The strip shows this many frames of the sdo run, each this wide: half the rendered width, so
// that three fit side by side and six weigh about 250 KB.
constexpr size_t kOverlayThumbnails = 6;
constexpr int kThumbnailWidth = 320;
// DrawOverlay's feature colours (static green, dynamic red), redrawn on the thumbnails.
constexpr unsigned kStaticFeature = 0x00dc00, kDynamicFeature = 0xff0000;

std::string Milliseconds(double ms) { return fmt::format("{:.1f}", ms); }

HtmlSection TimingSection(const std::vector<DemoRun>& runs) {
  HtmlSection section;
  section.title = "Stage timings";
  section.paragraphs.push_back(
      "Medians in milliseconds on this machine: per frame for the dynamic front end and its "
      "stages, for features + tracking and for the total; per keyframe for local mapping. Each "
      "stage has its own median, so stages need not add up to the front end's median. The front "
      "end runs in sdo mode only (oracle reads the ground-truth masks instead).");
  HtmlTable table;
  table.header = {"run",
                  "frames",
                  "tracked",
                  "keyframes",
                  "front end",
                  "segment",
                  "detect",
                  "flow",
                  "classify",
                  "features + tracking",
                  "total per frame",
                  "mapping per keyframe"};
  for (const DemoRun& run : runs) {
    const RunSummary& s = run.summary;
    const bool front_end = run.mode == RunMode::kSdo;
    auto stage = [&](double ms) { return front_end ? Milliseconds(ms) : std::string("-"); };
    table.rows.push_back(
        {run.label, std::to_string(s.frames), std::to_string(s.tracked),
         std::to_string(s.keyframes), stage(s.median_front_end_ms),
         stage(s.median_front_end_stages.segment_ms), stage(s.median_front_end_stages.detect_ms),
         stage(s.median_front_end_stages.flow_ms), stage(s.median_front_end_stages.classify_ms),
         Milliseconds(s.median_frame_ms), Milliseconds(s.median_total_ms),
         Milliseconds(s.median_mapping_ms)});
  }
  section.tables.push_back(std::move(table));
  return section;
}

// Thumbnails of the strip's overlays of `run` (which saved them), each linking to its full size.
// Overlays are named after the sequence's rgb images, so the sequence gives their names.
HtmlSection OverlaySection(const DemoRun& run, const std::filesystem::path& out) {
  HtmlSection section;
  section.title = "Static and dynamic features (" + run.label + ")";
  section.layout = HtmlImageLayout::kStrip;
  section.paragraphs.push_back(
      "Features the dynamic front end kept as static are green, those it marked dynamic red "
      "(redrawn larger on these thumbnails). Tinted regions are dynamic: orange a known movable "
      "class (the renderer's detections), magenta moving with no known class, blue turned dynamic "
      "by the tracker's scene-flow check; grey lines outline segments, cyan marks motion "
      "boundaries, yellow boxes are detections. Click a frame for the full-size overlay.");
  const RgbdDataset dataset(run.sequence, synth::SyntheticCamera());
  for (const auto& [index, marks] : run.strip) {
    const auto name = dataset.entries().at(index).rgb_path.filename();
    const auto overlay = run.out / "overlays" / name;
    const auto thumbnail =
        out / "report_files" / std::filesystem::path(name).replace_extension(".jpg");
    WriteThumbnail(overlay, thumbnail, kThumbnailWidth, marks);
    section.images.push_back({thumbnail.lexically_relative(out),
                              fmt::format("frame {} of {}", index + 1, run.summary.frames),
                              overlay.lexically_relative(out)});
  }
  return section;
}

// The sdo run's moving objects: their scores against the rendered bodies and a top view of their
// tracks, written to <out>/plots/objects_top.{png,svg}.
HtmlSection ObjectsSection(const DemoRun& run, const std::filesystem::path& out) {
  HtmlSection section;
  section.title = "Moving objects (" + run.label + ")";
  section.paragraphs.push_back(
      "The moving objects the sdo run reported (run --save-objects: objects.csv and objects/), "
      "each with one id while it is in view and its own rigid motion from frame to frame, scored "
      "against the rendered bodies (sdoslam eval-objects): the ids taken for each body, the "
      "frames its main id covers, and the error of the estimated motions at the object's "
      "centroid. The overlays above name each object by its id.");
  HtmlTable table;
  table.header = ObjectEvaluationHeader();
  table.rows = ObjectEvaluationRows(*run.objects);
  section.tables.push_back(std::move(table));
  const Plot plot =
      ObjectTracksTopView(*run.objects, ReadTumTrajectory(run.sequence / "groundtruth.txt"));
  const auto png = out / "plots" / "objects_top.png", svg = out / "plots" / "objects_top.svg";
  SavePlot(plot, png);
  SavePlot(plot, svg);
  section.images.push_back({png.lexically_relative(out),
                            "The camera's true path in black; each object's centroid in colour "
                            "(through the camera trajectory's alignment) over its true path in "
                            "grey",
                            svg.lexically_relative(out)});
  if (!run.objects->unmatched_ids.empty()) {
    std::string ids;
    for (int id : run.objects->unmatched_ids) ids += fmt::format(" {}", id);
    section.notes.push_back("Objects no body explains (or seen in fewer than 3 frames):" + ids);
  }
  return section;
}

// The plots' .png files among `files` (each .png is followed by its .svg), as images that link
// to their .svg.
std::vector<HtmlImage> PlotImages(const std::vector<std::filesystem::path>& files,
                                  const std::filesystem::path& out) {
  std::vector<HtmlImage> images;
  for (const auto& file : files) {
    if (file.extension() != ".png") continue;
    const auto svg = std::filesystem::path(file).replace_extension(".svg");
    images.push_back({file.lexically_relative(out), "", svg.lexically_relative(out)});
  }
  return images;
}

// <out>/report.html: everything the demo printed and plotted on one page, with a strip of the
// sdo run's overlays, so that a user sees what happened without reading the terminal.
void WriteDemoReport(const DemoArgs& args, const std::filesystem::path& out,
                     const std::vector<DemoRun>& runs,
                     const std::vector<EstimateEvaluation>& evaluations,
                     const EvaluationOptions& options) {
  HtmlReport report;
  report.title = "sdoslam demo";
  report.intro.push_back(fmt::format(
      "A static room and the same room with people walking through it, {} frames each at 30 fps "
      "along the same camera motion (sensor noise seed {}), rendered by sdoslam synth. SLAM ran "
      "conventional (every feature used) on both; on the walking sequence also sdo (the dynamic "
      "front end decides which features are static) and oracle (the ground-truth masks: the "
      "ceiling for sdo).",
      args.frames, args.seed));
  report.sections.push_back(EvaluationSection(evaluations, options));
  // The strip right under the table: what the front end does explains conventional vs sdo.
  for (const DemoRun& run : runs) {
    if (!run.strip.empty()) report.sections.push_back(OverlaySection(run, out));
  }

  if (!evaluations.empty()) {
    // One row per run: its top view beside its error over time on its own scale; then the
    // errors of all runs on one scale.
    const auto plots = out / "plots";
    const auto top_views = PlotImages(WriteEvaluationPlots(evaluations, options, plots), out);
    const auto errors = PlotImages(WriteErrorOverTimePlots(evaluations, plots), out);
    HtmlSection per_run;
    per_run.title = "Trajectories and error over time";
    per_run.paragraphs.push_back(
        "Left, top views: ground truth in black, the estimate after alignment in colour, grey "
        "lines from estimated poses to their ground truth. Right, the translation error of each "
        "aligned pose against time, on the run's own scale. Click a plot for its SVG.");
    for (size_t k = 0; k < evaluations.size(); ++k) {
      per_run.images.push_back(top_views.at(k));
      per_run.images.push_back(errors.at(k));
    }
    report.sections.push_back(per_run);
    HtmlSection all_runs;
    all_runs.title = "Error over time, all runs";
    all_runs.paragraphs.push_back("The same errors on one scale.");
    all_runs.images.push_back(top_views.at(evaluations.size()));  // ate_over_time.png
    report.sections.push_back(all_runs);
  }

  for (const DemoRun& run : runs) {
    if (run.objects) report.sections.push_back(ObjectsSection(run, out));
  }
  report.sections.push_back(TimingSection(runs));
  for (const DemoRun& run : runs) {
    if (run.mode != RunMode::kSdo) continue;
    HtmlSection config;
    config.title = "Configuration of " + run.label;
    config.paragraphs.push_back(
        "The resolved configuration the run wrote; passed to sdoslam run --config, it reruns the "
        "run.");
    config.text_file = (run.out / "config.yaml").lexically_relative(out);
    report.sections.push_back(config);
  }
  WriteHtmlReport(report, out / "report.html");
}

// Thumbnails of an earlier demo would linger next to the new ones. Only its .jpg files go:
// nothing else in the folder, nothing behind a symbolic link (the user's files stay).
void RemoveEarlierThumbnails(const std::filesystem::path& folder) {
  std::error_code ec;
  if (!std::filesystem::is_directory(std::filesystem::symlink_status(folder, ec))) return;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
    if (entry.path().extension() == ".jpg" && entry.is_regular_file(ec) && !entry.is_symlink(ec))
      std::filesystem::remove(entry.path(), ec);
  }
}

// The main job on built-in data: render a static room and the same room with people walking
// through it (same camera motion), run SLAM and evaluate against the ground truth: conventional
// on both, then the dynamic front end (sdo) and the ground-truth-mask oracle on the walking one.
// The rendered people are boxes no COCO detector knows, so the demo's known-object detections
// come from the renderer (the `file` detector backend); moving objects of no known class would be
// found by motion.
void RunDemo(const DemoArgs& args) {
  const std::filesystem::path out = args.out;
  // Said before anything is rendered, in the words a run's result set uses; the first write
  // below would otherwise fail with the file system's "Not a directory" on a path inside it.
  if (std::filesystem::exists(out) && !std::filesystem::is_directory(out))
    throw IoError(out.string() + ": --out names a file, not a folder");
  std::cout << "sdoslam demo: synthetic sequence -> SLAM -> evaluation (nothing downloaded)\n\n";
  std::vector<EstimateEvaluation> evaluations;
  std::vector<DemoRun> runs;
  RemoveEarlierThumbnails(out / "report_files");
  for (const char* scenario : {"static_room", "walking_xyz"}) {
    synth::SynthOptions synth_options;
    synth_options.scenario = scenario;
    synth_options.motion = synth::CameraMotion::kXyz;
    synth_options.frames = args.frames;
    synth_options.seed = args.seed;
    const auto sequence = out / scenario;
    const synth::SequenceSummary rendered =
        synth::WriteSequence(synth_options, sequence, /*overwrite=*/true);
    std::cout << fmt::format(
        "{}: rendered {} frames in {:.1f} s; people and moving objects cover {:.0f} % of the "
        "image\n",
        scenario, rendered.frames, rendered.total_seconds, 100.0 * rendered.dynamic_fraction_mean);
    std::vector<RunMode> modes = {RunMode::kConventional};
    if (std::string(scenario) != "static_room")
      modes = {RunMode::kConventional, RunMode::kSdo, RunMode::kOracle};
    for (RunMode mode : modes) {
      DemoRun demo_run{fmt::format("{} {}", scenario, ToString(mode)),
                       mode,
                       sequence,
                       out / "slam" / fmt::format("{}_{}", scenario, ToString(mode)),
                       {},
                       {},
                       {}};
      RunOptions run_options;
      run_options.dataset = sequence;
      run_options.camera = synth::SyntheticCamera();
      run_options.mode = mode;
      run_options.front_end.detector = "file";
      run_options.front_end.detections_file = "detections.json";
      run_options.out = demo_run.out;
      if (mode == RunMode::kSdo) {
        // The report's strip shows the dynamic front end at work: overlays of the strip's frames
        // (to click through to; only those, to keep the demo folder small) and their features,
        // to redraw on thumbnails.
        run_options.save_overlays = true;
        // Its moving objects too, for the report (the camera trajectory is the same with and
        // without them).
        run_options.save_objects = true;
        for (size_t i : EvenlySpaced(rendered.frames, kOverlayThumbnails)) {
          demo_run.strip[i];
          run_options.overlay_frames.push_back(i);
        }
        run_options.after_frame = [&strip = demo_run.strip](const TrackingResult& r,
                                                            const System&) {
          const auto it = strip.find(r.index);
          if (it == strip.end()) return;
          for (size_t k = 0; k < r.feature_points.size(); ++k) {
            const bool dynamic = k < r.feature_labels.size() && r.feature_labels[k] != kStatic;
            it->second.push_back({r.feature_points[k], dynamic ? kDynamicFeature : kStaticFeature});
          }
        };
      }
      RunSummary run = RunOnDataset(run_options);
      std::cout << ToString(mode) << ": " << FormatRunSummary(run);
      if (run.masks && mode == RunMode::kSdo)
        std::cout << FormatMaskEvaluation(*run.masks, "sdo masks");
      if (run_options.save_objects) {
        demo_run.objects = EvaluateObjects(sequence, demo_run.out);
        std::cout << "sdo moving objects:\n" << FormatObjectEvaluation(*demo_run.objects);
      }
      std::cout << '\n';
      if (run.evaluation) {
        run.evaluation->label = demo_run.label;
        evaluations.push_back(*run.evaluation);
      }
      demo_run.summary = std::move(run);
      runs.push_back(std::move(demo_run));
    }
  }
  const EvaluationOptions options;
  std::cout << FormatTable(evaluations, options);
  WriteDemoReport(args, out, runs, evaluations, options);
  std::cout << "\nsequences, trajectories and plots in " << out.string()
            << "/\nreport (open in a browser): " << (out / "report.html").string() << "\n";
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand("demo", "run the built-in demo (no dataset, no download)");
  cmd->add_option("--out", args->out, "output folder")->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the sensor noise")->capture_default_str();
  cmd->add_option("--frames", args->frames, "frames per sequence")
      ->check(CLI::Range(30, 100000))
      ->capture_default_str();
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace sdoslam
