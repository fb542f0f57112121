#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/io/trajectory.h"

namespace sdoslam {

// Moving objects as output (run --save-objects): the dynamic regions of each frame's label image
// become objects with an id kept from frame to frame, a class, a centroid and their own rigid
// motion, estimated from their own pixels (Lucas–Kanade corners lifted to 3-D by depth, a
// RANSAC fit of a rigid motion). It only reads what tracking produced: the camera trajectory is
// the same with and without it.
struct ObjectTrackerOptions {
  // Regions are cut from the label image at 1/work_scale of its size, closed by close_px (work
  // pixels) so that a body split into parts by the segmenter is one region, and kept when they
  // cover at least min_pixels of the full image.
  int work_scale = 4;
  int close_px = 2;
  int min_pixels = 1500;
  // ... and split where neighbouring depths differ by more than this share: movers that overlap
  // in the image at different depths are separate objects.
  double depth_step = 0.04;
  // A region continues the track seen in the previous frame whose points (followed by
  // Lucas–Kanade, below) land in it: at least min_votes of them and a quarter of those it
  // followed. Else the track whose centroid (carried on at its velocity for at most
  // max_predicted_frames) lies within gate_m of its own. A track unseen for more than
  // max_missed_frames frames ends. sdo's labels lose a mover for a while where it slows (a
  // pendulum at the end of its swing: 9-13 frames on the OMD copy), and it comes back near where
  // it was lost, not where its last velocity pointed: with 10 missed frames and no bound on the
  // prediction its id broke there (docs/results.md, Moving objects).
  int min_votes = 5;
  double gate_m = 0.4;
  int max_missed_frames = 30;
  int max_predicted_frames = 3;
  // Points whose move the camera's own motion explains (within static_px in the image and the
  // sensor's depth noise) are left out of the object's motion where they are fewer than half of
  // its points: a mask that takes in a strip of the static scene would pull the motion toward
  // standing still. Where they are most, the object itself stands still and all are kept. 0: off.
  double static_px = 1.5;
  // The motion from the track's previous frame: up to max_corners corners on its previous
  // region followed by Lucas–Kanade (both ways, round trip within max_round_trip_px) into its
  // region now; a rigid motion fitted to their 3-D ends by RANSAC (optim/rigid_ransac.h: a point
  // an inlier within inlier_m + inlier_per_m2 · z² of the fit, z its depth, as the sensor's noise
  // grows with z²) and given when at least min_motion_points agree; its rotation refined on the
  // points' pixels (pixel_sigma) and depths (the Kinect's noise at their depth, as the scene-flow
  // check models it: tracking/scene_flow.h, DepthNoiseSigma).
  int max_corners = 100;
  double max_round_trip_px = 1.0;
  double inlier_m = 0.01;
  double inlier_per_m2 = 0.005;
  int min_motion_points = 10;
  double pixel_sigma = 0.5;
  uint32_t seed = 1;   // RANSAC's; with the frame's index, the same objects every run
  void Check() const;  // Error names the setting as objects.<key>
  // Every setting, as its key in a run config's objects: section.
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("work_scale", o.work_scale);
    visit("close_px", o.close_px);
    visit("min_pixels", o.min_pixels);
    visit("depth_step", o.depth_step);
    visit("min_votes", o.min_votes);
    visit("gate_m", o.gate_m);
    visit("max_missed_frames", o.max_missed_frames);
    visit("max_predicted_frames", o.max_predicted_frames);
    visit("static_px", o.static_px);
    visit("max_corners", o.max_corners);
    visit("max_round_trip_px", o.max_round_trip_px);
    visit("inlier_m", o.inlier_m);
    visit("inlier_per_m2", o.inlier_per_m2);
    visit("min_motion_points", o.min_motion_points);
    visit("pixel_sigma", o.pixel_sigma);
    visit("seed", o.seed);
  }
};

// A detection's class and box (full-image pixels): a region mostly labelled known takes the
// class of the box that overlaps it most.
struct ClassHint {
  std::string class_name;
  cv::Rect2f box;
};

// One object in one frame, in the frame's camera coordinates: the world's follow from the final
// trajectory (ObjectsInWorld), after local BA and loop closing have moved the poses.
struct ObjectObservation {
  size_t frame = 0;
  double timestamp = 0;
  int id = 0;
  std::string class_name;  // a detection's class, or "unknown"
  int pixels = 0;
  Eigen::Vector3d centroid_camera = Eigen::Vector3d::Zero();  // mean of its 3-D pixels
  // X_now = motion · X_previous for the object's points, each in its frame's camera coordinates;
  // previous_frame's index and timestamp. None when too few of its points agree.
  std::optional<Eigen::Isometry3d> motion_camera;
  size_t previous_frame = 0;
  double previous_timestamp = 0;
  int motion_inliers = 0;
};

