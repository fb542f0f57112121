#include "sdoslam/objects/object_eval.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/text_file.h"
#include "sdoslam/eval/metrics.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {

void ObjectEvalOptions::Check() const {
  if (!(max_spread_m > 0)) throw Error("max_spread_m must be > 0");
  if (min_rows < 2) throw Error("min_rows must be at least 2");
  if (!(max_ground_truth_gap > 0)) throw Error("max_ground_truth_gap must be > 0");
  if (min_visible_pixels < 1) throw Error("min_visible_pixels must be at least 1");
}

namespace {

struct Bodies {
  std::map<std::string, Trajectory> poses;
  std::map<std::string, int> instance_id;  // synthetic sequences: the id in instance/ masks
};

Bodies ReadBodies(const std::filesystem::path& sequence) {
  Bodies bodies;
  const auto object_poses = sequence / "object_poses.txt";
  if (std::filesystem::exists(object_poses)) {
    std::map<int, std::string> names;
    if (const auto json = ReadRegularFileIfExists(sequence / "objects.json")) {
      try {
        const nlohmann::json parsed = nlohmann::json::parse(*json);
        for (const auto& o : parsed.at("objects"))
          names[o.at("id").get<int>()] = o.value("name", "");
      } catch (const nlohmann::json::exception& e) {
        throw Error((sequence / "objects.json").string() + ": " + e.what());
      }
    }
    for (auto& [instance, trajectory] : ReadObjectPoses(object_poses)) {
      const std::string name = names.count(instance) != 0 && !names[instance].empty()
                                   ? names[instance]
                                   : fmt::format("body_{}", instance);
      bodies.poses[name] = std::move(trajectory);
      bodies.instance_id[name] = instance;
    }
    return bodies;
  }
  const auto folder = sequence / "bodies";
  if (std::filesystem::is_directory(folder)) {
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      if (entry.path().extension() == ".txt")
        bodies.poses[entry.path().stem().string()] = ReadTumTrajectory(entry.path());
    }
  }
  return bodies;
}

// One row of objects.csv.
struct Row {
  double timestamp;
  int id;
  std::optional<Eigen::Isometry3d> motion;  // world: X_now = H · X_previous
  Eigen::Vector3d centroid;
};

std::vector<Row> ReadObjectsCsv(const std::filesystem::path& path) {
  const std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error(path.string() + ": cannot open (run with --save-objects)");
  std::istringstream lines(*text);
  std::string line;
  std::vector<Row> rows;
  size_t number = 0;
  while (std::getline(lines, line)) {
    ++number;
    if (number == 1 || line.empty()) continue;  // header
    std::vector<std::string> f;
    std::stringstream fields(line);
    std::string field;
    while (std::getline(fields, field, ',')) f.push_back(field);
    if (!line.empty() && line.back() == ',') f.emplace_back();
    if (f.size() != 14) {
      throw Error(
          fmt::format("{}:{}: expected 14 fields (timestamp,id,class,tx,...,pixels), got {}",
                      path.string(), number, f.size()));
    }
    try {
      Row r;
      r.timestamp = std::stod(f[0]);
      r.id = std::stoi(f[1]);
      if (!f[3].empty()) {
        Eigen::Isometry3d H = Eigen::Isometry3d::Identity();
        H.translation() = Eigen::Vector3d(std::stod(f[3]), std::stod(f[4]), std::stod(f[5]));
        H.linear() =
            Eigen::Quaterniond(std::stod(f[9]), std::stod(f[6]), std::stod(f[7]), std::stod(f[8]))
                .normalized()
                .toRotationMatrix();
        r.motion = H;
      }
      r.centroid = Eigen::Vector3d(std::stod(f[10]), std::stod(f[11]), std::stod(f[12]));
      rows.push_back(r);
    } catch (const std::exception&) {
      throw Error(fmt::format("{}:{}: a field is not a number", path.string(), number));
    }
  }
  return rows;
}

