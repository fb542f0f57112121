#include "sdoslam/apps/bench_matrix.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/memory.h"
#include "sdoslam/core/text_file.h"
#include "sdoslam/runner/run_on_dataset.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sequence.h"

#ifdef __GLIBC__     // defined by the C library's headers above
#include <malloc.h>  // malloc_trim
#endif

namespace sdoslam {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5)];
}

namespace {

namespace fs = std::filesystem;

constexpr char kSynthPrefix[] = "synth:";

// One sequence of the matrix, resolved and checked before anything runs.
struct MatrixSequence {
  std::string label;  // the table's sequence cell
  fs::path dataset;
  std::optional<synth::SynthOptions> render;  // a built-in sequence: rendered into `dataset` once
  RunOptions base;       // camera, SLAM and front-end options; mode and out are set per run
  std::string out_name;  // the folder of its runs under <work>/matrix
};

std::vector<std::string> Split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  size_t begin = 0;
  for (size_t end; (end = text.find(separator, begin)) != std::string::npos; begin = end + 1)
    parts.push_back(text.substr(begin, end - begin));
  parts.push_back(text.substr(begin));
  return parts;
}

// Letters, digits, '.', '_' and '-' only: a folder name from any label.
std::string FolderName(const std::string& text) {
  std::string name = text;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-') c = '_';
  }
  return name;
}

Error ItemError(const std::string& option, const std::string& item, const std::string& what) {
  return Error(fmt::format("{} item '{}': {}", option, item, what));
}

MatrixSequence ResolveSynthetic(const std::string& item, const BenchMatrixArgs& args) {
  const std::vector<std::string> parts = Split(item.substr(std::strlen(kSynthPrefix)), ':');
  if (parts.size() > 2)
    throw ItemError("--sequences", item, "expected synth:<scenario>[:<motion>]");
  synth::SynthOptions render;
  render.scenario = parts[0];
  render.frames = args.frames;
  try {
    // Unknown names throw here, before anything is rendered or run.
    const synth::Scenario scenario = synth::MakeScenario(render.scenario, 1.0);
    render.motion = parts.size() == 2 ? synth::ParseCameraMotion(parts[1]) : scenario.motion;
  } catch (const Error& e) {
    throw ItemError("--sequences", item, e.what());
  }
  const std::string motion = synth::ToString(*render.motion);
  MatrixSequence s;
  s.label = fmt::format("synth:{}:{}", render.scenario, motion);
  // The single-sequence bench names its renders alike, so the two share them.
  s.dataset = fs::path(args.work) / fmt::format("{}_{}_{}", render.scenario, motion, render.frames);
  s.render = render;
  s.base.camera = synth::SyntheticCamera();
  s.out_name = FolderName(render.scenario + "_" + motion);
  return s;
}

MatrixSequence ResolveDataset(const std::string& item, const BenchMatrixArgs& args) {
  const fs::path folder = item;
  if (!fs::exists(folder)) {
    throw ItemError("--sequences", item,
                    "no such folder (an item is a dataset folder or synth:<scenario>[:<motion>])");
  }
  if (!fs::is_directory(folder)) throw ItemError("--sequences", item, "not a folder");
  fs::path config = args.config;
  if (config.empty()) {
    config = folder / "camera.yaml";
    if (!fs::exists(config)) {
      throw ItemError("--sequences", item,
                      "no config: give --config, or put a camera.yaml into the folder");
    }
  }
  MatrixSequence s;
  try {
    s.base = LoadRunConfig(config);  // its mode: is replaced by each row's
  } catch (const Error& e) {
    throw ItemError("--sequences", item, e.what());
  }
  s.label = item;
  s.dataset = folder;
  s.out_name = FolderName(fs::weakly_canonical(fs::absolute(folder)).filename().string());
  return s;
}

