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
#include "sdoslam/eval/report.h"
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
  std::string class_name;
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
      r.class_name = f[2];
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
    Eigen::Vector3d best_mean = Eigen::Vector3d::Zero();  // the centroid's mean in the body's frame
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
        if (spread < best_spread) best_spread = spread, best = name, best_mean = mean;
      }
    }
    if (best.empty()) {
      result.unmatched_ids.push_back(id);
    } else {
      ids_of[best].push_back({id, best_spread});
    }
    ObjectTrack& track = result.tracks[id];
    track.class_name = object_rows.front()->class_name;
    track.body = best;
    for (const Row* r : object_rows) {
      track.timestamps.push_back(r->timestamp);
      track.centroids.push_back(S * r->centroid);
      if (best.empty()) continue;
      const auto P = body_pose(best, r->timestamp);
      track.true_centroids.push_back(P ? std::optional<Eigen::Vector3d>(*P * best_mean)
                                       : std::nullopt);
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

std::vector<std::string> ObjectEvaluationHeader() {
  return {"body",      "ids",     "in view",       "main id",     "coverage",
          "spread mm", "motions", "trans rmse mm", "rot rmse deg"};
}

std::vector<std::vector<std::string>> ObjectEvaluationRows(const ObjectEvaluation& e) {
  std::vector<std::vector<std::string>> rows;
  for (const BodyScore& b : e.bodies) {
    std::string ids = b.ids.empty() ? "-" : std::to_string(b.ids.front());
    if (b.ids.size() > 1) ids += fmt::format("+{}", b.ids.size() - 1);
    const double coverage =
        b.frames_in_view > 0 ? static_cast<double>(b.frames_main_id) / b.frames_in_view : 0.0;
    const ErrorStats t = ComputeErrorStats(b.translation_errors);
    const ErrorStats r = ComputeErrorStats(b.rotation_errors_deg);
    rows.push_back({b.body, ids, std::to_string(b.frames_in_view), std::to_string(b.frames_main_id),
                    fmt::format("{:.2f}", coverage),
                    fmt::format("{:.1f}", 1000 * b.centroid_spread_m),
                    std::to_string(b.translation_errors.size()),
                    b.translation_errors.empty() ? "-" : fmt::format("{:.1f}", 1000 * t.rmse),
                    b.rotation_errors_deg.empty() ? "-" : fmt::format("{:.2f}", r.rmse)});
  }
  return rows;
}

std::string FormatObjectEvaluation(const ObjectEvaluation& e) {
  // The body's name left-aligned in 20 characters, then each cell right-aligned one character
  // wider than its column's name.
  const std::vector<std::string> header = ObjectEvaluationHeader();
  auto line = [&](const std::vector<std::string>& cells) {
    std::string s = fmt::format("{:<20}", cells[0]);
    for (size_t c = 1; c < cells.size(); ++c)
      s += fmt::format(" {:>{}}", cells[c], header[c].size() + 1);
    return s + "\n";
  };
  std::string s = line(header);
  for (const auto& row : ObjectEvaluationRows(e)) s += line(row);
  if (!e.unmatched_ids.empty()) {
    std::string ids;
    for (int id : e.unmatched_ids) ids += fmt::format(" {}", id);
    s += fmt::format("objects no body explains:{}\n", ids);
  }
  return s;
}

Plot ObjectTracksTopView(const ObjectEvaluation& e, const Trajectory& camera_ground_truth,
                         const std::string& plane, size_t max_tracks) {
  // The longest tracks, drawn in id order.
  std::vector<int> ids;
  for (const auto& [id, track] : e.tracks) ids.push_back(id);
  std::stable_sort(ids.begin(), ids.end(), [&](int a, int b) {
    return e.tracks.at(a).centroids.size() > e.tracks.at(b).centroids.size();
  });
  if (ids.size() > max_tracks) ids.resize(max_tracks);
  std::sort(ids.begin(), ids.end());

  std::vector<Eigen::Vector3d> extent;
  for (const auto& pose : camera_ground_truth) extent.push_back(pose.T_world_camera.translation());
  for (int id : ids) {
    const auto& c = e.tracks.at(id).centroids;
    extent.insert(extent.end(), c.begin(), c.end());
  }
  const std::array<int, 2> axes = PlaneAxes(plane, extent);
  auto project = [&](const Eigen::Vector3d& p) { return Eigen::Vector2d(p[axes[0]], p[axes[1]]); };
  const char* kAxisNames = "xyz";
  Plot plot{"Moving objects: top view",
            fmt::format("{} [m]", kAxisNames[axes[0]]),
            fmt::format("{} [m]", kAxisNames[axes[1]]),
            true,
            {}};
  PlotSeries camera{"camera (ground truth)", {}, 0x000000, 1.5, false};
  for (const auto& pose : camera_ground_truth)
    camera.points.push_back(project(pose.T_world_camera.translation()));
  plot.series.push_back(std::move(camera));
  // Under the tracks: where each matched object's centroid truly went (the point fixed in its
  // body where the centroid sits on average), broken where the body's pose is unknown.
  bool first_truth = true;
  for (int id : ids) {
    const ObjectTrack& track = e.tracks.at(id);
    PlotSeries truth{"", {}, 0xbbbbbb, 3.0, true};
    for (size_t k = 1; k < track.true_centroids.size(); ++k) {
      if (!track.true_centroids[k - 1] || !track.true_centroids[k]) continue;
      truth.points.push_back(project(*track.true_centroids[k - 1]));
      truth.points.push_back(project(*track.true_centroids[k]));
    }
    if (truth.points.empty()) continue;
    if (first_truth) truth.label = "true paths of matched objects";
    first_truth = false;
    plot.series.push_back(std::move(truth));
  }
  for (size_t k = 0; k < ids.size(); ++k) {
    const ObjectTrack& track = e.tracks.at(ids[k]);
    PlotSeries series{fmt::format("id {} {}{}", ids[k], track.class_name,
                                  track.body.empty() ? "" : " = " + track.body),
                      {},
                      PlotColour(k),
                      1.5,
                      false};
    for (const auto& c : track.centroids) series.points.push_back(project(c));
    plot.series.push_back(std::move(series));
  }
  return plot;
}

}  // namespace sdoslam
