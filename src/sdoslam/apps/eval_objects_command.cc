#include "sdoslam/apps/eval_objects_command.h"

#include <iostream>
#include <memory>

#include "sdoslam/objects/object_eval.h"

namespace sdoslam {
namespace {

struct EvalObjectsArgs {
  std::string dataset;
  std::vector<std::string> runs;
  ObjectEvalOptions options;
};

}  // namespace

void AddEvalObjectsCommand(CLI::App& app) {
  auto args = std::make_shared<EvalObjectsArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval-objects",
      "each ground-truth body's object ids, coverage and per-frame motion error in a run's "
      "objects.csv (run --save-objects)");
  cmd->add_option("--dataset", args->dataset,
                  "sequence with groundtruth.txt and its bodies: object_poses.txt (sdoslam synth) "
                  "or bodies/*.txt (sdoslam convert --to tum of an OMD segment)")
      ->required();
  cmd->add_option("--run", args->runs, "output folder of `sdoslam run --save-objects` (repeatable)")
      ->required();
  cmd->add_option("--max-spread", args->options.max_spread_m,
                  "metres: an object is a body's when its centroid stays within this RMS distance "
                  "of one place in the body's frame")
      ->capture_default_str();
  cmd->callback([args] {
    for (const std::string& run : args->runs) {
      const ObjectEvaluation e = EvaluateObjects(args->dataset, run, args->options);
      std::cout << run << ":\n" << FormatObjectEvaluation(e);
    }
  });
}

}  // namespace sdoslam
