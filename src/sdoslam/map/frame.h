#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/core/geometry.h"
#include "sdoslam/features/orb_extractor.h"

namespace sdoslam {

class MapPoint;

// What every frame of a run shares: camera, pyramid, the virtual stereo baseline, and the grid
// used to look up features by position.
struct FrameGeometry {
  FrameGeometry(const Camera& camera, const OrbExtractor& extractor, double bf, double close_depth);
  Camera camera;
  PinholeIntrinsics intrinsics;
  std::vector<double> scale, inv_sigma2;
  double log_scale_factor = 0;
  double close_depth = 0;  // metres: nearer keypoints count as "close" (ORB-SLAM's ThDepth)
  float min_x = 0, max_x = 0, min_y = 0, max_y = 0;  // undistorted image bounds
  static constexpr int kGridCols = 64, kGridRows = 48;
  float grid_cell_inv_w = 0, grid_cell_inv_h = 0;
  bool InImage(double u, double v) const {
    return u >= min_x && u < max_x && v >= min_y && v < max_y;
  }
};

// How the camera moved while a rolling shutter read an image out. A rolling shutter exposes the
// rows one after another, so under a fast turn each row sees the scene from a slightly different
// pose: the freiburg1 Kinect (TUM) reads a frame out over about 23 ms, and a hand-held turn of
// 50 deg/s shifts the bottom rows 10 px against the top. The pose a frame is
// tracked at is the middle row's; the motion over a frame (the tracker's constant-velocity model)
// gives each row's offset from it.
class RowMotion {
 public:
  RowMotion() = default;  // no rolling shutter: inactive
  // `per_frame`: T_cam(k) * T_cam(k-1)^-1; `readout_frames`: the readout time, first row to
  // last, in frame intervals. The turn is taken apart into axis and angle once, here, not per
  // feature.
  RowMotion(const Eigen::Isometry3d& per_frame, double readout_frames)
      : turn_(per_frame.linear()),
        translation_(per_frame.translation()),
        readout_frames_(readout_frames) {}
  bool active() const { return readout_frames_ != 0; }
  // Takes a point seen (camera coordinates) by row `row` (as detected, distorted) of an image
  // `height` rows high into the camera of the middle row's exposure: M^-s with M = per_frame and
  // s = (row - height/2) / height * readout_frames (rotation angle and translation scaled by s:
  // exact to first order in the small motion of one frame).
  Eigen::Isometry3d ToMiddleRow(double row, int height) const;

 private:
  Eigen::AngleAxisd turn_{0.0, Eigen::Vector3d::UnitZ()};
  Eigen::Vector3d translation_ = Eigen::Vector3d::Zero();
  double readout_frames_ = 0;
};

// Undistorts `detected` pixels of an image whose rows moved by `motion`, and turns each one's ray
// to the middle row's camera (the rotation only: the translation needs depth, and over a few
// milliseconds it moves a pixel by a fraction of what the turn does).
std::vector<cv::Point2f> UndistortToMiddleRow(const Camera& camera, const RowMotion& motion,
                                              const std::vector<cv::Point2f>& detected);

// `image` in grey: converted from BGR (CV_8UC3), or `image` itself when it is grey already.
cv::Mat GrayImage(const cv::Mat& image);

// A frame's features: keypoints with depth, descriptors, and the map points they are matched to.
class Frame {
 public:
  // Extracts ORB features from `bgr` (CV_8UC3, or a grey CV_8UC1 image) and reads each
  // keypoint's depth from `depth` (metres, 0 = none) at the keypoint's (distorted) position, where
  // the depth image is registered, and its colour from `bgr`. `gray`: `bgr` in grey where the
  // caller has made it already (it is made here otherwise). `areas`: where the features go
  // (OrbExtractor::Extract).
  Frame(size_t index, double timestamp, const cv::Mat& bgr, const cv::Mat& depth,
        std::shared_ptr<const FrameGeometry> geometry, const OrbExtractor& extractor,
        const cv::Mat& gray = cv::Mat(), const ExtractionAreas& areas = {});

