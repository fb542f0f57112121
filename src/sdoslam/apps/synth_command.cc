#include "sdoslam/apps/synth_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <csignal>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>

#include "sdoslam/apps/exit_codes.h"
#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"
#include "sdoslam/io/omd.h"
#include "sdoslam/io/output_folder.h"
#include "sdoslam/synth/real_background.h"
#include "sdoslam/synth/sequence.h"
#include "sdoslam/synth/sequence_writer.h"

namespace sdoslam {
namespace {

struct SynthArgs {
  std::string scenario = "walking_xyz";
  std::string out;
  std::string motion;
  int frames = 300;
  unsigned seed = 1;
  bool no_noise = false;
  int motion_blur = 0;
  int supersample = 1;
  double readout = 0;
  bool exposure_changes = false;
  bool overwrite = false;
  bool list = false;
  std::string contact_sheet;
  std::string background;
  std::string camera;
  bool forward_backward = false;
  bool frames_given = false;
  std::string layout = "tum";
  double depth_factor = 5000.0;
};

// `--background`: the scenario's objects rendered into a real recording.
void RunBackgroundSynth(const SynthArgs& args) {
  synth::BackgroundSynthOptions options;
  options.background = args.background;
  options.scenario = args.scenario;
  std::filesystem::path camera_file = args.camera;
  if (camera_file.empty()) camera_file = options.background / "camera.yaml";
  if (!std::filesystem::exists(camera_file)) {
    throw Error(camera_file.string() +
                " does not exist: give the recording's camera with --camera (e.g. "
                "configs/tum_fr2.yaml)");
  }
  options.camera = LoadCameraConfig(camera_file);
  // Played backward, a rolling shutter's rows run against the camera's motion: no one readout
  // fits both halves, so the play's camera.yaml says global shutter.
  if (args.forward_backward) options.camera.readout_s = 0;
  options.forward_backward = args.forward_backward;
  options.max_frames = args.frames_given ? args.frames : 0;
  options.seed = args.seed;
  options.sensor.enabled = !args.no_noise;
  options.sensor.motion_blur_samples = args.motion_blur;
  const synth::SequenceSummary s =
      synth::WriteBackgroundSequence(options, args.out, args.overwrite);
  std::cout << fmt::format(
      "wrote {} frames of '{}' over {}{} to {} in {:.1f} s ({:.1f} ms/frame rendering)\n"
      "people and moving objects cover {:.0f} % of the image on average, {:.0f} % at most\n",
      s.frames, args.scenario, args.background,
      args.forward_backward ? " (forward, then backward)" : "", args.out, s.total_seconds,
      1000.0 * s.render_seconds / s.frames, 100.0 * s.dynamic_fraction_mean,
      100.0 * s.dynamic_fraction_max);
}

void RunSynth(const SynthArgs& args) {
  if (args.list) {
    for (const auto& name : synth::ScenarioNames()) {
      const synth::Scenario s = synth::MakeScenario(name, 10.0);
      std::cout << fmt::format("{:<22} camera {:<14} {}\n", name, synth::ToString(s.motion),
                               s.description);
    }
    std::cout << "over a real recording (--background): ";
    for (const auto& name : synth::BackgroundScenarioNames()) std::cout << name << ' ';
    std::cout << '\n';
    std::cout << "camera motions (--motion): ";
    for (const auto& m : synth::CameraMotionNames()) std::cout << m << ' ';
    std::cout << '\n';
    return;
  }
  if (!args.contact_sheet.empty()) {
    const cv::Mat sheet = synth::ContactSheet(synth::ScenarioNames(), 9.0);
    WriteFileAtomically(args.contact_sheet, [&](const std::filesystem::path& tmp) {
      return cv::imwrite(tmp.string(), sheet);
    });
    std::cout << "wrote " << args.contact_sheet << '\n';
    if (args.out.empty()) return;
  }
  if (args.out.empty()) throw Error("--out is required (the folder to write the sequence to)");
  if (!args.background.empty()) {
    if (!args.motion.empty()) throw Error("--motion does not apply with --background");
    if (args.exposure_changes) throw Error("--exposure-changes does not apply with --background");
    if (args.supersample != 1) throw Error("--supersample does not apply with --background");
    if (args.readout != 0)
      throw Error("--readout does not apply with --background (the recording has its own shutter)");
    if (args.layout != "tum" || args.depth_factor != 5000.0)
      throw Error("--layout and --depth-factor do not apply with --background");
    RunBackgroundSynth(args);
    return;
  }
  if (!args.camera.empty() || args.forward_backward) {
    throw Error("--camera and --forward-backward apply only with --background");
  }
  synth::SynthOptions options;
  options.scenario = args.scenario;
  if (!args.motion.empty()) options.motion = synth::ParseCameraMotion(args.motion);
  options.frames = args.frames;
  options.seed = args.seed;
  options.sensor.enabled = !args.no_noise;
  options.sensor.motion_blur_samples = args.motion_blur;
  options.sensor.supersampling = args.supersample;
  options.sensor.readout_time = args.readout;
  if (args.readout != 0 && args.layout == "omd")
    throw Error("--readout applies only to the TUM layout");
  if (const double frame_s = 1.0 / synth::SyntheticCamera().fps; args.readout > frame_s)
    throw Error(fmt::format("--readout must be at most one frame ({:g} s), got {:g}", frame_s,
                            args.readout));
  options.sensor.exposure_changes = args.exposure_changes;
  options.depth_factor = args.depth_factor;
  synth::SequenceSummary s;
  if (args.layout == "omd") {
    // Rendered in the TUM layout into a hidden folder of its own beside `out`, then rewritten
    // as an OMD segment; an earlier `out` is replaced only once the segment is complete.
    OutputFolderOptions omd_folder;
    omd_folder.kind = kOmdSegmentKind;
    omd_folder.overwrite = args.overwrite;
    CheckOutputFolder(args.out, omd_folder);  // before the rendering, not after it
    const std::filesystem::path out = std::filesystem::path(args.out).lexically_normal();
    const std::filesystem::path tum =
        (out.has_parent_path() ? out.parent_path() : std::filesystem::path(".")) /
        fmt::format(".{}.sdoslam-tum-{}", out.filename().string(), ::getpid());
    s = synth::WriteSequence(options, tum);
    try {
      WriteOmdFromTum(tum, args.out, OmdWriteOptions::ExampleApparatus(), args.overwrite);
    } catch (...) {
      RemoveOutputFolder(tum, synth::kSyntheticSequenceKind);
      throw;
    }
    RemoveOutputFolder(tum, synth::kSyntheticSequenceKind);
  } else {
    s = synth::WriteSequence(options, args.out, args.overwrite);
  }
  std::cout << fmt::format(
      "wrote {} frames of '{}' to {} in {:.1f} s ({:.1f} ms/frame rendering)\n"
      "people and moving objects cover {:.0f} % of the image on average, {:.0f} % at most\n",
      s.frames, args.scenario, args.out, s.total_seconds, 1000.0 * s.render_seconds / s.frames,
      100.0 * s.dynamic_fraction_mean, 100.0 * s.dynamic_fraction_max);
}

}  // namespace

void AddSynthCommand(CLI::App& app) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd =
      app.add_subcommand("synth", "render a synthetic dynamic RGB-D sequence with ground truth");
  cmd->add_option("--scenario", args->scenario, "scenario name (--list shows them)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "output folder (TUM layout plus masks and detections)");
  cmd->add_option("--motion", args->motion,
                  "override the camera motion: static, xyz, rpy, halfsphere, unconstrained, loop");
  cmd->add_option("--frames", args->frames,
                  "number of frames at 30 Hz (with --background: recording frames used; default "
                  "all)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str()
      ->each([args](const std::string&) { args->frames_given = true; });
  cmd->add_option("--seed", args->seed, "seed of the sensor noise")->capture_default_str();
  cmd->add_flag("--no-noise", args->no_noise,
                "perfect sensor: no image or depth noise, no missing depth");
  cmd->add_option("--motion-blur", args->motion_blur, "renderings averaged per frame (0: no blur)")
      ->check(CLI::Range(0, 64));
  cmd->add_option("--supersample", args->supersample,
                  "rays per pixel side for the colour image, averaged over the pixel as a camera "
                  "does (1: one ray through the centre, whose sharp texture edges alias)")
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  cmd->add_option("--readout", args->readout,
                  "rolling shutter: seconds from the top row's exposure to the bottom's, the "
                  "middle row at the frame's time (0: global shutter); camera.yaml gets it as "
                  "readout_s")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--exposure-changes", args->exposure_changes, "let the exposure drift");
  cmd->add_option("--background", args->background,
                  fmt::format("render the scenario's moving objects into this real static "
                              "recording (TUM layout with groundtruth.txt); scenarios: {}",
                              fmt::join(synth::BackgroundScenarioNames(), ", ")));
  cmd->add_option("--camera", args->camera,
                  "camera config of the --background recording (default: its camera.yaml)");
  cmd->add_flag("--forward-backward", args->forward_backward,
                "play the --background recording forward, then backward");
  cmd->add_option("--layout", args->layout,
                  "tum (default: rgb/, depth/, lists, ground truth, masks, detections) or omd (an "
                  "Oxford Multi-motion segment: rgbd/, vicon.csv with the apparatus and objects "
                  "at 200 Hz, vicon.yaml and kalibr.yaml with a non-trivial camera chain; no "
                  "masks)")
      ->check(CLI::IsMember({"tum", "omd"}))
      ->capture_default_str();
  cmd->add_option("--depth-factor", args->depth_factor,
                  "raw depth units per metre in the depth PNGs (TUM 5000; 1000 = millimetres, "
                  "as OMD and Bonn)")
      ->check(CLI::Range(100.0, 8000.0))
      ->capture_default_str();
  cmd->add_flag("--overwrite", args->overwrite, "replace an existing output folder");
  cmd->add_flag("--list", args->list, "list the scenarios and camera motions");
  cmd->add_option("--contact-sheet", args->contact_sheet,
                  "write a PNG with frames of every scenario");
  cmd->callback([args] {
    InterruptHandler interrupts(
        "\nsdoslam: interrupted; removing the frames written so far, the output folder stays as "
        "it was (interrupt again to stop at once)\n");
    const auto exit_code = [] {
      return ExitRequest{InterruptHandler::ReceivedSignal() == SIGTERM ? kExitTerminated
                                                                       : kExitInterrupted};
    };
    try {
      RunSynth(*args);
    } catch (const Interrupted&) {
      std::cout << "interrupted: nothing written, " << args->out << " is as it was\n";
      throw exit_code();
    }
    if (InterruptHandler::Requested()) {
      // The signal came after the last frame: the sequence was finished and is in place whole.
      std::cout << "interrupted after the last frame: " << args->out << " is complete\n";
      throw exit_code();
    }
  });
}

}  // namespace sdoslam