std::vector<MatrixSequence> ResolveSequences(const BenchMatrixArgs& args) {
  if (args.sequences.empty()) throw Error("--sequences: no sequence given");
  std::vector<MatrixSequence> sequences;
  std::set<std::string> seen;
  bool any_dataset = false;
  for (const std::string& item : args.sequences) {
    if (item.empty()) throw Error("--sequences: an empty item (a stray comma?)");
    const bool synthetic = item.rfind(kSynthPrefix, 0) == 0;
    MatrixSequence s = synthetic ? ResolveSynthetic(item, args) : ResolveDataset(item, args);
    any_dataset = any_dataset || !synthetic;
    if (!seen.insert(s.label).second) throw ItemError("--sequences", item, "listed twice");
    try {
      args.overrides.ApplyTo(&s.base);
    } catch (const Error& e) {
      throw ItemError("--sequences", item, e.what());
    }
    s.base.slam.sequential = !args.threaded;
    s.base.camera_rate = args.camera_rate;
    s.base.dataset = s.dataset;
    s.out_name = fmt::format("{:02}_{}", sequences.size() + 1, s.out_name);
    sequences.push_back(std::move(s));
  }
  if (!args.config.empty() && !any_dataset) {
    throw Error("--config is for the dataset folders in --sequences, and there is none");
  }
  return sequences;
}

std::vector<RunMode> ResolveModes(const std::vector<std::string>& names) {
  if (names.empty()) throw Error("--modes: no mode given");
  std::vector<RunMode> modes;
  for (const std::string& name : names) {
    if (name.empty()) throw Error("--modes: an empty item (a stray comma?)");
    RunMode mode;
    try {
      mode = ParseRunMode(name);  // its message names the item and the known modes
    } catch (const Error& e) {
      throw Error(std::string("--modes: ") + e.what());
    }
    if (std::find(modes.begin(), modes.end(), mode) != modes.end())
      throw ItemError("--modes", name, "listed twice");
    modes.push_back(mode);
  }
  return modes;
}

// Per-frame stage times, read back from the run's frames.csv: the run's summary keeps only their
// medians, and the table wants p95 as well.
struct FrameTimes {
  std::vector<double> front_end_ms;
  std::vector<double> tracking_ms;  // features + tracking
};

FrameTimes ReadFrameTimes(const fs::path& csv) {
  FrameTimes times;
  std::vector<std::string> header;
  size_t front_end = 0, features = 0, tracking = 0;
  ForEachDataLine(csv, [&](int line, const std::vector<std::string>& tokens) {
    std::string text;  // the reader splits at blanks; frames.csv separates by commas
    for (const std::string& token : tokens) text += (text.empty() ? "" : " ") + token;
    const std::vector<std::string> fields = Split(text, ',');
    if (header.empty()) {
      header = fields;
      auto column = [&](const char* name) {
        const auto it = std::find(header.begin(), header.end(), name);
        if (it == header.end()) throw Error(Where(csv, line) + "no column " + name);
        return static_cast<size_t>(it - header.begin());
      };
      front_end = column("front_end_ms");
      features = column("features_ms");
      tracking = column("tracking_ms");
      return;
    }
    if (fields.size() != header.size()) {
      throw Error(Where(csv, line) +
                  fmt::format("{} fields, the header has {}", fields.size(), header.size()));
    }
    times.front_end_ms.push_back(ParseDouble(fields[front_end], csv, line, "front_end_ms"));
    times.tracking_ms.push_back(ParseDouble(fields[features], csv, line, "features_ms") +
                                ParseDouble(fields[tracking], csv, line, "tracking_ms"));
  });
  return times;
}

// What one run measured.
struct RunMeasurement {
  std::optional<double> ate_mm, rte_mm;  // none without ground truth (or too short for RTE)
  double front_end_median = 0, front_end_p95 = 0;
  double tracking_median = 0, tracking_p95 = 0;
  std::optional<double> mapping_median, mapping_p95;  // none when no keyframe was mapped
  double fps = 0, latency_ms = 0;
  size_t peak_bytes = 0;
  bool peak_from_kernel = false;  // false: the largest per-frame sample (see MeasureRun)
  size_t tracked = 0, frames = 0;
};

