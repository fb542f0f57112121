#include "sdoslam/objects/object_tracker.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/optim/rigid_ransac.h"
#include "sdoslam/tracking/scene_flow.h"

namespace sdoslam {

void ObjectTrackerOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw Error(std::string("objects.") + what);
  };
  require(work_scale >= 1, "work_scale must be at least 1");
  require(close_px >= 0, "close_px must be >= 0");
  require(depth_step > 0, "depth_step must be > 0");
  require(min_pixels >= 1, "min_pixels must be at least 1");
  require(gate_m > 0, "gate_m must be > 0");
  require(min_votes >= 1, "min_votes must be at least 1");
  require(max_missed_frames >= 0, "max_missed_frames must be >= 0");
  require(max_predicted_frames >= 0, "max_predicted_frames must be >= 0");
  require(static_px >= 0, "static_px must be >= 0");
  require(max_corners >= 3, "max_corners must be at least 3");
  require(max_round_trip_px > 0, "max_round_trip_px must be > 0");
  require(pixel_sigma > 0, "pixel_sigma must be > 0");
  require(inlier_m > 0 && inlier_per_m2 >= 0, "inlier_m must be > 0 and inlier_per_m2 >= 0");
  require(min_motion_points >= 3, "min_motion_points must be at least 3");
}

ObjectTracker::ObjectTracker(const CameraOptions& camera, const ObjectTrackerOptions& options)
    : camera_(camera), options_(options) {
  options_.Check();
  // Every pixel's undistorted ray once, (x/z, y/z): centroids sum thousands of pixels a frame.
  std::vector<cv::Point2f> pixels;
  pixels.reserve(static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height));
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x)
      pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  const std::vector<cv::Point2f> undistorted = camera_.UndistortPoints(pixels);
  rays_.create(camera.height, camera.width, CV_32FC2);
  for (size_t k = 0; k < undistorted.size(); ++k) {
    rays_.at<cv::Vec2f>(static_cast<int>(k) / camera.width, static_cast<int>(k) % camera.width) =
        cv::Vec2f(static_cast<float>((undistorted[k].x - camera.cx) / camera.fx),
                  static_cast<float>((undistorted[k].y - camera.cy) / camera.fy));
  }
}

