#pragma once

#include <string>
#include <vector>

#include "sdoslam/apps/run_command.h"

namespace sdoslam {

// `sdoslam bench --sequences ... --modes ...`: the paper's table. Every sequence is run in every
// mode `runs` times; each (sequence, mode) becomes one row of a Markdown table.
struct BenchMatrixArgs {
  // Each item is a built-in synthetic sequence, synth:<scenario>[:<motion>] (without a motion,
  // the scenario's own), rendered once into `work` with `frames` frames, or a dataset folder.
  std::vector<std::string> sequences;
  std::vector<std::string> modes = {"conventional", "sdo", "oracle"};
  std::string config;  // for the dataset folders; default: <folder>/camera.yaml
  std::string table;   // also write the table here (Markdown); empty: print it only
  std::string work = "sdoslam_bench";
  int frames = 150;
  int runs = 5;
  bool threaded = false;
  bool camera_rate = false;  // RunOptions::camera_rate
  RunOverrides overrides;    // the front end's backends and the check; the mode is per row
};

// Checks every item before the first run (an unknown mode or scenario, a missing folder or config
// is an Error naming the item), then runs the matrix and prints the table.
void RunBenchMatrix(const BenchMatrixArgs& args);

// The nearest-rank percentile (q in [0, 1]) of `values`; 0 for none.
double Percentile(std::vector<double> values, double q);

}  // namespace sdoslam
