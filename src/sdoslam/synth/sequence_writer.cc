#include "sdoslam/synth/sequence_writer.h"

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"

namespace sdoslam::synth {
namespace {

std::string Stamp(double t) {
  char b[64];
  std::snprintf(b, sizeof(b), "%.6f", t);
  return b;
}

void WriteImage(const std::filesystem::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw Error("cannot write " + path.string());
}

// " tx ty tz qx qy qz qw" of a pose.
std::string PoseFields(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Vector3d p = T.translation();
  char b[256];
  std::snprintf(b, sizeof(b), " %.9f %.9f %.9f %.9f %.9f %.9f %.9f", p.x(), p.y(), p.z(), q.x(),
                q.y(), q.z(), q.w());
  return b;
}

}  // namespace

SequenceWriter::SequenceWriter(std::filesystem::path out, bool overwrite, const std::string& title,
                               std::vector<std::filesystem::path> inputs)
    : out_(std::move(out)) {
  OutputFolderOptions options;
  options.kind = kSyntheticSequenceKind;
  options.overwrite = overwrite;
  options.inputs = std::move(inputs);
  folder_ = std::make_unique<OutputFolder>(out_, options);
  staging_ = folder_->staging();
  for (const char* sub : {"rgb", "depth", "instance", "dynamic"}) {
    std::filesystem::create_directories(staging_ / sub);
  }
  rgb_list_ = "# color images\n# sdoslam synth " + title + "\n# timestamp filename\n";
  depth_list_ = "# depth maps\n# sdoslam synth " + title + "\n# timestamp filename\n";
  object_poses_ = "# timestamp object_id tx ty tz qx qy qz qw (world frame)\n";
}

void SequenceWriter::AddFrame(double stamp_value, double t, double dt, const SensorFrame& frame,
                              const cv::Mat& instance, const Eigen::Isometry3d& T_world_camera,
                              const Scene& scene) {
  // Ctrl-C between frames: the staged frames go (OutputFolder), an earlier `out` stays.
  if (InterruptHandler::Requested()) throw Interrupted();
  const std::string stamp = Stamp(stamp_value);
  cv::Mat dynamic = cv::Mat::zeros(instance.size(), CV_8UC1);
  nlohmann::json frame_detections = nlohmann::json::array();
  for (const SceneObject& object : scene.objects) {
    const cv::Mat mask = instance == object.id;
    // A thing of a known movable class (a person) is dynamic whether it moves or not, as the
    // paper's known classes are: one standing still now may walk off with the points mapped on
    // it. Things of no class are dynamic while they move.
    const bool dynamic_now = !object.class_name.empty() || object.MovesBetween(t - dt, t) ||
                             object.MovesBetween(t, t + dt);
    if (dynamic_now) dynamic.setTo(255, mask);
    object_poses_ += stamp + " " + std::to_string(object.id) + PoseFields(object.pose_at(t)) + "\n";
    const int pixels = cv::countNonZero(mask);
    if (!object.class_name.empty() && pixels >= 100) {
      const cv::Rect box = cv::boundingRect(mask);
      frame_detections.push_back({{"class", object.class_name},
                                  {"score", 1.0},
                                  {"box", {box.x, box.y, box.width, box.height}},
                                  {"instance", object.id}});
    }
  }
  const double fraction = cv::countNonZero(dynamic) / static_cast<double>(dynamic.total());
  summary_.frames += 1;
  summary_.dynamic_fraction_mean += fraction;  // divided by the count in Finish()
  summary_.dynamic_fraction_max = std::max(summary_.dynamic_fraction_max, fraction);

  WriteImage(staging_ / "rgb" / (stamp + ".png"), frame.bgr);
  WriteImage(staging_ / "depth" / (stamp + ".png"), frame.depth);
  WriteImage(staging_ / "instance" / (stamp + ".png"), instance);
  WriteImage(staging_ / "dynamic" / (stamp + ".png"), dynamic);
  rgb_list_ += stamp + " rgb/" + stamp + ".png\n";
  depth_list_ += stamp + " depth/" + stamp + ".png\n";
  ground_truth_.push_back({stamp_value, T_world_camera});
  detections_.push_back(
      {{"timestamp", stamp}, {"rgb", "rgb/" + stamp + ".png"}, {"detections", frame_detections}});
}

SequenceSummary SequenceWriter::Finish(const CameraOptions& camera, const Scene& scene,
                                       const YAML::Emitter& info) {
  if (summary_.frames == 0) throw Error("no frame to write to " + out_.string());
  WriteFileAtomically(staging_ / "rgb.txt", [&](std::ostream& o) { o << rgb_list_; });
  WriteFileAtomically(staging_ / "depth.txt", [&](std::ostream& o) { o << depth_list_; });
  WriteTumTrajectory(staging_ / "groundtruth.txt", ground_truth_);
  WriteFileAtomically(staging_ / "object_poses.txt", [&](std::ostream& o) { o << object_poses_; });
  WriteFileAtomically(staging_ / "detections.json", [&](std::ostream& o) {
    o << nlohmann::json{{"format", "sdoslam detections v1"},
                        {"box_format", "x y width height, pixels"},
                        {"frames", detections_}}
             .dump(1)
      << '\n';
  });
  nlohmann::json objects = nlohmann::json::array();
  for (const SceneObject& object : scene.objects) {
    objects.push_back({{"id", object.id},
                       {"name", object.name},
                       {"class", object.class_name.empty() ? nlohmann::json(nullptr)
                                                           : nlohmann::json(object.class_name)},
                       {"known", !object.class_name.empty()}});
  }
  WriteFileAtomically(staging_ / "objects.json", [&](std::ostream& o) {
    o << nlohmann::json{{"static_structure_id", 0}, {"objects", objects}}.dump(2) << '\n';
  });
  YAML::Emitter camera_yaml;
  camera_yaml << YAML::BeginMap;
  WriteCameraOptions(camera, &camera_yaml);
  camera_yaml << YAML::EndMap;
  WriteFileAtomically(staging_ / "camera.yaml",
                      [&](std::ostream& o) { o << camera_yaml.c_str() << '\n'; });
  WriteFileAtomically(staging_ / "sequence.yaml",
                      [&](std::ostream& o) { o << info.c_str() << '\n'; });

  folder_->Commit();
  SequenceSummary summary = summary_;
  summary.dynamic_fraction_mean /= summary.frames;
  return summary;
}

}  // namespace sdoslam::synth