namespace {

// Lucas–Kanade's window (px), pyramid levels above the image (a mover shifts by tens of pixels
// a frame) and iterations per level (OpenCV's 30 cost three times the time for nothing: the
// points settle in a few). An 11 px window, not 15: half the pixels per point, and the boxes'
// motions came out the same (oracle boxes_translational 3.8-4.3 mm, 0.15-0.53 deg).
constexpr int kWindow = 11, kLevels = 3, kIterations = 10;

// One point's residuals for the motion G (quaternion, translation) taking its earlier position
// `from` to where it is seen now: the projection against its pixel (px, over pixel_sigma) and
// the depth against its depth (over both ends' depth noise).
struct MotionResidual {
  Eigen::Vector3d from;
  Eigen::Vector2d pixel;
  double depth, pixel_sigma, depth_sigma, fx, fy, cx, cy;
  template <typename T>
  bool operator()(const T* q, const T* t, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> rotation(q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> translation(t);
    const Eigen::Matrix<T, 3, 1> p = rotation * from.cast<T>() + translation;
    r[0] = (T(fx) * p.x() / p.z() + T(cx) - T(pixel.x())) / T(pixel_sigma);
    r[1] = (T(fy) * p.y() / p.z() + T(cy) - T(pixel.y())) / T(pixel_sigma);
    r[2] = (p.z() - T(depth)) / T(depth_sigma);
    return true;
  }
};

// G refined from `start` on the points' pixels and depths now (Huber-robust, Ceres).
Eigen::Isometry3d RefineMotion(const CameraOptions& c, const ObjectTrackerOptions& o,
                               const std::vector<Eigen::Vector3d>& from,
                               const std::vector<Eigen::Vector3d>& to,
                               const std::vector<Eigen::Vector2d>& pixels,
                               const Eigen::Isometry3d& start) {
  Eigen::Quaterniond q(start.linear());
  Eigen::Vector3d t = start.translation();
  ceres::Problem problem;
  for (size_t k = 0; k < from.size(); ++k) {
    const double sigma = std::sqrt(2.0) * DepthNoiseSigma(SceneFlowOptions(), to[k].z());
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<MotionResidual, 3, 4, 3>(new MotionResidual{
            from[k], pixels[k], to[k].z(), o.pixel_sigma, sigma, c.fx, c.fy, c.cx, c.cy}),
        new ceres::HuberLoss(2.0), q.coeffs().data(), t.data());
  }
  problem.SetManifold(q.coeffs().data(), new ceres::EigenQuaternionManifold);
  ceres::Solver::Options options;
  options.max_num_iterations = 10;
  options.linear_solver_type = ceres::DENSE_QR;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

}  // namespace

std::vector<ObjectTracker::Region> ObjectTracker::FindRegions(
    const cv::Mat& depth, const cv::Mat& labels, const std::vector<ClassHint>& hints) const {
  const int s = options_.work_scale;
  const cv::Size work_size(labels.cols / s, labels.rows / s);
  cv::Mat dynamic = labels != 0, work;
  cv::resize(dynamic, work, work_size, 0, 0, cv::INTER_AREA);
  work = work > 0;
  if (options_.close_px > 0) {
    const int k = 2 * options_.close_px + 1;
    cv::morphologyEx(work, work, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  }
  // Regions grow over neighbours whose depths differ by less than depth_step (relative): two
  // movers that overlap in the image at different depths are two objects. Flood fill on the log
  // of depth, so that OpenCV's absolute tolerance is a relative one; pixels without depth are
  // in no region.
  cv::Mat work_depth, log_depth;
  cv::resize(depth, work_depth, work_size, 0, 0, cv::INTER_NEAREST);
  cv::Mat has_depth = work_depth > 0;
  cv::max(work_depth, 1e-3, work_depth);
  cv::log(work_depth, log_depth);
  // floodFill's mask: non-zero where it may not go (and its one-pixel frame); then each region's
  // number (2, 3, ...) where it went.
  cv::Mat region_of(work_size.height + 2, work_size.width + 2, CV_8U, cv::Scalar(1));
  region_of(cv::Rect(1, 1, work_size.width, work_size.height)).setTo(0, work & has_depth);
  const double step = std::log1p(options_.depth_step);
  std::vector<cv::Mat> work_masks;
  for (int y = 0; y < work_size.height && work_masks.size() < 250; ++y) {
    for (int x = 0; x < work_size.width && work_masks.size() < 250; ++x) {
      if (region_of.at<uint8_t>(y + 1, x + 1) != 0) continue;
      const int number = static_cast<int>(work_masks.size()) + 2;
      cv::Rect box;
      const int area =
          cv::floodFill(log_depth, region_of, cv::Point(x, y), cv::Scalar(), &box, cv::Scalar(step),
                        cv::Scalar(step), 8 | cv::FLOODFILL_MASK_ONLY | (number << 8));
      work_masks.push_back(area * s * s >= options_.min_pixels
                               ? region_of(cv::Rect(1, 1, work_size.width, work_size.height)) ==
                                     number
                               : cv::Mat());
    }
  }
  std::vector<Region> regions;
  for (const cv::Mat& work_mask : work_masks) {
    if (work_mask.empty()) continue;
    // Up to the image's size within its bounds only.
    const cv::Rect work_box = cv::boundingRect(work_mask);
    const cv::Rect box =
        cv::Rect(work_box.x * s, work_box.y * s, work_box.width * s, work_box.height * s) &
        cv::Rect(0, 0, labels.cols, labels.rows);
    cv::Mat mask(labels.size(), CV_8U, cv::Scalar(0)), up;
    cv::resize(work_mask(work_box), up, box.size(), 0, 0, cv::INTER_NEAREST);
    cv::bitwise_and(up, dynamic(box), mask(box));
    if (std::optional<Region> r = MakeRegion(mask, box, depth, labels, hints))
      regions.push_back(std::move(*r));
  }
  return regions;
}

std::optional<ObjectTracker::Region> ObjectTracker::MakeRegion(
    const cv::Mat& mask, const cv::Rect& within, const cv::Mat& depth, const cv::Mat& labels,
    const std::vector<ClassHint>& hints) const {
  Region r;
  r.mask = mask;
  r.box = cv::boundingRect(mask(within)) + within.tl();  // every pass below stays inside it
  if (r.box.area() < options_.min_pixels) return std::nullopt;
  const cv::Mat inside = mask(r.box);
  r.pixels = cv::countNonZero(inside);
  if (r.pixels < options_.min_pixels) return std::nullopt;
  // The mean of its pixels with depth, on a 2-pixel grid: the region is one surface in depth
  // (depth_step), so no far background pulls the mean, and a median would move in the grid's
  // steps (a centimetre at 1.5 m) instead of with the object.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int samples = 0;
  for (int y = r.box.y; y < r.box.y + r.box.height; y += 2) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const float* d = depth.ptr<float>(y);
    const cv::Vec2f* ray = rays_.ptr<cv::Vec2f>(y);
    for (int x = r.box.x; x < r.box.x + r.box.width; x += 2) {
      if (m[x] && d[x] > 0) {
        sum += static_cast<double>(d[x]) * Eigen::Vector3d(ray[x][0], ray[x][1], 1.0);
        ++samples;
      }
    }
  }
  if (samples < 10) return std::nullopt;  // no depth: it cannot be placed
  r.centroid_camera = sum / static_cast<double>(samples);
  // The class of the box covering most of it, where it is mostly labelled known (1).
  r.class_name = "unknown";
  if (cv::countNonZero(inside & (labels(r.box) == 1)) * 2 > r.pixels) {
    double best = 0.3 * r.box.area();  // at least 30 % of its bounds
    for (const ClassHint& h : hints) {
      const double overlap = (cv::Rect2f(r.box) & h.box).area();
      if (overlap > best) best = overlap, r.class_name = h.class_name;
    }
  }
  return r;
}

ObjectTracker::FollowedPoints ObjectTracker::FollowPoints(
    const cv::Mat& previous_mask, const cv::Rect& bounds, const cv::Mat& gray,
    const std::vector<cv::Mat>& pyramid) const {
  FollowedPoints f;
  // Corners within the region's bounds only, found at half resolution (the pyramid's level 1):
  // the corner response of the whole image per object cost milliseconds, and Lucas–Kanade
  // settles a point on the full image anyway.
  const cv::Rect half(bounds.x / 2, bounds.y / 2, bounds.width / 2, bounds.height / 2);
  if (half.area() == 0) return f;
  const cv::Mat half_image = previous_pyramid_[2];  // level 1 (level 0's derivatives between)
  cv::Mat half_mask;
  cv::resize(previous_mask(cv::Rect(half.x * 2, half.y * 2, half.width * 2, half.height * 2)),
             half_mask, half.size(), 0, 0, cv::INTER_NEAREST);
  std::vector<cv::Point2f> before;
  cv::goodFeaturesToTrack(half_image(half), before, options_.max_corners, 0.002, 3, half_mask);
  if (before.empty()) return f;
  for (cv::Point2f& p : before)
    p = 2.0f * (p + cv::Point2f(static_cast<float>(half.x), static_cast<float>(half.y)));
  std::vector<cv::Point2f> now, back;
  std::vector<uint8_t> found, found_back;
  std::vector<float> error;
  const cv::Size window(kWindow, kWindow);
  const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, kIterations, 0.03);
  cv::calcOpticalFlowPyrLK(previous_pyramid_, pyramid, before, now, found, error, window, kLevels,
                           stop);
  cv::calcOpticalFlowPyrLK(pyramid, previous_pyramid_, now, back, found_back, error, window,
                           kLevels, stop);
  for (size_t k = 0; k < before.size(); ++k) {
    if (!found[k] || !found_back[k] || cv::norm(back[k] - before[k]) > options_.max_round_trip_px)
      continue;
    if (now[k].x < 0 || now[k].y < 0 || now[k].x > gray.cols - 1 || now[k].y > gray.rows - 1)
      continue;
    f.before.push_back(before[k]);
    f.now.push_back(now[k]);
  }
  return f;
}