RunMeasurement MeasureRun(RunOptions run) {
  RunMeasurement m;
  // The table has no mask scores, and scoring masks would put evaluation work inside the timed
  // frame loop of sdo and oracle rows only.
  run.evaluate_masks = false;
  // Peak memory. All runs of the matrix share this process, so the process's lifetime peak
  // (getrusage's ru_maxrss) would hand every row the largest earlier row's peak. Instead the
  // heap that earlier runs freed is given back to the system first (the allocator keeps it
  // otherwise, and it would count as this run's), the kernel's peak is reset to the resident
  // size now, and read when the run is over: the run's own peak, including what the process held
  // before it (code, libraries, caches), not missing short spikes. Where the kernel cannot reset
  // it, the resident size is sampled after every frame instead: a lower bound of the peak.
#ifdef __GLIBC__
  malloc_trim(0);
#endif
  m.peak_from_kernel = ResetPeakResidentBytes();
  size_t sampled_peak = ResidentBytes();
  if (!m.peak_from_kernel) {
    run.after_frame = [&sampled_peak](const TrackingResult&, const System&) {
      sampled_peak = std::max(sampled_peak, ResidentBytes());
    };
  }
  const RunSummary s = RunOnDataset(run);
  m.peak_bytes = m.peak_from_kernel ? PeakResidentBytes() : std::max(sampled_peak, ResidentBytes());
  // The frame loop's wall-clock time (reading frames, front end, tracking, mapping in its thread,
  // the wait for its queue at the end; not the one-off setup, writing and scoring): the rate a
  // camera could be fed at. Latency: from a frame's reading to its pose, less its wait for
  // tracking (FrameOutput::latency_ms).
  m.fps = s.wall_ms_per_frame > 0 ? 1000.0 / s.wall_ms_per_frame : 0;
  m.latency_ms = s.median_latency_ms;
  m.tracked = s.tracked;
  m.frames = s.frames;
  if (s.evaluation) {
    m.ate_mm = 1000 * s.evaluation->ate.translation.rmse;
    if (s.evaluation->rte) m.rte_mm = 1000 * s.evaluation->rte->translation.rmse;
  }
  const FrameTimes times = ReadFrameTimes(run.out / "frames.csv");
  m.front_end_median = ComputeErrorStats(times.front_end_ms).median;
  m.front_end_p95 = Percentile(times.front_end_ms, 0.95);
  m.tracking_median = ComputeErrorStats(times.tracking_ms).median;
  m.tracking_p95 = Percentile(times.tracking_ms, 0.95);
  std::vector<double> mapping_ms;
  for (const MappingRecord& r : s.mapping) mapping_ms.push_back(r.ms);
  if (!mapping_ms.empty()) {
    m.mapping_median = ComputeErrorStats(mapping_ms).median;
    m.mapping_p95 = Percentile(mapping_ms, 0.95);
  }
  return m;
}

struct MatrixRow {
  std::string sequence;
  RunMode mode = RunMode::kConventional;
  std::string not_applicable;  // why the row was not run; empty when it was
  std::vector<RunMeasurement> runs;
};

double MedianOf(const std::vector<double>& values) { return ComputeErrorStats(values).median; }

// "median (min–max)" of the runs' values; the range only when there are several; "–" for none.
std::string MedianAndRange(const std::vector<double>& values) {
  if (values.empty()) return "–";
  std::string cell = fmt::format("{:.1f}", MedianOf(values));
  if (values.size() > 1) {
    const auto [low, high] = std::minmax_element(values.begin(), values.end());
    cell += fmt::format(" ({:.1f}–{:.1f})", *low, *high);
  }
  return cell;
}

// "median / p95": the median over runs of each run's median and of each run's p95.
std::string MedianAndP95(const std::vector<double>& medians, const std::vector<double>& p95s) {
  if (medians.empty()) return "–";
  return fmt::format("{:.1f} / {:.1f}", MedianOf(medians), MedianOf(p95s));
}

