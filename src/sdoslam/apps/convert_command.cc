#include "sdoslam/apps/convert_command.h"

#include <iostream>
#include <memory>

#include "sdoslam/core/error.h"
#include "sdoslam/io/dataset.h"

namespace sdoslam {
namespace {

struct ConvertArgs {
  std::string dataset;
  std::string layout = "auto";
  std::string config;
  std::string to = "tum";
  std::string out;
  bool overwrite = false;
};

void Convert(const ConvertArgs& args) {
  DatasetOptions options;
  options.layout = ParseDatasetLayout(args.layout);
  const DatasetLayout layout =
      options.layout == DatasetLayout::kAuto ? DetectLayout(args.dataset) : options.layout;
  CameraOptions camera;
  if (!args.config.empty()) {
    camera = LoadCameraConfig(args.config);
  } else if (layout == DatasetLayout::kOmd) {
    camera.from_dataset = true;  // kalibr.yaml's colour camera, depth in millimetres
    camera.depth_factor = options.omd.depth_factor;
  } else {
    const std::filesystem::path own = std::filesystem::path(args.dataset) / "camera.yaml";
    if (!std::filesystem::exists(own))
      throw Error(args.dataset + " has no camera.yaml: give the camera with --config");
    camera = LoadCameraConfig(own);
  }
  const RgbdDataset dataset(args.dataset, camera, options);
  WriteTumCopy(dataset, args.out, args.overwrite);
  std::cout << "wrote " << dataset.size() << " frames of " << args.dataset << " ("
            << ToString(dataset.layout()) << ") to " << args.out << " (TUM layout"
            << (dataset.ground_truth() ? ", groundtruth.txt" : "")
            << (dataset.bodies().empty() ? "" : ", bodies/") << ")\n";
}

}  // namespace

void AddConvertCommand(CLI::App& app) {
  auto args = std::make_shared<ConvertArgs>();
  CLI::App* cmd = app.add_subcommand(
      "convert", "write a sequence (TUM, OMD) in the TUM layout, for evo and the TUM tools");
  cmd->add_option("--dataset", args->dataset, "sequence folder")->required();
  cmd->add_option("--layout", args->layout, "its layout: auto (by its files), tum, omd, bonn")
      ->check(CLI::IsMember({"auto", "tum", "omd", "bonn"}));
  cmd->add_option("--config", args->config,
                  "camera config (default: OMD kalibr.yaml's colour camera with millimetre "
                  "depth; TUM: the folder's camera.yaml)");
  cmd->add_option("--to", args->to, "output layout")->check(CLI::IsMember({"tum"}));
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_flag("--overwrite", args->overwrite, "replace an existing output folder");
  cmd->callback([args] { Convert(*args); });
}

}  // namespace sdoslam