// Frames in view per body, by the instance masks (rgb.txt's images under instance/); empty
// when the sequence has no masks.
std::map<std::string, std::vector<double>> FramesInView(const std::filesystem::path& sequence,
                                                        const Bodies& bodies, int min_pixels) {
  std::map<std::string, std::vector<double>> in_view;
  if (!std::filesystem::is_directory(sequence / "instance") || bodies.instance_id.empty())
    return in_view;
  const auto list = sequence / "rgb.txt";
  ForEachDataLine(list, [&](int number, const std::vector<std::string>& tokens) {
    if (tokens.size() < 2) throw Error(Where(list, number) + "expected timestamp filename");
    const double t = ParseTimestamp(tokens[0], list, number, "timestamp");
    const auto path = sequence / "instance" / std::filesystem::path(tokens[1]).filename();
    const cv::Mat instance = ReadImage(path, cv::IMREAD_UNCHANGED);
    if (instance.empty()) throw Error(path.string() + ": cannot read the instance mask");
    for (const auto& [name, id] : bodies.instance_id) {
      if (cv::countNonZero(instance == id) >= min_pixels) in_view[name].push_back(t);
    }
  });
  return in_view;
}

double RotationAngleDeg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

}  // namespace

std::map<std::string, Trajectory> ReadGroundTruthBodies(const std::filesystem::path& sequence) {
  return ReadBodies(sequence).poses;
}

ObjectEvaluation EvaluateObjects(const std::filesystem::path& sequence,
                                 const std::filesystem::path& run,
                                 const ObjectEvalOptions& options) {
  options.Check();
  if (!std::filesystem::exists(sequence / "groundtruth.txt") &&
      std::filesystem::exists(sequence / "vicon.csv")) {
    throw Error(sequence.string() +
                ": an Oxford Multi-motion segment; score its TUM copy (sdoslam convert --dataset " +
                sequence.string() +
                " --to tum --out COPY), which holds groundtruth.txt and bodies/");
  }
  const Trajectory gt = ReadTumTrajectory(sequence / "groundtruth.txt");
  const Trajectory estimate = ReadTumTrajectory(run / "CameraTrajectory.txt");
  const Bodies bodies = ReadBodies(sequence);
  if (bodies.poses.empty()) {
    throw Error(sequence.string() +
                ": no ground-truth bodies (object_poses.txt or bodies/*.txt; convert an OMD "
                "segment with sdoslam convert --to tum)");
  }
  const std::vector<Row> rows = ReadObjectsCsv(run / "objects.csv");
  // The estimate's world in the ground truth's: X_gt = S · X_est.
  const Similarity alignment = ComputeAte(gt, estimate).alignment;
  Eigen::Isometry3d S = Eigen::Isometry3d::Identity();
  S.linear() = alignment.rotation;
  S.translation() = alignment.translation;

  std::map<int, std::vector<const Row*>> by_id;
  for (const Row& r : rows) by_id[r.id].push_back(&r);
  auto body_pose = [&](const std::string& name, double t) {
    return InterpolatePose(bodies.poses.at(name), t, options.max_ground_truth_gap);
  };
  // Each object to the body in whose frame its centroid stays most nearly put.
  std::map<std::string, std::vector<std::pair<int, double>>> ids_of;  // body -> (id, spread)
  ObjectEvaluation result;
  for (const auto& [id, object_rows] : by_id) {
    std::string best;
    double best_spread = options.max_spread_m;
    if (static_cast<int>(object_rows.size()) >= options.min_rows) {
      for (const auto& [name, trajectory] : bodies.poses) {
        std::vector<Eigen::Vector3d> local;
        for (const Row* r : object_rows) {
          if (const auto P = body_pose(name, r->timestamp))
            local.push_back(P->inverse() * (S * r->centroid));
        }
        if (static_cast<int>(local.size()) < options.min_rows) continue;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& p : local) mean += p;
        mean /= static_cast<double>(local.size());
        double sum = 0;
        for (const auto& p : local) sum += (p - mean).squaredNorm();
        const double spread = std::sqrt(sum / static_cast<double>(local.size()));
        if (spread < best_spread) best_spread = spread, best = name;
      }
    }
    if (best.empty()) {
      result.unmatched_ids.push_back(id);
    } else {
      ids_of[best].push_back({id, best_spread});
    }
  }
  const auto in_view = FramesInView(sequence, bodies, options.min_visible_pixels);
  for (const auto& [name, trajectory] : bodies.poses) {
    BodyScore score;
    score.body = name;
    auto ids = ids_of[name];
    std::stable_sort(ids.begin(), ids.end(), [&](const auto& a, const auto& b) {
      return by_id.at(a.first).size() > by_id.at(b.first).size();
    });
    std::vector<double> covered;
    for (const auto& [id, spread] : ids) {
      score.ids.push_back(id);
      for (const Row* r : by_id.at(id)) covered.push_back(r->timestamp);
    }
    if (!ids.empty()) {
      score.frames_main_id = by_id.at(ids.front().first).size();
      score.centroid_spread_m = ids.front().second;
    }
    std::sort(covered.begin(), covered.end());
    covered.erase(std::unique(covered.begin(), covered.end()), covered.end());
    const auto view = in_view.find(name);
    score.frames_in_view = view != in_view.end() ? view->second.size()
                           : in_view.empty()     ? covered.size()
                                                 : 0;
    // Motion errors of every id taken for the body.
    for (const auto& [id, spread] : ids) {
      const std::vector<const Row*>& r = by_id.at(id);
      for (size_t k = 1; k < r.size(); ++k) {
        if (!r[k]->motion) continue;
        const auto now = body_pose(name, r[k]->timestamp);
        const auto before = body_pose(name, r[k - 1]->timestamp);
        if (!now || !before) continue;
        const Eigen::Isometry3d H_true = *now * before->inverse();
        const Eigen::Isometry3d H = S * *r[k]->motion * S.inverse();
        const Eigen::Vector3d centre = S * r[k - 1]->centroid;
        score.translation_errors.push_back((H * centre - H_true * centre).norm());
        score.rotation_errors_deg.push_back(
            RotationAngleDeg(H_true.linear().transpose() * H.linear()));
      }
    }
    result.bodies.push_back(std::move(score));
  }
  return result;
}

