#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "sdoslam/runner/run_on_dataset.h"

namespace sdoslam {

// `sdoslam run`: SLAM on an RGB-D sequence in the TUM layout.
void AddRunCommand(CLI::App& app);

// Command-line choices that override a run's config file, shared by `run` and `bench`: the
// mode, the front end's backends and the consistency check. Empty: keep the config's.
struct RunOverrides {
  std::string mode, segmenter, segmenter_model, detector, detector_model, flow, flow_model;
  std::string consistency;  // on | off
  void AddTo(CLI::App* cmd);
  // Applies the overrides and checks the resulting front-end options.
  void ApplyTo(RunOptions* run) const;
};

}  // namespace sdoslam