std::optional<Eigen::Isometry3d> ObjectTracker::EstimateMotion(
    size_t index, const FollowedPoints& followed, const Region& region, const cv::Mat& depth,
    const Eigen::Isometry3d& camera_motion, int* inliers) const {
  *inliers = 0;
  std::vector<cv::Point2f> kept_before, kept_now;
  std::vector<double> z_before, z_now;
  // The mask grown by 2 px, within its bounds grown as much (`grown` covers `box` only).
  const cv::Mat& mask = region.mask;
  const cv::Rect box =
      (region.box + cv::Size(4, 4) - cv::Point(2, 2)) & cv::Rect(0, 0, mask.cols, mask.rows);
  cv::Mat grown;
  cv::dilate(mask(box), grown, cv::Mat(), cv::Point(-1, -1), 2);
  for (size_t k = 0; k < followed.before.size(); ++k) {
    const cv::Point a(cvRound(followed.before[k].x), cvRound(followed.before[k].y));
    const cv::Point b(cvRound(followed.now[k].x), cvRound(followed.now[k].y));
    if (!box.contains(b) || !grown.at<uint8_t>(b - box.tl())) continue;
    const float za = previous_depth_.at<float>(a), zb = depth.at<float>(b);
    if (!(za > 0) || !(zb > 0)) continue;
    kept_before.push_back(followed.before[k]);
    kept_now.push_back(followed.now[k]);
    z_before.push_back(za);
    z_now.push_back(zb);
  }
  if (static_cast<int>(kept_before.size()) < options_.min_motion_points) return std::nullopt;
  std::vector<cv::Point2f> ub = camera_.UndistortPoints(kept_before);
  std::vector<cv::Point2f> un = camera_.UndistortPoints(kept_now);
  std::vector<Eigen::Vector3d> from, to;
  for (size_t k = 0; k < ub.size(); ++k) {
    from.push_back(camera_.Unproject({ub[k].x, ub[k].y}, z_before[k]));
    to.push_back(camera_.Unproject({un[k].x, un[k].y}, z_now[k]));
  }
  if (options_.static_px > 0) {
    // Which points the camera's motion alone explains: where it puts them in the image, and at
    // what depth (both ends' noise).
    std::vector<uint8_t> still(from.size(), 0);
    size_t stills = 0;
    for (size_t k = 0; k < from.size(); ++k) {
      const Eigen::Vector3d p = camera_motion * from[k];
      if (p.z() <= 0) continue;
      const Eigen::Vector2d pixel = camera_.Project(p);  // undistorted, as `un`
      const double depth_sigma = std::sqrt(2.0) * DepthNoiseSigma(SceneFlowOptions(), to[k].z());
      still[k] = (pixel - Eigen::Vector2d(un[k].x, un[k].y)).norm() <= options_.static_px &&
                 std::abs(p.z() - to[k].z()) <= 3 * depth_sigma;
      stills += still[k];
    }
    if (stills > 0 && 2 * stills < from.size()) {
      size_t kept = 0;
      for (size_t k = 0; k < from.size(); ++k) {
        if (still[k]) continue;
        from[kept] = from[k], to[kept] = to[k], un[kept] = un[k];
        ++kept;
      }
      from.resize(kept), to.resize(kept), un.resize(kept);
    }
  }
  const int n = static_cast<int>(from.size());
  if (n < options_.min_motion_points) return std::nullopt;
  RigidRansacOptions ransac;
  ransac.inlier_base = options_.inlier_m;
  ransac.inlier_per_depth2 = options_.inlier_per_m2;
  ransac.min_inliers = options_.min_motion_points;
  ransac.seed = static_cast<uint32_t>(options_.seed + index);
  const RigidRansacResult fit = EstimateRigidTransformRansac(from, to, ransac);
  if (!fit.found) return std::nullopt;
  // The fit weighs every coordinate alike, but a depth is far noisier than the pixel it was
  // read at (centimetres at 3 m against a fraction of a pixel): the rotation is refined on the
  // points' pixels and depths, each with its own noise.
  std::vector<int> used;
  for (int k = 0; k < n; ++k) {
    if (fit.inlier[static_cast<size_t>(k)]) used.push_back(k);
  }
  std::vector<Eigen::Vector2d> pixels;
  for (int k : used)
    pixels.emplace_back(un[static_cast<size_t>(k)].x, un[static_cast<size_t>(k)].y);
  std::vector<Eigen::Vector3d> from_used, to_used;
  for (int k : used) {
    from_used.push_back(from[static_cast<size_t>(k)]);
    to_used.push_back(to[static_cast<size_t>(k)]);
  }
  Eigen::Isometry3d T =
      RefineMotion(camera_.options(), options_, from_used, to_used, pixels, fit.T_b_a);
  // ... and the translation is the one that moves the points' mean where their mean went: the
  // object's own displacement, its depth noise averaged over all of them, whatever a small
  // rotation error would do to the motion of the camera's origin.
  Eigen::Vector3d mean_from = Eigen::Vector3d::Zero(), mean_to = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < used.size(); ++k) {
    mean_from += from_used[k];
    mean_to += to_used[k];
  }
  const double count = static_cast<double>(used.size());
  T.translation() = mean_to / count - T.linear() * (mean_from / count);
  *inliers = fit.num_inliers;
  return T;
}

