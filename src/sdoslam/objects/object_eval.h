#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/eval/plot.h"
#include "sdoslam/io/trajectory.h"

namespace sdoslam {

// Scores a run's objects (objects.csv of run --save-objects) against ground-truth bodies, through
// the camera trajectory's alignment to the ground truth (SE3, as the ATE's).
struct ObjectEvalOptions {
  // An object is a body's when its centroid, brought into the body's frame, stays within this
  // RMS distance of its mean there (a rigid body's visible surface moves with it).
  double max_spread_m = 0.25;
  int min_rows = 3;                    // an object seen in fewer frames is not scored
  double max_ground_truth_gap = 0.05;  // seconds between body poses to interpolate across
  // A body is in view in a frame where its instance mask (when the sequence has one) covers at
  // least this many pixels.
  int min_visible_pixels = 1500;
  void Check() const;
};

struct BodyScore {
  std::string body;
  std::vector<int> ids;          // the run's objects taken for it, most frames first
  size_t frames_in_view = 0;     // by its instance masks; without them, frames any id covers
  size_t frames_main_id = 0;     // frames the first of `ids` covers
  double centroid_spread_m = 0;  // of the first id, RMS (see max_spread_m)
  // Per frame with an estimated motion: where the estimated motion and the true one move the
  // object's centroid, apart (metres), and the angle between their rotations (degrees).
  std::vector<double> translation_errors, rotation_errors_deg;
};

// One object of the run, in the ground truth's world (through the camera trajectory's alignment).
struct ObjectTrack {
  std::string class_name;  // as objects.csv has it: a detection's class, or "unknown"
  std::string body;        // the body it was taken for; empty: none
  std::vector<double> timestamps;
  std::vector<Eigen::Vector3d> centroids;
  // Taken for a body: per timestamp, where the point fixed in the body at the centroid's mean
  // position in the body's frame truly was (none where the body's pose is unknown). The gap to
  // `centroids` is the centroid's spread (BodyScore::centroid_spread_m).
  std::vector<std::optional<Eigen::Vector3d>> true_centroids;
};

struct ObjectEvaluation {
  std::vector<BodyScore> bodies;      // every ground-truth body, in name order
  std::vector<int> unmatched_ids;     // objects no body explains (or seen too briefly)
  std::map<int, ObjectTrack> tracks;  // every object of objects.csv, by id
};

// Ground-truth bodies of a sequence folder: object_poses.txt (sdoslam synth: by instance id,
// named by objects.json) or bodies/<name>.txt (convert --to tum of an OMD segment). Empty when
// it has neither.
std::map<std::string, Trajectory> ReadGroundTruthBodies(const std::filesystem::path& sequence);

// Scores `run` (CameraTrajectory.txt, objects.csv) against `sequence` (groundtruth.txt, the
// bodies, instance/ masks when present). Throws Error naming the missing or malformed file.
ObjectEvaluation EvaluateObjects(const std::filesystem::path& sequence,
                                 const std::filesystem::path& run,
                                 const ObjectEvalOptions& options = {});

// The scores as a table, one row per body (FormatObjectEvaluation's columns): ids taken (the
// main one, "+n" others), frames in view, frames of the main id, its coverage, its centroid
// spread in mm, motions scored, translation RMSE in mm and rotation RMSE in degrees.
std::vector<std::string> ObjectEvaluationHeader();
std::vector<std::vector<std::string>> ObjectEvaluationRows(const ObjectEvaluation& e);

std::string FormatObjectEvaluation(const ObjectEvaluation& e);

// A top view, in the ground truth's world, of where the run's objects went: the camera's true
// path (black), each object's centroid track (in colour, named by id, class and the body it was
// taken for; at most `max_tracks`, the longest) over the true path of that centroid (grey, for
// objects taken for a body). `plane` as EvaluationOptions::plane.
Plot ObjectTracksTopView(const ObjectEvaluation& e, const Trajectory& camera_ground_truth,
                         const std::string& plane = "auto", size_t max_tracks = 12);

}  // namespace sdoslam