class ObjectTracker {
 public:
  ObjectTracker(const CameraOptions& camera, const ObjectTrackerOptions& options = {});

  // Frame `index`: `labels` CV_8U at image size (non-zero: dynamic), `gray` CV_8U and `depth`
  // CV_32F metres, the camera pose tracking gave it (`tracked` false: lost, nothing is placed).
  std::vector<ObjectObservation> Update(size_t index, double timestamp, const cv::Mat& gray,
                                        const cv::Mat& depth, const cv::Mat& labels,
                                        const std::vector<ClassHint>& hints,
                                        const Eigen::Isometry3d& T_world_camera, bool tracked);

 private:
  struct Region {
    cv::Mat mask;  // CV_8U at image size
    cv::Rect box;  // its bounds
    int pixels = 0;
    Eigen::Vector3d centroid_camera;
    std::string class_name;
  };
  struct Track {
    int id;
    Eigen::Vector3d centroid_world;
    Eigen::Vector3d velocity_world = Eigen::Vector3d::Zero();  // per frame
    size_t last_frame;
    cv::Mat mask;  // its region in last_frame
    cv::Rect box;  // the mask's bounds
  };
  std::vector<Region> FindRegions(const cv::Mat& depth, const cv::Mat& labels,
                                  const std::vector<ClassHint>& hints) const;
  // Corners of `previous_mask` (whose bounds are `previous_box`) in the previous frame followed
  // into `gray` (both ways).
  struct FollowedPoints {
    std::vector<cv::Point2f> before, now;
  };
  // `pyramid`: gray's, for Lucas–Kanade (previous_pyramid_ is the previous frame's).
  FollowedPoints FollowPoints(const cv::Mat& previous_mask, const cv::Rect& previous_box,
                              const cv::Mat& gray, const std::vector<cv::Mat>& pyramid) const;
  // The region `p` lies in, or -1. Regions never overlap (each pixel is flood-filled once, and a
  // split hands each pixel to one part), so the first that holds it is the one: a lookup per
  // point, where an image of region numbers cost two full-size fills a frame.
  static int RegionAt(const std::vector<Region>& regions, const cv::Point& p);
  // The votes of a track's `followed` points for the `regions` they land in: zero where too few
  // land for the region to continue the track.
  std::vector<int> Votes(const FollowedPoints& followed, const std::vector<Region>& regions) const;
  // A region that continues two or more tracks (objects that came together in the image, at
  // depths too close to cut them apart) is cut between them: each pixel goes to the track whose
  // followed point lies nearest.
  void SplitMergedRegions(const std::vector<FollowedPoints>& followed, const cv::Mat& depth,
                          const cv::Mat& labels, const std::vector<ClassHint>& hints,
                          std::vector<Region>* regions) const;
  // The region of `mask`, which is zero outside `within`: its size, centroid and class; none
  // when too small or without depth. (Every pass over a mask here stays inside known bounds: a
  // scan of the whole image per region and per track was a tenth of the tracker's time.)
  std::optional<Region> MakeRegion(const cv::Mat& mask, const cv::Rect& within,
                                   const cv::Mat& depth, const cv::Mat& labels,
                                   const std::vector<ClassHint>& hints) const;
  // The object's motion from the previous frame (previous_depth_) into this one, from the
  // `followed` points that land in its region.
  // `camera_motion`: the camera's own, X_now = camera_motion · X_previous for a static point.
  std::optional<Eigen::Isometry3d> EstimateMotion(size_t index, const FollowedPoints& followed,
                                                  const Region& region, const cv::Mat& depth,
                                                  const Eigen::Isometry3d& camera_motion,
                                                  int* inliers) const;

  Camera camera_;
  ObjectTrackerOptions options_;
  cv::Mat rays_;  // CV_32FC2: each pixel's undistorted (x/z, y/z)
  std::vector<Track> tracks_;
  int next_id_ = 1;
  size_t previous_index_ = 0;
  double previous_timestamp_ = 0;
  cv::Mat previous_depth_;
  Eigen::Isometry3d previous_T_world_camera_ = Eigen::Isometry3d::Identity();
  std::vector<cv::Mat> previous_pyramid_;
};

// The observations in the world of `trajectory` (the run's final camera poses, by timestamp):
// one CSV row per object and frame whose pose is known, objects.csv's columns
//   timestamp,id,class,tx,ty,tz,qx,qy,qz,qw,cx,cy,cz,pixels
// where t, q is the object's motion H (X_now = H · X_previous, world) and c its centroid; the
// motion's fields are empty when it was not estimated or the previous frame has no pose.
std::string ObjectsCsv(const std::vector<ObjectObservation>& observations,
                       const Trajectory& trajectory);
// Each object's centroid track in the same world, TUM format (identity orientation), by id.
std::map<int, Trajectory> ObjectCentroidTracks(const std::vector<ObjectObservation>& observations,
                                               const Trajectory& trajectory);

}  // namespace sdoslam