int ObjectTracker::RegionAt(const std::vector<Region>& regions, const cv::Point& p) {
  for (size_t r = 0; r < regions.size(); ++r) {
    if (regions[r].box.contains(p) && regions[r].mask.at<uint8_t>(p) != 0)
      return static_cast<int>(r);
  }
  return -1;
}

std::vector<int> ObjectTracker::Votes(const FollowedPoints& followed,
                                      const std::vector<Region>& regions) const {
  std::vector<int> votes(regions.size(), 0);
  for (const cv::Point2f& p : followed.now) {
    const int r = RegionAt(regions, cv::Point(cvRound(p.x), cvRound(p.y)));
    if (r >= 0) ++votes[static_cast<size_t>(r)];
  }
  // Only a region that holds min_votes of the track's points and a quarter of them continues it.
  for (int& v : votes) {
    if (v < options_.min_votes || 4 * v < static_cast<int>(followed.now.size())) v = 0;
  }
  return votes;
}

void ObjectTracker::SplitMergedRegions(const std::vector<FollowedPoints>& followed,
                                       const cv::Mat& depth, const cv::Mat& labels,
                                       const std::vector<ClassHint>& hints,
                                       std::vector<Region>* regions) const {
  std::vector<std::vector<size_t>> voters(regions->size());  // tracks continued by each region
  for (size_t t = 0; t < followed.size(); ++t) {
    const std::vector<int> votes = Votes(followed[t], *regions);
    for (size_t r = 0; r < votes.size(); ++r) {
      if (votes[r] > 0) voters[r].push_back(t);
    }
  }
  std::vector<Region> kept;
  for (size_t r = 0; r < regions->size(); ++r) {
    Region& region = (*regions)[r];
    if (voters[r].size() < 2) {
      kept.push_back(std::move(region));
      continue;
    }
    // Two objects that came together in the image, each pixel to the object whose followed
    // point lies nearest (the label of the nearest seed, by distance transform), within the
    // region's bounds.
    const cv::Rect box = region.box;
    cv::Mat not_seed(box.size(), CV_8U, cv::Scalar(255));
    cv::Mat owner(box.size(), CV_32S, cv::Scalar(-1));  // the track of each seed
    for (size_t t : voters[r]) {
      for (const cv::Point2f& p : followed[t].now) {
        const cv::Point q(cvRound(p.x), cvRound(p.y));
        if (!box.contains(q) || region.mask.at<uint8_t>(q) == 0) continue;
        not_seed.at<uint8_t>(q - box.tl()) = 0;
        owner.at<int>(q - box.tl()) = static_cast<int>(t);
      }
    }
    cv::Mat distance, nearest;
    cv::distanceTransform(not_seed, distance, nearest, cv::DIST_L2, cv::DIST_MASK_5,
                          cv::DIST_LABEL_PIXEL);
    // DIST_LABEL_PIXEL numbers the seeds 1, 2, ... in scan order.
    std::vector<int> track_of_label(1, -1);
    for (int y = 0; y < box.height; ++y) {
      for (int x = 0; x < box.width; ++x) {
        if (not_seed.at<uint8_t>(y, x) == 0) track_of_label.push_back(owner.at<int>(y, x));
      }
    }
    for (size_t t : voters[r]) {
      cv::Mat part(labels.size(), CV_8U, cv::Scalar(0));
      for (int y = 0; y < box.height; ++y) {
        const uint8_t* m = region.mask.ptr<uint8_t>(box.y + y) + box.x;
        const int* label = nearest.ptr<int>(y);
        uint8_t* out = part.ptr<uint8_t>(box.y + y) + box.x;
        for (int x = 0; x < box.width; ++x)
          out[x] = m[x] && track_of_label[static_cast<size_t>(label[x])] == static_cast<int>(t)
                       ? 255
                       : 0;
      }
      if (std::optional<Region> split = MakeRegion(part, box, depth, labels, hints))
        kept.push_back(std::move(*split));
    }
  }
  *regions = std::move(kept);
}