std::string FormatObjectEvaluation(const ObjectEvaluation& e) {
  std::string s =
      "body                 ids  in view  main id  coverage  spread mm  motions  trans rmse mm  "
      "rot rmse deg\n";
  for (const BodyScore& b : e.bodies) {
    std::string ids = b.ids.empty() ? "-" : std::to_string(b.ids.front());
    if (b.ids.size() > 1) ids += fmt::format("+{}", b.ids.size() - 1);
    const double coverage =
        b.frames_in_view > 0 ? static_cast<double>(b.frames_main_id) / b.frames_in_view : 0.0;
    const ErrorStats t = ComputeErrorStats(b.translation_errors);
    const ErrorStats r = ComputeErrorStats(b.rotation_errors_deg);
    s += fmt::format("{:<20} {:>4} {:>8} {:>8} {:>9.2f} {:>10.1f} {:>8} {:>14} {:>13}\n", b.body,
                     ids, b.frames_in_view, b.frames_main_id, coverage, 1000 * b.centroid_spread_m,
                     b.translation_errors.size(),
                     b.translation_errors.empty() ? "-" : fmt::format("{:.1f}", 1000 * t.rmse),
                     b.rotation_errors_deg.empty() ? "-" : fmt::format("{:.2f}", r.rmse));
  }
  if (!e.unmatched_ids.empty()) {
    std::string ids;
    for (int id : e.unmatched_ids) ids += fmt::format(" {}", id);
    s += fmt::format("objects no body explains:{}\n", ids);
  }
  return s;
}

}  // namespace sdoslam
