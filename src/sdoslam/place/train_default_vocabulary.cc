// sdoslam_train_default_vocabulary OUT: trains the vocabulary that is built into the library
// (place/default_vocabulary.h) and writes it to OUT. Run by the build, never at run time.
//
// What it is trained on: ORB features, extracted exactly as runs extract them (OrbExtractor at
// the default OrbOptions, from the grey image), of 200 frames rendered with the project's own
// renderer (synth/): the synthetic room (walls, floor, desks, cabinets, shelves, monitors;
// procedural textures) under each of the six camera motions, with the people, swinging boxes and
// carts of eight scenarios in view, 25 frames spread over 24 s of each, with the sensor's image
// noise. Rendering is deterministic and the noise seeded, so the file is the same, byte for byte,
// at every build. VocabularyOptions{} (10^4 words) is the default size.
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <exception>
#include <iostream>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "sdoslam/features/orb_extractor.h"
#include "sdoslam/place/vocabulary.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"

namespace sdoslam {
namespace {

struct TrainingSequence {
  const char* scenario;
  synth::CameraMotion motion;
};

// Every camera motion at least once, every kind of mover in view.
constexpr TrainingSequence kSequences[] = {
    {"static_room", synth::CameraMotion::kXyz},
    {"walking_rpy", synth::CameraMotion::kRpy},
    {"walking_halfsphere", synth::CameraMotion::kHalfsphere},
    {"boxes_unconstrained", synth::CameraMotion::kUnconstrained},
    {"loop", synth::CameraMotion::kLoop},
    {"mixed", synth::CameraMotion::kXyz},
    {"parked_cart", synth::CameraMotion::kHalfsphere},
    {"walking_static", synth::CameraMotion::kStatic},
};
// 200 frames, about 200,000 descriptors: 20 per word. Measured on TUM fr2_desk, 320 frames
// serve no better, and rendering is most of the build-time cost.
constexpr int kFramesPerSequence = 25;
constexpr double kDuration = 24.0;  // seconds: the camera motions' periods are 4-7 s

int Main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: sdoslam_train_default_vocabulary OUT\n";
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  const CameraOptions camera_options = synth::SyntheticCamera();
  const Camera camera(camera_options);
  const OrbExtractor orb(OrbOptions{});
  const int sequences = static_cast<int>(std::size(kSequences));
  std::vector<cv::Mat> descriptors(static_cast<size_t>(sequences * kFramesPerSequence));
  std::vector<synth::Scenario> scenarios;
  for (const TrainingSequence& s : kSequences)
    scenarios.push_back(synth::MakeScenario(s.scenario, kDuration, s.motion));

  // Frames in parallel (each result goes to its own slot: the order of completion does not
  // matter); the renderer parallelises each frame's rows as well.
  tbb::parallel_for(0, static_cast<int>(descriptors.size()), [&](int i) {
    const int s = i / kFramesPerSequence, k = i % kFramesPerSequence;
    const synth::Scenario& scenario = scenarios[static_cast<size_t>(s)];
    const double t = kDuration * k / kFramesPerSequence;
    const synth::RenderedView view = synth::Render(
        scenario.scene, t, synth::CameraPoseAt(scenario.motion, t, kDuration), camera);
    // The sensor's image noise (synth::Sense's 2 grey levels per channel), drawn with OpenCV's
    // generator: Sense also makes the depth image, which would double the time per frame.
    cv::Mat noise(view.colour.size(), CV_32FC3);
    cv::RNG(static_cast<uint64_t>(1000 * s + k + 1)).fill(noise, cv::RNG::NORMAL, 0.0, 2.0);
    cv::Mat bgr, gray;
    cv::Mat(view.colour * 255.0 + noise).convertTo(bgr, CV_8UC3);
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keypoints;
    orb.Extract(gray, &keypoints, &descriptors[static_cast<size_t>(i)]);
  });
  const double render_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const Vocabulary vocabulary = Vocabulary::Train(descriptors, VocabularyOptions{});
  vocabulary.Save(argv[1]);
  std::cout << fmt::format(
      "default vocabulary: {} words (branching {}, depth {}) from {} descriptors of {} rendered "
      "frames; rendering and features {:.1f} s, total {:.1f} s -> {}\n",
      vocabulary.size(), vocabulary.branching(), vocabulary.depth(),
      vocabulary.training_descriptors(), vocabulary.training_images(), render_seconds,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), argv[1]);
  return 0;
}

}  // namespace
}  // namespace sdoslam

int main(int argc, char** argv) {
  try {
    return sdoslam::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "sdoslam_train_default_vocabulary: " << e.what() << '\n';
    return 1;
  }
}