std::vector<ObjectObservation> ObjectTracker::Update(size_t index, double timestamp,
                                                     const cv::Mat& gray, const cv::Mat& depth,
                                                     const cv::Mat& labels,
                                                     const std::vector<ClassHint>& hints,
                                                     const Eigen::Isometry3d& T_world_camera,
                                                     bool tracked) {
  std::vector<ObjectObservation> out;
  const bool has_previous = !previous_pyramid_.empty() && previous_index_ + 1 == index;
  std::vector<Region> regions;
  if (tracked && !labels.empty()) regions = FindRegions(depth, labels, hints);
  // Lucas–Kanade's pyramid of this frame, built once for every object (and kept for the next),
  // and only where a track is followed into this frame or a region may be followed out of it.
  const bool follows =
      has_previous && std::any_of(tracks_.begin(), tracks_.end(),
                                  [&](const Track& t) { return t.last_frame == previous_index_; });
  std::vector<cv::Mat> pyramid;
  if (follows || !regions.empty())
    cv::buildOpticalFlowPyramid(gray, pyramid, cv::Size(kWindow, kWindow), kLevels);
  // Association. A track seen in the previous frame follows its own points (Lucas–Kanade from
  // its region then) into this frame: the region most of them land in continues it (a sdo mask
  // that covers another part of the object each frame moves the centroid by decimetres, not the
  // object's pixels). Tracks and regions left over pair by the distance of their centroids (the
  // track's carried on at its velocity), within gate_m.
  std::vector<FollowedPoints> followed(tracks_.size());
  for (size_t t = 0; t < tracks_.size(); ++t) {
    if (has_previous && tracks_[t].last_frame == previous_index_)
      followed[t] = FollowPoints(tracks_[t].mask, tracks_[t].box, gray, pyramid);
  }
  SplitMergedRegions(followed, depth, labels, hints, &regions);
  struct Pair {
    int votes;
    double distance;
    size_t region, track;
  };
  std::vector<Pair> pairs;
  for (size_t t = 0; t < tracks_.size(); ++t) {
    const std::vector<int> votes = Votes(followed[t], regions);
    for (size_t r = 0; r < regions.size(); ++r) {
      if (votes[r] > 0) pairs.push_back({votes[r], 0.0, r, t});
    }
  }
  for (size_t r = 0; r < regions.size(); ++r) {
    const Eigen::Vector3d c = T_world_camera * regions[r].centroid_camera;
    for (size_t t = 0; t < tracks_.size(); ++t) {
      const Track& track = tracks_[t];
      const double frames = static_cast<double>(
          std::min(index - track.last_frame, static_cast<size_t>(options_.max_predicted_frames)));
      const double d = (c - (track.centroid_world + frames * track.velocity_world)).norm();
      if (d <= options_.gate_m) pairs.push_back({0, d, r, t});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    return std::tie(b.votes, a.distance, a.region, a.track) <
           std::tie(a.votes, b.distance, b.region, b.track);
  });
  std::vector<int> track_of(regions.size(), -1);
  std::vector<uint8_t> track_taken(tracks_.size(), 0);
  for (const Pair& p : pairs) {
    if (track_of[p.region] >= 0 || track_taken[p.track]) continue;
    track_of[p.region] = static_cast<int>(p.track);
    track_taken[p.track] = 1;
  }
  for (size_t r = 0; r < regions.size(); ++r) {
    Region& region = regions[r];
    const Eigen::Vector3d centroid_world = T_world_camera * region.centroid_camera;
    ObjectObservation o;
    o.frame = index;
    o.timestamp = timestamp;
    o.class_name = region.class_name;
    o.pixels = region.pixels;
    o.centroid_camera = region.centroid_camera;
    if (track_of[r] < 0) {
      tracks_.push_back(
          {next_id_++, centroid_world, Eigen::Vector3d::Zero(), index, region.mask, region.box});
      o.id = tracks_.back().id;
    } else {
      Track& t = tracks_[static_cast<size_t>(track_of[r])];
      o.id = t.id;
      if (has_previous && t.last_frame == previous_index_) {
        o.motion_camera =
            EstimateMotion(index, followed[static_cast<size_t>(track_of[r])], region, depth,
                           T_world_camera.inverse() * previous_T_world_camera_, &o.motion_inliers);
        o.previous_frame = previous_index_;
        o.previous_timestamp = previous_timestamp_;
      }
      // Smoothed: a centroid that jumps with its mask would throw the prediction off.
      const double frames = static_cast<double>(index - t.last_frame);
      t.velocity_world =
          0.5 * t.velocity_world + 0.5 * (centroid_world - t.centroid_world) / frames;
      t.centroid_world = centroid_world;
      t.last_frame = index;
      t.mask = region.mask;
      t.box = region.box;
    }
    out.push_back(std::move(o));
  }
  // Tracks unseen too long end.
  std::erase_if(tracks_, [&](const Track& t) {
    return index - t.last_frame > static_cast<size_t>(options_.max_missed_frames);
  });
  previous_index_ = index;
  previous_timestamp_ = timestamp;
  previous_pyramid_ = std::move(pyramid);
  // Only a frame with objects is followed out of (its regions are the tracks seen in it).
  if (regions.empty()) previous_pyramid_.clear();
  previous_depth_ = regions.empty() ? cv::Mat() : depth.clone();
  previous_T_world_camera_ = T_world_camera;
  return out;
}