std::string MarkdownCell(std::string text) {
  for (size_t at = 0; (at = text.find('|', at)) != std::string::npos; at += 2)
    text.replace(at, 1, "\\|");
  return text;
}

std::string FormatRow(const MatrixRow& row) {
  std::vector<std::string> cells = {MarkdownCell(row.sequence), ToString(row.mode)};
  if (!row.not_applicable.empty()) {
    cells.resize(11, "n/a");
  } else {
    std::vector<double> ate, rte, front_med, front_p95, tracking_med, tracking_p95, mapping_med,
        mapping_p95, fps, latency;
    size_t peak = 0, tracked_min = SIZE_MAX, tracked_max = 0, frames = 0;
    for (const RunMeasurement& m : row.runs) {
      if (m.ate_mm) ate.push_back(*m.ate_mm);
      if (m.rte_mm) rte.push_back(*m.rte_mm);
      front_med.push_back(m.front_end_median);
      front_p95.push_back(m.front_end_p95);
      tracking_med.push_back(m.tracking_median);
      tracking_p95.push_back(m.tracking_p95);
      if (m.mapping_median) {
        mapping_med.push_back(*m.mapping_median);
        mapping_p95.push_back(*m.mapping_p95);
      }
      fps.push_back(m.fps);
      latency.push_back(m.latency_ms);
      peak = std::max(peak, m.peak_bytes);
      tracked_min = std::min(tracked_min, m.tracked);
      tracked_max = std::max(tracked_max, m.tracked);
      frames = std::max(frames, m.frames);
    }
    const bool front_end = row.mode == RunMode::kSdo;  // the other modes have none: not 0 ms
    cells.push_back(MedianAndRange(ate));
    cells.push_back(MedianAndRange(rte));
    cells.push_back(front_end ? MedianAndP95(front_med, front_p95) : "–");
    cells.push_back(MedianAndP95(tracking_med, tracking_p95));
    cells.push_back(MedianAndP95(mapping_med, mapping_p95));
    cells.push_back(fmt::format("{:.1f}", MedianOf(fps)));
    cells.push_back(fmt::format("{:.1f}", MedianOf(latency)));
    cells.push_back(fmt::format("{:.0f}", static_cast<double>(peak) / (1 << 20)));
    cells.push_back(tracked_min == tracked_max
                        ? fmt::format("{}/{}", tracked_max, frames)
                        : fmt::format("{}–{}/{}", tracked_min, tracked_max, frames));
  }
  std::string line = "|";
  for (const std::string& cell : cells) line += " " + cell + " |";
  return line + "\n";
}

std::string FormatTable(const BenchMatrixArgs& args, const std::vector<MatrixRow>& rows,
                        size_t baseline_bytes) {
  bool peak_from_kernel = true, any_not_applicable = false;
  for (const MatrixRow& row : rows) {
    any_not_applicable = any_not_applicable || !row.not_applicable.empty();
    for (const RunMeasurement& m : row.runs)
      peak_from_kernel = peak_from_kernel && m.peak_from_kernel;
  }
  std::string text = fmt::format(
      "sdoslam bench: {} run{} per row, {} mapping{}. ATE and RTE (over 1 s): median over runs "
      "(min–max). Stage times: median over runs of each run's median / p95, per frame (front "
      "end; features + tracking) or per keyframe (local mapping).\n\n",
      args.runs, args.runs == 1 ? "" : "s", args.threaded ? "threaded" : "sequential",
      args.camera_rate ? ", frames read at the camera's rate" : "");
  text +=
      "| sequence | mode | ATE RMSE mm | RTE RMSE mm | front end ms | features + tracking ms | "
      "mapping ms/keyframe | fps | latency ms | peak RSS MB | tracked/frames |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MatrixRow& row : rows) text += FormatRow(row);
  text += fmt::format(
      "\nfps: frames / wall-clock seconds of the frame loop (reading, front end, tracking, "
      "mapping and the wait for its queue at the end; time in which threads overlap counts "
      "once), median over runs; latency: median time from the start of a frame's reading to its "
      "pose, less the time it waited for tracking to finish the frame before (a run that reads "
      "ahead keeps that queue full; a camera the system keeps up with does not). peak RSS (MB "
      "of 2^20 bytes): the largest run's {}; the runs share one "
      "process, which "
      "held {:.0f} MB before the first.{}\n",
      peak_from_kernel
          ? "peak resident memory (the kernel's high-water mark, reset before each run)"
          : "resident memory sampled after each frame (a lower bound of the peak)",
      static_cast<double>(baseline_bytes) / (1 << 20),
      any_not_applicable ? " n/a: oracle needs the ground-truth dynamic masks (a dynamic/ folder)."
                         : "");
  return text;
}

}  // namespace