  size_t size() const { return keypoints.size(); }
  // Indices of static features within `radius` px of (u, v) (undistorted), on levels
  // [min_level, max_level] (-1: any), in ascending order.
  std::vector<int> FeaturesInArea(double u, double v, double radius, int min_level = -1,
                                  int max_level = -1) const;
  bool HasDepth(int i) const { return depth[static_cast<size_t>(i)] > 0; }
  // Features on things judged dynamic (label != 0) are kept for drawing and evaluation, but
  // tracking and mapping never match them nor make map points from them.
  bool IsStatic(int i) const { return label[static_cast<size_t>(i)] == 0; }
  // What tracking and mapping build on: a static feature with depth.
  bool IsStaticWithDepth(int i) const { return IsStatic(i) && HasDepth(i); }
  // Labels each feature from `label_image` (CV_8U, image size, 0 = static) at its detected
  // position; FeaturesInArea leaves the non-static ones out. An empty image clears all labels.
  // Call before tracking the frame.
  void SetLabels(const cv::Mat& label_image);
  // Gives feature i a dynamic label after tracking has started on the frame (the consistency
  // check): drops its map point, and FeaturesInArea leaves it out.
  void MarkDynamic(int i, uint8_t dynamic_label);
  // Returns feature i to static (the check found a feature the front end took out consistent
  // with the static world): FeaturesInArea includes it again.
  void MarkStatic(int i) { label[static_cast<size_t>(i)] = 0; }
  // Marks the features on `mask` (CV_8U, image size, non-zero: seen moving lately, see
  // SdoClassifierOptions::unmapped_frames) as making no map points; tracking still matches them
  // to the map. An empty mask clears the marks.
  void SetUnmappable(const cv::Mat& mask);
  // Whether feature i may make a map point (keyframe points from depth, triangulation, the
  // tracker's temporary points): static, and not where something was seen moving lately.
  bool MakesPoints(int i) const {
    return IsStatic(i) && (unmappable_.empty() || unmappable_[static_cast<size_t>(i)] == 0);
  }
  // Moves every feature (undistorted position, depth) to where the middle row's camera saw it
  // (RowMotion), and remembers `motion` in row_motion. Call once, before tracking the frame.
  void CompensateRollingShutter(const RowMotion& motion);
  // Keypoint i back-projected with its depth, in world coordinates at the frame's pose.
  Eigen::Vector3d UnprojectWorld(int i) const;
  PointObservation Observation(int i) const;
  // Frees every feature (the frame keeps its index, timestamp and pose): for culled keyframes,
  // so that a long run's memory follows the map, not the number of keyframes ever made.
  void ReleaseFeatures();
  Eigen::Vector3d CameraCentre() const { return T_camera_world.inverse().translation(); }

  size_t index;
  double timestamp;
  std::shared_ptr<const FrameGeometry> geometry;
  std::vector<cv::KeyPoint> keypoints;  // as detected (distorted)
  std::vector<cv::Point2f> undistorted;
  std::vector<float> depth;           // metres; 0 = none
  std::vector<float> right_u;         // virtual right-image u; -1 = none
  cv::Mat descriptors;                // N x 32, CV_8U
  std::vector<MapPoint*> map_points;  // matched map point per feature, or nullptr
  std::vector<bool> outlier;
  std::vector<uint8_t> label;  // 0 = static; otherwise the dynamic label of the front end
  // Colour of the image at each keypoint (B, G, R; grey images give equal channels): the map's
  // point cloud takes its colours from here (System::StaticMapCloud).
  std::vector<cv::Vec3b> colors;
  Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();
  RowMotion row_motion;  // what CompensateRollingShutter applied; inactive: nothing

 private:
  void BuildGrid();
  // The value of `image` (CV_8U, image size) at each keypoint's (rounded, clamped) position.
  std::vector<uint8_t> ValuesAtKeypoints(const cv::Mat& image) const;
  int GridCell(int i) const;  // -1 outside the grid
  // Features per grid cell: those of cell c are grid_features_[grid_start_[c] ..
  // grid_start_[c + 1]).
  std::vector<int> grid_start_, grid_features_;
  std::vector<uint8_t> unmappable_;  // per feature, 1: makes no map point; empty: none marked
};

}  // namespace sdoslam