namespace {

// The pose of the trajectory at exactly `timestamp` (a frame's own time), or none.
std::optional<Eigen::Isometry3d> PoseAt(const Trajectory& trajectory, double timestamp) {
  const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), timestamp - 1e-6,
                                   [](const StampedPose& p, double t) { return p.timestamp < t; });
  if (it == trajectory.end() || std::abs(it->timestamp - timestamp) > 1e-6) return std::nullopt;
  return it->T_world_camera;
}

}  // namespace

std::string ObjectsCsv(const std::vector<ObjectObservation>& observations,
                       const Trajectory& trajectory) {
  std::string csv = "timestamp,id,class,tx,ty,tz,qx,qy,qz,qw,cx,cy,cz,pixels\n";
  for (const ObjectObservation& o : observations) {
    const std::optional<Eigen::Isometry3d> T = PoseAt(trajectory, o.timestamp);
    if (!T) continue;
    std::string motion = ",,,,,,";
    if (o.motion_camera) {
      if (const auto T_before = PoseAt(trajectory, o.previous_timestamp)) {
        // X_world_now = T · G · T_before⁻¹ · X_world_before.
        const Eigen::Isometry3d H = *T * *o.motion_camera * T_before->inverse();
        const Eigen::Quaterniond q(H.linear());
        motion =
            fmt::format("{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f}", H.translation().x(),
                        H.translation().y(), H.translation().z(), q.x(), q.y(), q.z(), q.w());
      }
    }
    const Eigen::Vector3d c = *T * o.centroid_camera;
    csv += fmt::format("{:.6f},{},{},{},{:.6f},{:.6f},{:.6f},{}\n", o.timestamp, o.id, o.class_name,
                       motion, c.x(), c.y(), c.z(), o.pixels);
  }
  return csv;
}

std::map<int, Trajectory> ObjectCentroidTracks(const std::vector<ObjectObservation>& observations,
                                               const Trajectory& trajectory) {
  std::map<int, Trajectory> tracks;
  for (const ObjectObservation& o : observations) {
    const std::optional<Eigen::Isometry3d> T = PoseAt(trajectory, o.timestamp);
    if (!T) continue;
    StampedPose p;
    p.timestamp = o.timestamp;
    p.T_world_camera.translation() = *T * o.centroid_camera;
    tracks[o.id].push_back(p);
  }
  return tracks;
}

}  // namespace sdoslam
