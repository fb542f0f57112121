#include "sdoslam/apps/eval_masks_command.h"

#include <fmt/format.h>

#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/camera.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/text_file.h"
#include "sdoslam/eval/mask_metrics.h"
#include "sdoslam/io/png_reader.h"
#include "sdoslam/io/result_set.h"
#include "sdoslam/io/tum_dataset.h"

namespace sdoslam {
namespace {

struct EvalMasksArgs {
  std::string dataset;
  std::vector<std::string> runs;
  std::string per_frame;  // CSV of the per-class scores of every frame; empty: none
};

// features.csv: index,x,y,label per feature, grouped by frame index.
std::map<size_t, std::pair<std::vector<cv::Point2f>, std::vector<uint8_t>>> ReadFeatures(
    const std::filesystem::path& path) {
  std::map<size_t, std::pair<std::vector<cv::Point2f>, std::vector<uint8_t>>> by_frame;
  const std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error(path.string() + ": cannot open");
  std::istringstream in(*text);
  std::string line;
  size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1 || line.empty()) continue;  // header
    size_t index;
    float x, y;
    int label;
    if (std::sscanf(line.c_str(), "%zu,%f,%f,%d", &index, &x, &y, &label) != 4)
      throw Error(fmt::format("{}:{}: expected index,x,y,label", path.string(), number));
    by_frame[index].first.emplace_back(x, y);
    by_frame[index].second.push_back(static_cast<uint8_t>(label));
  }
  return by_frame;
}

void EvalMasks(const EvalMasksArgs& args) {
  const std::filesystem::path dataset = args.dataset;
  // Frames in the dataset's order, to map a run's frame index to its file.
  std::vector<std::filesystem::path> rgb;
  {
    const std::optional<std::string> text = ReadRegularFileIfExists(dataset / "rgb.txt");
    if (!text) throw Error((dataset / "rgb.txt").string() + ": cannot open");
    std::istringstream in(*text);
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      const auto space = line.find(' ');
      if (space != std::string::npos) rgb.emplace_back(line.substr(space + 1));
    }
  }
  std::ostringstream per_frame;
  per_frame << kPerFrameScoresHeader << "\n";
  for (const std::string& run_folder : args.runs) {
    const std::filesystem::path run = run_folder;
    // Only a complete set is scored: never masks of an earlier run mixed with a newer one's.
    const ResultManifest manifest = VerifyResultSet(run);
    if (!std::filesystem::is_directory(run / "masks") || !manifest.Find("features.csv"))
      throw Error(run.string() + ": no masks/ and features.csv (run with --save-masks)");
    if (manifest.status != "complete") {
      std::cout << fmt::format("note: {} is an interrupted run ({} of {} frames)\n", run.string(),
                               manifest.info.value("frames_processed", size_t{0}),
                               manifest.info.value("frames_requested", size_t{0}));
    }
    MaskEvaluator evaluator(dataset);
    const auto features = ReadFeatures(run / "features.csv");
    for (size_t i = 0; i < rgb.size(); ++i) {
      const auto mask_path = run / "masks" / rgb[i].filename();
      if (!std::filesystem::exists(mask_path)) continue;  // the run stopped earlier
      const cv::Mat mask = ReadImage(mask_path, cv::IMREAD_GRAYSCALE);
      if (mask.empty()) throw Error(mask_path.string() + ": cannot read");
      const auto it = features.find(i);
      if (it == features.end()) {
        evaluator.AddFrame(rgb[i], mask);
      } else {
        evaluator.AddFrame(rgb[i], mask, it->second.first, it->second.second);
      }
    }
    if (evaluator.result().frames == 0) throw Error(run.string() + ": no mask matches the dataset");
    std::cout << FormatMaskEvaluation(evaluator.result(), run.string());
    WritePerFrameScores(evaluator.result(), run.string(), per_frame);
  }
  // Written once every run is scored: an error in a later run leaves no partial table.
  if (!args.per_frame.empty()) {
    WriteFileAtomically(args.per_frame, [&](std::ostream& out) { out << per_frame.str(); });
    std::cout << "wrote " << args.per_frame << "\n";
  }
}

}  // namespace

void AddEvalMasksCommand(CLI::App& app) {
  auto args = std::make_shared<EvalMasksArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval-masks",
      "precision, recall and IoU of saved dynamic masks against synthetic ground truth");
  cmd->add_option("--dataset", args->dataset,
                  "synthetic sequence (dynamic/, instance/, objects.json)")
      ->required();
  cmd->add_option("--run", args->runs, "output folder of `sdoslam run --save-masks` (repeatable)")
      ->required();
  cmd->add_option("--per-frame", args->per_frame,
                  "write each class's scores frame by frame to this CSV (run, frame, file, class, "
                  "IoU, true/false positives, false negatives)");
  cmd->callback([args] { EvalMasks(*args); });
}

}  // namespace sdoslam