void RunBenchMatrix(const BenchMatrixArgs& args) {
  // Every item is checked before the first rendering or run: a typo in the last item must not
  // cost the time of the first ones.
  const std::vector<RunMode> modes = ResolveModes(args.modes);
  std::vector<MatrixSequence> sequences = ResolveSequences(args);
  if (!args.table.empty()) {
    // Likewise a --table that cannot be written (it is written, atomically, at the end).
    const fs::path folder = fs::absolute(args.table).parent_path();
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec || access(folder.c_str(), W_OK) != 0)
      throw IoError("--table " + args.table + ": cannot write into " + folder.string());
  }
  const size_t baseline_bytes = ResidentBytes();
  std::vector<MatrixRow> rows;
  const fs::path runs_folder = fs::path(args.work) / "matrix";
  for (const MatrixSequence& sequence : sequences) {
    if (sequence.render && !fs::exists(sequence.dataset / "groundtruth.txt")) {
      std::cout << fmt::format("rendering {} frames of {}...\n", sequence.render->frames,
                               sequence.label);
      synth::WriteSequence(*sequence.render, sequence.dataset, /*overwrite=*/true);
    }
    for (const RunMode mode : modes) {
      MatrixRow& row = rows.emplace_back();
      row.sequence = sequence.label;
      row.mode = mode;
      if (mode == RunMode::kOracle && !fs::is_directory(sequence.dataset / "dynamic")) {
        row.not_applicable = "no ground-truth dynamic masks";
        std::cout << fmt::format("{}, {}: n/a (no dynamic/ folder of ground-truth masks)\n",
                                 sequence.label, ToString(mode));
        continue;
      }
      for (int run = 0; run < args.runs; ++run) {
        RunOptions options = sequence.base;
        options.mode = mode;
        options.out = runs_folder / sequence.out_name / ToString(mode) / fmt::format("run{}", run);
        try {
          row.runs.push_back(MeasureRun(options));
        } catch (const IoError& e) {
          throw IoError(fmt::format("{}, mode {}: {}", sequence.label, ToString(mode), e.what()));
        } catch (const Error& e) {
          throw Error(fmt::format("{}, mode {}: {}", sequence.label, ToString(mode), e.what()));
        }
        const RunMeasurement& m = row.runs.back();
        std::cout << fmt::format("{}, {}, run {}/{}: {}{:.1f} fps, {}/{} tracked\n", sequence.label,
                                 ToString(mode), run + 1, args.runs,
                                 m.ate_mm ? fmt::format("ATE {:.1f} mm, ", *m.ate_mm) : "", m.fps,
                                 m.tracked, m.frames);
      }
    }
  }
  const std::string table = FormatTable(args, rows, baseline_bytes);
  std::cout << fmt::format("\nruns in {}/\n\n", runs_folder.string()) << table;
  if (!args.table.empty()) {
    WriteFileAtomically(args.table, [&](std::ostream& out) { out << table; });
    std::cout << "wrote " << args.table << '\n';
  }
}

}  // namespace sdoslam
